"""throw3d's model and integration step: landing points against finer runs, and throws per second.

For random actions over the whole box each throw is flown to the floor and its
landing point compared:

- integration: the task's arm (the paper's 2 bending modes per plane, 5 Gauss
  points) at 20, 30 and 40 ars443 steps to release, and with 3 Gauss points,
  against the same arm at 400 steps;
- basis: richer arms (more bending modes, torsion, stretch and shear) at 200
  steps against the richest (bending order 3, torsion, stretch and shears at
  order 1, 8 Gauss points) at 400 steps. This is the model's truncation: the
  task, like basketball, keeps the paper's 2-mode arm.

Each row gives the largest, 95th-percentile and median landing difference
(the miss a perfect policy of that model makes on the finer one) and, for the
integration rows, throws per second at batch 1024 in float32 (median of 3).

    python experiments/studies/throw3d_convergence.py      # ~15 min on 2 cores
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv
from gvsjax.tasks import ballistics
from gvsjax.tasks import throw3d as t3

ROOT = Path(__file__).resolve().parents[2]

FINE = 400  # steps of the references
RICH = dict(n_modes=4, torsion_order=1, stretch_order=1, shear_order=1, n_gauss=8)
INTEGRATION = {
    "40 steps (the task's)": dict(arm={}, n_steps=40),
    "30 steps": dict(arm={}, n_steps=30),
    "20 steps": dict(arm={}, n_steps=20),
    "40 steps, 3 Gauss points": dict(arm=dict(n_gauss=3), n_steps=40),
}
BASIS = {
    "2 bending modes (the task's)": dict(arm={}, n_steps=200),
    "3 bending modes": dict(arm=dict(n_modes=3), n_steps=200),
    "4 bending modes": dict(arm=dict(n_modes=4, n_gauss=8), n_steps=200),
    "4 bending modes, torsion": dict(arm=dict(n_modes=4, torsion_order=1, n_gauss=8), n_steps=200),
    "richest at 200 steps": dict(arm=RICH, n_steps=200),
}


def params_of(spec, dtype="float64"):
    arm = gv.paper_arm_3d(tip_force=t3.BALL_WEIGHT, **spec["arm"])
    return t3.Throw3DParams(arm=arm, n_steps=spec["n_steps"], sim_dtype=dtype)


def landing(params, actions):
    def one(a):
        T, d, s = t3.action_to_physical(a, params)
        p0, v0 = t3.release_state(params, T, d, s)
        end = ballistics.floor_time(p0, v0, params.g, params.court[2])
        return ballistics.flight_point(p0, v0, end, params.g)

    return np.asarray(jax.jit(jax.vmap(one))(jnp.asarray(actions)))


def throws_per_second(params, batch=1024, repeats=3):
    f = jax.jit(jax.vmap(lambda a: t3.release_state(params, *t3.action_to_physical(a, params))))
    a = jnp.asarray(np.random.default_rng(1).uniform(-1, 1, (batch, 3)))
    jax.block_until_ready(f(a))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(f(a))
        times.append(time.perf_counter() - t0)
    return batch / float(np.median(times))


def _row(err):
    return dict(max_cm=float(err.max() * 100), p95_cm=float(np.percentile(err, 95) * 100),
                median_cm=float(np.median(err) * 100))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=256, help="random actions")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "throw3d_convergence.json"))
    args = ap.parse_args()
    actions = np.random.default_rng(0).uniform(-1, 1, (args.n, 3))
    out = dict(n_actions=args.n, fine_steps=FINE, integration={}, basis={})
    ref = landing(params_of(dict(arm={}, n_steps=FINE)), actions)
    for name, spec in INTEGRATION.items():
        row = _row(np.linalg.norm(landing(params_of(spec), actions) - ref, axis=-1))
        row["float32_max_cm"] = float(np.linalg.norm(landing(params_of(spec, "float32"), actions) - ref,
                                                     axis=-1).max() * 100)
        row["throws_per_s_float32"] = throws_per_second(params_of(spec, "float32"))
        out["integration"][name] = row
        print(f"{name:36s} max {row['max_cm']:7.2f} cm  p95 {row['p95_cm']:6.2f}  median {row['median_cm']:6.3f}  "
              f"float32 max {row['float32_max_cm']:6.2f}  {row['throws_per_s_float32']:6.0f} throws/s", flush=True)
    rich = lambda spec: dict(spec, arm=dict(spec["arm"], recursion="scan"))  # noqa: E731  (large arms compile faster)
    ref = landing(params_of(rich(dict(arm=RICH, n_steps=FINE))), actions)
    for name, spec in BASIS.items():
        row = _row(np.linalg.norm(landing(params_of(rich(spec)), actions) - ref, axis=-1))
        out["basis"][name] = row
        print(f"{name:36s} max {row['max_cm']:7.2f} cm  p95 {row['p95_cm']:6.2f}  median {row['median_cm']:6.3f}",
              flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(dict(out, integration_variants=INTEGRATION, basis_variants=BASIS,
                                              richest=RICH), indent=1))
    print("wrote", args.out)


if __name__ == "__main__":
    main()
