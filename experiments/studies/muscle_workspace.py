"""Static workspace of the 3D arm under tendon and under muscle actuation, against track3d's target box.

Tip positions of the arm at rest (``gv.equilibrium``, gravity on) under many held
actions of each actuation: tendon actions (4) at ``tension_max`` and muscle actions
(12) at several ``moment_max``. Half the actions are drawn uniformly from [-1.5, 1.5]
and clipped, so a third of the entries sit at a limit, where the workspace's edge
is; for the muscles the other half are linear profiles along the arm in each
direction, a(X) = clip(c + g (X - 1/2)), c in [-1.5, 1.5], g in [-4, 4] (uniform
moments at the limit, which independent draws at six points almost never give).
Two measures of the cover of track3d's box (x, y in [-0.6, 0.6], z in [0.3, 0.9] m):
the share of uniform box points within 5 cm of a reached tip, and per radial distance
from the arm's axis the lowest tip reached (the box's lowest targets are z = 0.3 m).

    python experiments/studies/muscle_workspace.py      # ~3 min on 2 cores; benchmarks/muscle_workspace.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

import gvsjax as gv
from gvsjax.tasks import arm3d
from gvsjax.tasks.actuation import MUSCLE_POINTS
from gvsjax.tasks.track3d import Track3DParams

ROOT = Path(__file__).resolve().parents[2]
LOAD_STEPS = 4  # continuation: the largest actions curl the tip below the base
RADII = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8)  # m from the axis, where the lowest tip is reported


def equilibrium_tip(arm: arm3d.ArmParams, action: jax.Array, limit: jax.Array):
    """The tip at rest under a held action, the actuation's limit (N or N m) set to ``limit``,
    and whether the statics converged."""
    tension, strain_force = arm3d.actuate(action, arm.replace(moment_max=limit, tension_max=limit))
    eq = gv.equilibrium(arm.robot, tendon_force=tension, strain_force=strain_force, load_scale_steps=LOAD_STEPS)
    return gv.tip_frame(arm.robot, eq.q)[1], eq.converged


def sample_actions(key: jax.Array, n: int, k: int, muscle: bool) -> jax.Array:
    """n actions (see the module docstring)."""
    k_u, k_c, k_g = jax.random.split(key, 3)
    uniform = jnp.clip(jax.random.uniform(k_u, (n, k), minval=-1.5, maxval=1.5), -1.0, 1.0)
    if not muscle:
        return uniform
    m = n // 2
    X = jnp.asarray(gv.control_points(MUSCLE_POINTS))
    c = jax.random.uniform(k_c, (m, 2, 1), minval=-1.5, maxval=1.5)
    g = jax.random.uniform(k_g, (m, 2, 1), minval=-4.0, maxval=4.0)
    profiles = jnp.clip(c + g * (X - 0.5), -1.0, 1.0).reshape(m, k)
    return jnp.concatenate([uniform[: n - m], profiles])


def cover(tip: np.ndarray, box: np.ndarray) -> dict:
    """Cover of the box points by the reached tips."""
    d, _ = cKDTree(tip).query(box)
    rho, z = np.hypot(tip[:, 0], tip[:, 1]), tip[:, 2]
    lowest = {f"{r:g}": float(z[np.abs(rho - r) < 0.025].min()) if np.any(np.abs(rho - r) < 0.025) else None
              for r in RADII}
    return {"box_within_5cm": float(np.mean(d < 0.05)), "box_within_10cm": float(np.mean(d < 0.10)),
            "lowest_z_at_radius_m": lowest, "max_radius_m": float(rho.max())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--samples", type=int, default=16384)
    ap.add_argument("--moment-max", default="60,80,90,100", help="N m, comma-separated")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "muscle_workspace.json"))
    args = ap.parse_args()
    P = Track3DParams()
    rng = np.random.default_rng(0)
    box = rng.uniform(P.box_low, P.box_high, (20000, 3))
    out: dict = {"samples": args.samples, "box_points": len(box)}
    for actuation, limits in (("tendon", [P.arm.tension_max]),
                              ("muscle", [float(m) for m in args.moment_max.split(",")])):
        arm = P.arm.replace(actuation=actuation)
        k = arm3d.n_actions(arm)
        actions = sample_actions(jax.random.PRNGKey(0), args.samples, k, actuation == "muscle")
        solve = jax.jit(jax.vmap(lambda a, limit, arm=arm: equilibrium_tip(arm, a, limit), in_axes=(0, None)))
        for limit in limits:
            tip, ok = (np.asarray(x) for x in solve(actions, limit))
            row = {"limit": limit, "converged": float(ok.mean()), **cover(tip[ok], box)}
            out[f"{actuation}_{limit:g}"] = row
            print(actuation, json.dumps(row), flush=True)
    Path(args.json).write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
