"""How the benchmark arm's strain basis converges under piecewise-constant rest curvature.

The benchmark (Choi & Tong, arXiv 2511.06667) sets a rest curvature that is constant on
five segments of its arm. ``gv.curvature_arm`` splits the rod at the segments' ends,
so that a constant curvature per link represents it exactly; this script measures, at
static equilibrium under gravity, how far the tip moves against a finer model when
  * the split arm's links carry linear instead of constant curvatures, and
  * one link with Legendre bases of order 4, 6 and 8 carries the same rest curvature
    (projected onto the basis),
for random turning angles uniform over the task's whole range ([-2, 2] rad per control
point and direction). The reference is the split arm with quadratic curvatures.

    python experiments/studies/curvature_arm_basis.py [n_samples=16]

writes benchmarks/curvature_arm_basis.json (tip errors in mm, tangent errors in deg).
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
import gvsjax as gv  # noqa: I001  (before JAX: the XLA flag)
import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core.curvature_arm import SEGMENT_SHARE, SEGMENTS, UPRIGHT, segment_lengths

OUT = Path(__file__).resolve().parents[2] / "benchmarks" / "curvature_arm_basis.json"


def single_link(order: int) -> gv.Robot:
    """The benchmark arm as one link with Legendre bending of ``order``, the segments on it."""
    base = gv.curvature_arm()
    link0 = base.links[0]
    link = gv.SoftLink(length=1.0, radius=link0.radius, material=link0.material,
                       basis=gv.StrainBasis((-1, order, order, -1, -1, -1), kind="legendre"),
                       joint=gv.Joint("fixed"), n_gauss=order + 2, recursion="scan")
    seg = gv.RestStrainSegments(link=0, knots=SEGMENTS, components=("bend_z", "bend_y"))
    return dataclasses.replace(base, links=(link,), rest_strains=(seg,), base_rotation=UPRIGHT)


def tips(robot: gv.Robot, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    solve = jax.jit(jax.vmap(lambda u: gv.equilibrium(robot, rest_strain=u, load_scale_steps=4)))
    start = time.perf_counter()
    res = solve(jnp.asarray(values))
    R, p = jax.vmap(lambda q: gv.tip_frame(robot, q))(res.q)
    assert bool(jnp.all(res.converged)), "an equilibrium did not converge"
    return np.asarray(p), np.asarray(R[:, :, 0]), time.perf_counter() - start


def main(n_samples: int = 16) -> dict:
    rng = np.random.default_rng(0)
    kappa = rng.uniform(-2.0, 2.0, (n_samples, 5, 2))  # turning angles, rad
    share = np.asarray(SEGMENT_SHARE) / segment_lengths()
    values = np.stack([-kappa[..., 0], kappa[..., 1]], -1) * share[None, :, None]  # 1/m, (bend_z, bend_y)
    values = values.reshape(n_samples, -1)
    ref_p, ref_t, _ = tips(gv.curvature_arm(bending_order=2), values)
    models = {f"split, order {k}": gv.curvature_arm(bending_order=k) for k in (0, 1)}
    models.update({f"one link, order {k}": single_link(k) for k in (4, 6, 8)})
    rows = {}
    for name, robot in models.items():
        p, t, seconds = tips(robot, values)
        err = 1e3 * np.linalg.norm(p - ref_p, axis=1)
        ang = np.degrees(np.arccos(np.clip(np.sum(t * ref_t, axis=1), -1.0, 1.0)))
        rows[name] = {"dofs": robot.n_dofs, "tip_error_mm_median": float(np.median(err)),
                      "tip_error_mm_max": float(err.max()), "tangent_error_deg_median": float(np.median(ang)),
                      "tangent_error_deg_max": float(ang.max()), "seconds_incl_compile": seconds}
        print(f"{name:18s} dofs {robot.n_dofs:3d}  tip error median {np.median(err):7.2f} mm, max {err.max():7.2f} mm;"
              f" tangent median {np.median(ang):6.2f} deg", flush=True)
    out = {"reference": "split arm, quadratic curvature per link", "n_samples": n_samples,
           "actions": "turning angles uniform in [-2, 2] rad per control point and direction; gravity on",
           "models": rows}
    OUT.write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    args = dict(a.split("=", 1) for a in sys.argv[1:])
    main(int(args.get("n_samples", 16)))
