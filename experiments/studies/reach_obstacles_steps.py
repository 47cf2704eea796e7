"""How many ars443 steps reach_obstacles needs per 0.1 s control step, and how stiff its bars are.

The contact is explicit in every integrator, so the bars' penalty stiffness k bounds the step
(|lambda| ~ sqrt(k / rho A)). Episodes of the task's arm in its cage (3 s, actions held or
redrawn every 0.5 s, many of them driving the arm into the bars) are run with ``n_substeps``
steps per control step and against a reference of ``--reference`` steps with the same k. The
table gives, per (k, n_substeps): the largest and 95th-percentile tip distance from the
reference over all control steps, the deepest penetration (which k sets), the share of
diverged episodes, and the env steps per second of the batch.

    python experiments/studies/reach_obstacles_steps.py            # ~10 min on 2 cores
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
from gvsjax.tasks.reach_obstacles import scene

ROOT = Path(__file__).resolve().parents[2]


def episodes(arm, actions):
    """Tip (B, T, 3) and deepest penetration (B,) of a batch under actions (B, T, 4)."""

    def one(acts):
        def body(carry, a):
            q, qd = carry
            tr = arm3d.advance(arm, q, qd, arm3d.tensions(a, arm), save_every=1)
            return (tr.q[-1], tr.qd[-1]), (tr.tip[-1], -jnp.min(tr.contact_gap))

        q, qd = arm3d.rest(arm.robot)
        _, (tip, depth) = jax.lax.scan(body, (q, qd), acts)
        return tip, jnp.max(depth)

    return jax.jit(jax.vmap(one))(actions)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--stiffness", type=float, nargs="+", default=[1e5, 3e5, 1e6])
    ap.add_argument("--substeps", type=int, nargs="+", default=[8, 16, 32])
    ap.add_argument("--reference", type=int, default=64)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "reach_obstacles_steps.json"))
    args = ap.parse_args()
    env = make("reach_obstacles")
    params = env.default_params()
    base = scene(params, 0.0)
    key = jax.random.PRNGKey(0)
    held = jax.random.uniform(key, (args.batch // 2, 1, 4), minval=-1.0, maxval=1.0).repeat(30, 1)
    jerky = jax.random.uniform(jax.random.fold_in(key, 1), (args.batch // 2, 6, 4), minval=-1.0, maxval=1.0)
    actions = jnp.concatenate([held, jerky.repeat(5, 1)])
    rows = []
    for k in args.stiffness:
        robot = base.robot
        contact = dataclasses.replace(robot.contact, rod=dataclasses.replace(robot.contact.rod, stiffness=k))
        robot = dataclasses.replace(robot, contact=contact)
        ref_tip, ref_depth = episodes(dataclasses.replace(base, robot=robot, n_substeps=args.reference), actions)
        for n in args.substeps:
            arm = dataclasses.replace(base, robot=robot, n_substeps=n)
            tip, depth = episodes(arm, actions)
            t0 = time.perf_counter()
            jax.block_until_ready(episodes(arm, actions))
            wall = time.perf_counter() - t0
            err = np.linalg.norm(np.asarray(tip) - np.asarray(ref_tip), axis=-1)
            err = np.where(np.isfinite(err), err, np.inf)
            row = {"stiffness": k, "n_substeps": n, "tip_error_max_m": float(err.max()),
                   "tip_error_p95_m": float(np.percentile(err, 95, method="inverted_cdf")),
                   "deepest_m": float(np.nanmax(np.asarray(depth))),
                   "reference_deepest_m": float(np.max(np.asarray(ref_depth))),
                   "diverged": float(np.mean(~np.all(np.isfinite(np.asarray(tip)), axis=(1, 2)))),
                   "env_steps_per_s": actions.shape[0] * actions.shape[1] / wall}
            rows.append(row)
            print(json.dumps(row))
    Path(args.json).write_text(json.dumps({"reference_substeps": args.reference, "batch": int(actions.shape[0]),
                                           "rows": rows, "jax": jax.__version__}, indent=2) + "\n")


if __name__ == "__main__":
    main()
