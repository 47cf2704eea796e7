"""Substeps and precision of the benchmark arm's control step: tip error against a fine run, and speed.

Episodes of ``follow_target``'s arm (``gv.curvature_arm``, twisting) under random actions held 0.1 s
each, through the task's own control step (``tasks.curvature.control``, its integrator), for 20
control steps (2 s), with n steps per control step in float64 and float32. The reference is 32
steps in float64. Reports the tip's distance to the reference at every control step (median, 95th
percentile, max over episodes and steps) and the environment steps per second of one batched
control step (median of repeats, compile excluded).

    python experiments/studies/curvature_substeps.py [batch=256] [episodes=64]

writes benchmarks/curvature_substeps.json.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
import gvsjax  # noqa: F401, I001  (before JAX: the XLA flag)
import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.tasks.curvature import control
from gvsjax.tasks.curvature.control import ArmControl

OUT = Path(__file__).resolve().parents[2] / "benchmarks" / "curvature_substeps.json"
STEPS = 20


def episode(arm: ArmControl, actions: jax.Array) -> jax.Array:
    """Tip positions (STEPS, 3) of one episode under ``actions`` (STEPS, 10)."""
    return control.open_loop_tips(arm, actions)


def main(batch: int = 256, episodes: int = 64) -> dict:
    base = ArmControl()
    actions = jax.random.uniform(jax.random.PRNGKey(0), (episodes, STEPS, 10), minval=-1.0, maxval=1.0)
    ref = np.asarray(jax.jit(jax.vmap(lambda a: episode(dataclasses.replace(base, n_substeps=32), a)))(actions))
    rows = []
    for dtype in ("float64", "float32"):
        for n in (2, 4, 8, 16):
            arm = dataclasses.replace(base, n_substeps=n, sim_dtype=dtype)
            tips = np.asarray(jax.jit(jax.vmap(lambda a, arm=arm: episode(arm, a)))(actions))
            err = 1e3 * np.linalg.norm(tips - ref, axis=-1)
            step = jax.jit(jax.vmap(lambda q, qd, a, arm=arm: control.advance(
                arm, q, qd, jnp.zeros(10), control.rest_values(arm.robot, a.reshape(5, 2), jnp.zeros(5))).q[-1]))
            q = jnp.zeros((batch, base.robot.n_dofs))
            a = jax.random.uniform(jax.random.PRNGKey(1), (batch, 10), minval=-2.0, maxval=2.0)
            step(q, q, a).block_until_ready()
            times = []
            for _ in range(5):
                start = time.perf_counter()
                step(q, q, a).block_until_ready()
                times.append(time.perf_counter() - start)
            rows.append({"dtype": dtype, "substeps": n, "tip_error_mm_median": float(np.median(err)),
                         "tip_error_mm_p95": float(np.percentile(err, 95)), "tip_error_mm_max": float(err.max()),
                         "env_steps_per_s": batch / float(np.median(times))})
            r = rows[-1]
            print(f"{dtype} {n:2d} substeps: tip error median {r['tip_error_mm_median']:.3f} mm, p95 "
                  f"{r['tip_error_mm_p95']:.3f}, max {r['tip_error_mm_max']:.3f}; "
                  f"{r['env_steps_per_s']:.0f} env steps/s", flush=True)
    out = {"reference": f"32 {base.integrator} steps per 0.1 s, float64", "integrator": base.integrator,
           "dofs": base.robot.n_dofs, "episodes": episodes, "control_steps": STEPS,
           "batch": batch, "rows": rows}
    OUT.write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    args = dict(a.split("=", 1) for a in sys.argv[1:])
    main(int(args.get("batch", 256)), int(args.get("episodes", 64)))
