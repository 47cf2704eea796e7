"""Which strain basis the closed-loop 3D tasks' arm needs: a convergence study.

The arm is ``gv.soft_arm`` (1 m, r 5 cm, E 10 MPa, rho 1000, nu 0.5, eta 1e5 Pa s,
upright, gravity along -z, two groups of four tendons anchored at X = 1 and 0.5).
Candidates differ in the Legendre orders of bending (both curvatures), torsion,
stretch and shear. Each is compared with a reference basis (bending order 5,
torsion, stretch and both shears order 2: 24 DoFs) on

* statics: the equilibrium tip under the task's largest actuations (one tendon of
  each group at the maximum tension, alone and combined in-plane and out of plane:
  the S-shape with a curvature jump at X = 0.5 is the hardest for a polynomial);
* dynamics: the tip path over 2 s after the combined tensions step on from rest
  (``ars443`` at 5 ms; the reference at the same step).

    python experiments/studies/track3d_basis.py               # ~15 min on 2 cores
    python experiments/studies/track3d_basis.py --quick       # statics only

Writes benchmarks/track3d_basis.json and prints a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv  # first: it sets XLA's flags

ROOT = Path(__file__).resolve().parents[2]
T_MAX = 3000.0  # N: 1.5 x the tasks' maximum tension (arm3d.ArmParams), a margin

CANDIDATES = {
    "bend1": dict(bending_order=1, torsion_order=0, stretch_order=0, shear_order=-1),
    "bend2": dict(bending_order=2, torsion_order=0, stretch_order=0, shear_order=-1),
    "bend3": dict(bending_order=3, torsion_order=0, stretch_order=0, shear_order=-1),
    "bend2 stretch1": dict(bending_order=2, torsion_order=0, stretch_order=1, shear_order=-1),
    "bend3 stretch1": dict(bending_order=3, torsion_order=0, stretch_order=1, shear_order=-1),
    "bend2 no-stretch": dict(bending_order=2, torsion_order=0, stretch_order=-1, shear_order=-1),
    "bend2 shear0": dict(bending_order=2, torsion_order=0, stretch_order=0, shear_order=0),
    "bend3 all-order1": dict(bending_order=3, torsion_order=1, stretch_order=1, shear_order=1),
}
REFERENCE = dict(bending_order=5, torsion_order=2, stretch_order=2, shear_order=2, n_gauss=7)

# tendon order: group X=1 at (+x, +y, -x, -y), then group X=0.5 the same
CASES = {
    "whole arm +x": [1, 0, 0, 0, 0, 0, 0, 0],
    "lower half +x": [0, 0, 0, 0, 1, 0, 0, 0],
    "S in-plane (whole +x, lower -x)": [1, 0, 0, 0, 0, 0, 1, 0],
    "3D (whole +x, lower +y)": [1, 0, 0, 0, 0, 1, 0, 0],
}


def arm(cfg: dict) -> gv.Robot:
    cfg = dict(cfg)
    top = max(cfg["bending_order"], cfg["torsion_order"], cfg["stretch_order"], cfg["shear_order"])
    cfg.setdefault("n_gauss", top + 2)
    return gv.soft_arm(**cfg)


def statics(robot) -> dict:
    out = {}
    t0 = time.perf_counter()
    for name, pull in CASES.items():
        eq = gv.equilibrium(robot, tendon_force=T_MAX * jnp.asarray(pull, float), load_scale_steps=6)
        out[name] = {"tip": np.asarray(gv.backbone(robot, eq.q)[-1]).tolist(), "converged": bool(eq.converged)}
    out["wall_s"] = time.perf_counter() - t0
    return out


def dynamics(robot, duration=2.0, dt=5e-3) -> dict:
    pull = T_MAX * jnp.asarray(CASES["3D (whole +x, lower +y)"], float)
    t0 = time.perf_counter()
    tr = gv.simulate(robot, duration, n_steps=round(duration / dt), tendon_force=pull, integrator="ars443",
                     check_stability=False)
    tip = np.asarray(tr.tip)
    return {"tip": tip.tolist(), "wall_s": time.perf_counter() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="statics only")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "track3d_basis.json"))
    ap.add_argument("--only", default="", help="comma-separated candidates to (re)run; the rest is read from --json")
    args = ap.parse_args()
    rows = {}
    if args.only:
        rows = json.loads(Path(args.json).read_text())["rows"]
    for name, cfg in {"reference": REFERENCE, **CANDIDATES}.items():
        if args.only and name not in args.only.split(","):
            continue
        robot = arm(cfg)
        row = {"config": cfg, "dofs": int(robot.n_dofs), "statics": statics(robot)}
        if not args.quick:
            row["dynamics"] = dynamics(robot)
        rows[name] = row
        print(f"{name}: {row['dofs']} DoFs, statics {row['statics']['wall_s']:.0f} s", flush=True)
        Path(args.json).write_text(json.dumps({"t_max_N": T_MAX, "rows": rows}, indent=1))
    ref = rows["reference"]
    print("\n| basis | DoFs | " + " | ".join(CASES) + " | dynamics: max over 2 s | rms | at 2 s |")
    print("|---|---|" + "---|" * (len(CASES) + 3))
    for name in ["reference", *CANDIDATES]:
        if name not in rows:
            continue
        row = rows[name]
        errs = [1e3 * np.linalg.norm(np.subtract(row["statics"][c]["tip"], ref["statics"][c]["tip"])) for c in CASES]
        dyn = ""
        if "dynamics" in row:
            gap = np.linalg.norm(np.subtract(row["dynamics"]["tip"], ref["dynamics"]["tip"]), axis=1)
            dyn = f"{1e3 * np.max(gap):.2f} | {1e3 * np.sqrt(np.mean(gap**2)):.2f} | {1e3 * gap[-1]:.2f}"
        print(f"| {name} | {row['dofs']} | " + " | ".join(f"{e:.2f}" for e in errs) + f" | {dyn} |")
    print("(tip distance from the reference, mm)")


if __name__ == "__main__":
    jax.config.update("jax_enable_x64", True)
    main()
