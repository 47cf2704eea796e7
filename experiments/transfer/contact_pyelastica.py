"""The paper's arm swung against a fixed sphere: gvsjax's contact against PyElastica's.

The swing of ``bench_pyelastica.py`` (theta(t) = 210 deg (t/T)^2 about +z, T = 2 s, the ball's
5.886 N on the tip, gravity along -y), run for 1.8 s with a sphere (r = 10 cm) at
(0.75, -0.55, 0) m in the arm's way, friction off. The base keeps turning, so the arm is driven
into the sphere, bends round it and slides off its top.

* gvsjax: ``gv.paper_arm`` with ``gv.Contact(obstacles=(sphere,))`` at its defaults (penalty
  k = 1e7 N/m^2, c = 5e3 N s/m^2 per metre of rod, 21 tube pieces), ars443 at 1 ms, for the
  paper's 2-mode basis and richer Legendre bases (the arm's shape around a contact is
  local, which 2 modes cannot draw).
* PyElastica: 100-element ``CosseratRod`` (shear and stretch, Kelvin-Voigt damping as in
  ``bench_pyelastica.py``), its ``RodSphereContact`` (a spring-damper on the penetration of each
  element's cylinder, no friction) against an ``ea.Sphere`` held by ``FixedConstraint``; the
  per-element constants are gvsjax's per-metre ones times the element length (k l, c l),
  so both penalties press equally per metre of rod.

Also run without the sphere, to separate the contact's share of the difference from the
two models' own difference in the swing. Writes ``benchmarks/contact_pyelastica.json`` and
``figures/contact_pyelastica.png``; ~10 min on 2 idle cores (PyElastica's 18,000 steps
with contact take most of it).

    pip install -e ".[bench]"
    python experiments/transfer/contact_pyelastica.py [--modes 2,4,8] [--elements 100] [--dt 1e-4]
    python experiments/transfer/contact_pyelastica.py --replot    # the figure from the JSON
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import jax
import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[1] / "benchmarks"))  # bench_pyelastica, bench_sim
from bench_pyelastica import BALL, THETA_F, _elastica, swinging_rod
from bench_sim import load_average

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation

P = gv.PAPER_ARM
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
T_SWING, DURATION, SAVE = 2.0, 1.8, 0.01  # s
CENTRE, RADIUS = np.array([0.75, -0.55, 0.0]), 0.1  # m


def gvsjax_path(n_modes: int, with_sphere: bool, dt: float = 1e-3) -> dict:
    """Tip path (every SAVE s from t = 0), deepest penetration and peak total contact force."""
    contact = gv.Contact(obstacles=(gv.Sphere(centre=tuple(CENTRE), radius=RADIUS),)) if with_sphere else None
    arm = gv.paper_arm(tip_force=BALL, n_modes=n_modes, n_gauss=max(5, n_modes + 1),
                       basis="monomial" if n_modes <= 2 else "legendre").replace(contact=contact)
    every = int(round(SAVE / dt))
    run = jax.jit(lambda: gv.simulate(arm, DURATION, dt, save_every=every, integrator="ars443",
                                      base_angle=lambda t: THETA_F * (t / T_SWING) ** 2))
    t0 = time.perf_counter()
    traj = jax.block_until_ready(run())
    tip = np.asarray(traj.tip)
    t = np.asarray(traj.t)
    if abs(t[0]) > 1e-12:  # saved states start one stride in: prepend the rest state
        tip = np.vstack([[0.0, -P["length"], 0.0], tip])  # q = 0: straight, hanging
        t = np.concatenate([[0.0], t])
    force = np.linalg.norm(np.asarray(traj.contact_force).sum(axis=1), axis=-1) if with_sphere else np.zeros(len(t))
    gap = np.asarray(traj.contact_gap)
    return dict(t=t, tip=tip, wall_s=time.perf_counter() - t0,
                deepest_m=float(max(0.0, -gap.min())) if gap.size else 0.0, peak_force_n=float(force.max()))


def pyelastica_path(with_sphere: bool, n_elements: int, dt: float) -> dict:
    ea, KelvinVoigtDamper, _, _ = _elastica()

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping, ea.Contact):
        pass

    sim = Sim()
    rod = swinging_rod(sim, n_elements, T_SWING)
    if with_sphere:
        sphere = ea.Sphere(center=CENTRE.copy(), base_radius=RADIUS, density=1000.0)
        sim.append(sphere)
        sim.constrain(sphere).using(ea.FixedConstraint, constrained_position_idx=(0,), constrained_director_idx=(0,))
        pen = gv.contact.Penalty()
        l_elem = P["length"] / n_elements
        sim.detect_contact_between(rod, sphere).using(ea.RodSphereContact, k=float(pen.stiffness) * l_elem,
                                                      nu=float(pen.damping) * l_elem)
    n_steps = int(round(DURATION / dt))
    h = DURATION / n_steps
    every = int(round(SAVE / h))
    sim.dampen(rod).using(KelvinVoigtDamper, time_step=h, eta=P["damping"], radius=P["radius"])
    sim.finalize()
    stepper = ea.PositionVerlet()
    tips, deepest, t = [rod.position_collection[:, -1].copy()], 0.0, np.float64(0.0)
    t0 = time.perf_counter()
    for i in range(n_steps):
        t = stepper.step(sim, t, np.float64(h))
        if with_sphere:  # the same measure as gvsjax's gap: element segment to sphere, minus radii
            a, b = rod.position_collection[:, :-1], rod.position_collection[:, 1:]
            d = b - a
            s = np.clip(np.einsum("ij,ij->j", CENTRE[:, None] - a, d) / np.einsum("ij,ij->j", d, d), 0.0, 1.0)
            dist = np.linalg.norm(a + s * d - CENTRE[:, None], axis=0)
            deepest = max(deepest, float(np.max(RADIUS + rod.radius - dist)))
        if (i + 1) % every == 0:
            tips.append(rod.position_collection[:, -1].copy())
    return dict(t=np.arange(len(tips)) * every * h, tip=np.array(tips), wall_s=time.perf_counter() - t0,
                deepest_m=deepest, dt=h)


def plot(runs: dict, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.6))
    ax.add_patch(plt.Circle(CENTRE[:2], RADIUS, color="0.75", label="sphere (r 10 cm)"))
    ax.add_patch(plt.Circle(CENTRE[:2], RADIUS + P["radius"], fill=False, ls=":", color="0.5",
                            label="reach of the rod's axis"))
    ref = runs["pyelastica, sphere"]
    for name, r in runs.items():
        style = dict(lw=2.2, color="k") if name.startswith("pyelastica") else dict(lw=1.2)
        if "no sphere" in name:
            style.update(ls="--", alpha=0.6)
        ax.plot(r["tip"][:, 0], r["tip"][:, 1], label=name, **style)
        if "sphere" in name and "no sphere" not in name and not name.startswith("pyelastica"):
            bx.plot(r["t"], 100 * np.linalg.norm(r["tip"] - ref["tip"], axis=1), label=name)
    gv_free = next(v for k, v in runs.items() if k.startswith("gvsjax") and "no sphere" in k)
    bx.plot(gv_free["t"], 100 * np.linalg.norm(gv_free["tip"] - runs["pyelastica, no sphere"]["tip"], axis=1),
            ls="--", color="0.4", label="without the sphere (" + gv_free["name"] + ")")
    ax.set(xlabel="x (m)", ylabel="y (m)", title="tip paths, 0-1.8 s of the T = 2 s swing", aspect="equal")
    ax.legend(fontsize=7, loc="upper left")
    bx.axhline(2.0, color="r", lw=0.8, ls=":", label="2 cm")
    bx.set(xlabel="t (s)", ylabel="|tip - PyElastica's tip| (cm)", title="distance to PyElastica's tip")
    bx.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=120)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--modes", default="2,4,8", help="comma-separated bending modes of the gvsjax arm")
    ap.add_argument("--elements", type=int, default=100)
    ap.add_argument("--dt", type=float, default=1e-4, help="PyElastica's step, s")
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "contact_pyelastica.json"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "figures", "contact_pyelastica.png"))
    ap.add_argument("--replot", action="store_true", help="only redraw the figure from the JSON's paths")
    args = ap.parse_args()
    if args.replot:
        with open(args.json) as fh:
            saved = json.load(fh)["paths"]
        plot({k: {**v, "t": np.array(v["t"]), "tip": np.array(v["tip"])} for k, v in saved.items()}, args.figure)
        return
    before = load_average()
    modes = [int(m) for m in args.modes.split(",")]
    runs: dict[str, dict] = {}
    for with_sphere in (True, False):
        tag = "sphere" if with_sphere else "no sphere"
        runs[f"pyelastica, {tag}"] = pyelastica_path(with_sphere, args.elements, args.dt)
        for m in modes if with_sphere else modes[-1:]:
            runs[f"gvsjax {m} modes, {tag}"] = dict(gvsjax_path(m, with_sphere), name=f"gvsjax {m} modes")
    rows = []
    for name, r in runs.items():
        if name.startswith("gvsjax"):
            ref = runs["pyelastica, " + name.split(", ")[1]]
            assert np.allclose(r["t"], ref["t"]), (name, r["t"][:3], ref["t"][:3])
            dist = np.linalg.norm(r["tip"] - ref["tip"], axis=1)
            rows.append(dict(run=name, max_tip_distance_m=float(dist.max()), final_tip_distance_m=float(dist[-1]),
                             deepest_penetration_m=r["deepest_m"], peak_contact_force_n=r["peak_force_n"],
                             pyelastica_deepest_m=ref["deepest_m"], wall_s=r["wall_s"]))
            print(f"{name:>26}: tip within {dist.max() * 100:.2f} cm of PyElastica's over the swing "
                  f"(final {dist[-1] * 100:.2f} cm); deepest {r['deepest_m'] * 1e3:.2f} mm "
                  f"(PyElastica {ref['deepest_m'] * 1e3:.2f} mm); peak force {r['peak_force_n']:.0f} N", flush=True)
    plot(runs, args.figure)
    with open(args.json, "w") as fh:
        json.dump(dict(command="python experiments/transfer/contact_pyelastica.py " + f"--modes {args.modes} "
                       f"--elements {args.elements} --dt {args.dt}", rows=rows,
                       pyelastica_dt=runs["pyelastica, sphere"]["dt"], gvsjax_dt=1e-3, integrator="ars443",
                       load_average_before=before, load_average_after=load_average(),
                       paths={k: dict(t=v["t"].tolist(), tip=v["tip"].tolist(), name=v.get("name", k))
                              for k, v in runs.items()}), fh)
    print(f"wrote {args.json} and {args.figure}")


if __name__ == "__main__":
    main()
