"""How many integrator steps the 3D tasks need per 0.1 s control step, and the cost of one.

Episodes of ``track3d`` (or ``--task track3d_muscle``: the same arm under muscle
moments) are run with ``n_substeps`` ars443 steps per control
step and with a reference of ``--reference`` steps, under two kinds of actions:
"random" (uniform in [-1, 1], a new one every control step: an untrained
policy's jerks, the hardest case) and "held" (uniform, each held for 1 s). The
table gives the largest and 95th-percentile tip distance from the reference
over all steps of the episodes (a diverged episode counts as infinite) and the
env steps per second of a batch.

    python experiments/studies/track3d_substeps.py              # ~5 min on 2 cores
    python experiments/studies/track3d_substeps.py --task track3d_muscle --json benchmarks/track3d_muscle_substeps.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv  # noqa: F401  (XLA flags first)
from gvsjax.tasks import arm3d, make

ROOT = Path(__file__).resolve().parents[2]


def tips(arm, actions):
    """Tip after each control step of a batch: actions (B, T, k) -> (B, T, 3)."""

    def one(acts):
        def body(carry, a):
            q, qd = carry
            tr = arm3d.control_step(arm, q, qd, a)[0]
            return (tr.q[-1], tr.qd[-1]), tr.tip[-1]

        return jax.lax.scan(body, arm3d.rest(arm.robot), acts)[1]

    return jax.vmap(one)(actions)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--task", default="track3d", help="track3d or track3d_muscle")
    ap.add_argument("--substeps", default="1,2,4,8")
    ap.add_argument("--reference", type=int, default=64)
    ap.add_argument("--episodes", type=int, default=64)
    ap.add_argument("--batch", type=int, default=1024, help="batch of the timing")
    ap.add_argument("--tension-max", type=float, default=0.0, help="N (default: the task's)")
    ap.add_argument("--sim-dtype", default="float64", help="of the runs compared with the float64 reference")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "track3d_substeps.json"))
    args = ap.parse_args()
    env = make(args.task)
    arm = env.default_params().arm
    if args.tension_max:
        arm = dataclasses.replace(arm, tension_max=args.tension_max)
    shape = (args.episodes, env.episode_length, env.action_size)
    random = jax.random.uniform(jax.random.PRNGKey(0), shape, minval=-1, maxval=1)
    held = jnp.repeat(random[:, ::10], 10, axis=1)
    families = {"random": random, "held": held}
    ref = {k: np.asarray(jax.jit(tips)(dataclasses.replace(arm, n_substeps=args.reference), a))
           for k, a in families.items()}
    rows = []
    for n in [int(s) for s in args.substeps.split(",")]:
        a = dataclasses.replace(arm, n_substeps=n, sim_dtype=args.sim_dtype)
        err = {k: np.nan_to_num(np.linalg.norm(np.asarray(jax.jit(tips)(a, acts)) - ref[k], axis=-1), nan=np.inf)
               for k, acts in families.items()}
        step = jax.jit(jax.vmap(lambda q, qd, u, a=a: arm3d.control_step(a, q, qd, u)[0].q[-1]))
        q = jnp.zeros((args.batch, arm.robot.n_dofs))
        T = jnp.full((args.batch, env.action_size), 0.25)  # a quarter of the limit, as 500 N of tension
        t0 = time.perf_counter()
        jax.block_until_ready(step(q, q, T))
        compile_s = time.perf_counter() - t0
        runs = []
        for _ in range(5):
            t0 = time.perf_counter()
            jax.block_until_ready(step(q, q, T))
            runs.append(time.perf_counter() - t0)
        rows.append({"n_substeps": n, **{f"{k}_max_tip_error_m": float(e.max()) for k, e in err.items()},
                     **{f"{k}_p95_tip_error_m": float(np.percentile(e, 95)) for k, e in err.items()},
                     "compile_s": compile_s, "env_steps_per_s": args.batch / float(np.median(runs))})
        print(rows[-1], flush=True)
    Path(args.json).write_text(json.dumps({"reference_substeps": args.reference, "episodes": args.episodes,
                                           "task": args.task, "actuation": arm.actuation,
                                           "tension_max_N": float(arm.tension_max),
                                           "moment_max_Nm": float(arm.moment_max), "batch": args.batch,
                                           "sim_dtype": args.sim_dtype,
                                           "rows": rows}, indent=1))
    print(f"\n| ars443 steps per 0.1 s | random actions: max / p95 tip error | held actions: max / p95 | "
          f"env steps/s (batch {args.batch}) |")
    print("|---|---|---|---|")
    mm = lambda x: f"{1e3 * x:.1f} mm"  # noqa: E731
    for r in rows:
        print(f"| {r['n_substeps']} | {mm(r['random_max_tip_error_m'])} / {mm(r['random_p95_tip_error_m'])} | "
              f"{mm(r['held_max_tip_error_m'])} / {mm(r['held_p95_tip_error_m'])} | {r['env_steps_per_s']:.0f} |")


if __name__ == "__main__":
    main()
