"""A 3D static load case: ``gv.equilibrium`` against PyElastica run to rest.

The rod: 1 m, radius 5 cm, E = 50 MPa, G = E/3, density 1000 kg/m^3, clamped at the
origin along +x. Loads: its weight along -y (77 N/m) and a dead tip force along +z
(100 N). The two bendings are not coplanar, so the equilibrium is a 3D curve with
torsion; the weight alone bends it by ~0.3 of the elastica's w L^3 / EI = 1 scale.

gvsjax: ``gv.equilibrium`` (Newton with continuation) on ``gv.rod_3d`` with all six
strains, bendings and torsion as Legendre polynomials of growing order (stretch and
shear constant), to show the basis convergence.

PyElastica: a ``CosseratRod`` of 100, 200 and 400 elements (shearable and extensible), the clamp by
``OneEndFixedBC``, ``GravityForces``, the tip force by ``EndpointForces`` ramped over
0.5 s, and ``AnalyticalLinearDamper`` to bring it to rest (the damping changes the path,
not the equilibrium); position Verlet at dt = 1e-5 s x 100 / elements for 3 s, after which
every node must move slower than 1e-6 m/s. Its tip converges slowly in the element count
(~1 mm between 100 and 200 elements here), so the three runs are Richardson-extrapolated
with their observed order. Its shear stiffness carries the circular section's 4/3 shear factor; gvsjax's
does not, an O((r/L)^2 P / GA) difference in the tip (here < 0.1 mm).

    pip install -e ".[bench]"
    python experiments/transfer/statics_pyelastica.py            # ~6 min on 2 cores

Writes benchmarks/statics_pyelastica.json and prints a Markdown table.
"""

from __future__ import annotations

import json
import os
import time

import numpy as np

import gvsjax as gv  # configures JAX before any computation

L, R, E, RHO, G_ACC, FZ = 1.0, 0.05, 5e7, 1000.0, 9.81, 100.0
T_END = 3.0  # s simulated by PyElastica; the damper settles the first mode in ~0.2 s
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def gvsjax_tip(order: int) -> tuple[np.ndarray, float, bool]:
    rod = gv.rod_3d(length=L, radius=R, youngs_modulus=E, density=RHO, gravity=G_ACC,
                    order=(order, order, order, 0, 0, 0), n_gauss=order + 1, basis="legendre")
    rod = rod.replace(loads=(gv.PointLoad(magnitude=FZ, link=0, X=1.0, direction=(0.0, 0.0, 1.0)),))
    t0 = time.perf_counter()
    res = gv.equilibrium(rod, load_scale_steps=4)
    tip = np.asarray(gv.backbone(rod, res.q)[-1])
    return tip, time.perf_counter() - t0, bool(res.converged)


def pyelastica_tip(n_elem: int = 100, dt: float = 1e-5) -> tuple[np.ndarray, float, float]:
    """Tip at rest, wall time, max node speed at the end."""
    import elastica as ea

    class Rod(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    sim = Rod()
    rod = ea.CosseratRod.straight_rod(n_elem, np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]),
                                      L, R, RHO, youngs_modulus=E, shear_modulus=E / 3.0)
    sim.append(rod)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
    sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([0.0, -G_ACC, 0.0]))
    sim.add_forcing_to(rod).using(ea.EndpointForces, start_force=np.zeros(3), end_force=np.array([0.0, 0.0, FZ]),
                                  ramp_up_time=0.5)
    sim.dampen(rod).using(ea.AnalyticalLinearDamper, uniform_damping_constant=40.0, time_step=dt)
    sim.finalize()
    stepper = ea.PositionVerlet()
    t0 = time.perf_counter()
    ea.integrate(stepper, sim, T_END, int(round(T_END / dt)), progress_bar=False)
    speed = float(np.abs(rod.velocity_collection).max())
    if speed > 1e-6:
        raise RuntimeError(f"PyElastica not at rest after {T_END} s (max speed {speed:.2e} m/s)")
    return rod.position_collection[:, -1].copy(), time.perf_counter() - t0, speed


def main() -> None:
    rows = []
    for order in (1, 2, 3):
        tip, wall, ok = gvsjax_tip(order)
        rows.append({"order": order, "tip": tip.tolist(), "wall_s": wall, "converged": ok})
        print(f"gvsjax order {order}: tip {np.round(tip, 5)} ({wall:.1f} s incl. compile, converged {ok})", flush=True)
    refs = {}
    for n_elem in (100, 200, 400):
        tip, wall, speed = pyelastica_tip(n_elem, dt=1e-5 * 100 / n_elem)
        refs[n_elem] = {"tip": tip.tolist(), "wall_s": wall, "final_speed": speed}
        print(f"PyElastica ({n_elem} elements): tip {np.round(tip, 5)} (max speed {speed:.1e} m/s after {T_END} s; "
              f"{wall:.0f} s wall)", flush=True)
    t1, t2, t3 = (np.asarray(refs[n]["tip"]) for n in (100, 200, 400))
    order = float(np.log2(np.linalg.norm(t2 - t1) / np.linalg.norm(t3 - t2)))  # observed convergence order
    ref = t3 + (t3 - t2) / (2**order - 1)  # Richardson extrapolation to infinitely many elements
    print(f"PyElastica converges with order {order:.2f} in the element count; extrapolated tip {np.round(ref, 5)}")
    print("\n| gvsjax basis (bending, torsion order) | tip (m) | to PyElastica 100 / 200 / 400 el. / extrap. (mm) |"
          "\n|---|---|---|")
    for r in rows:
        tip = np.asarray(r["tip"])
        d = [1e3 * float(np.linalg.norm(tip - x)) for x in (t1, t2, t3, ref)]
        r["distance_mm"] = dict(zip(("100", "200", "400", "extrapolated"), d))
        print(f"| {r['order']} | ({tip[0]:.4f}, {tip[1]:.4f}, {tip[2]:.4f}) | "
              f"{d[0]:.2f} / {d[1]:.2f} / {d[2]:.2f} / {d[3]:.2f} |")
    out = {"case": {"L": L, "radius": R, "E": E, "G": E / 3, "density": RHO, "gravity": G_ACC, "tip_force_z": FZ},
           "gvsjax": rows, "pyelastica": {"runs": refs, "observed_order": order, "extrapolated_tip": ref.tolist()}}
    with open(os.path.join(ROOT, "benchmarks", "statics_pyelastica.json"), "w") as f:
        json.dump(out, f, indent=2)


if __name__ == "__main__":
    main()
