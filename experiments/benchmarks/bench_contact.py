"""The cost of contact: throws per second of the paper's swing, batched, with one sphere and
with 12 capsules in the way, against the same swing without contact.

Each throw is ``bench_sim``'s: theta(t) = 210 deg (t/T)^2, a 5.886 N tip force,
T ~ U[0.5, 3] s, simulated to release at delta T, delta ~ U[0.85, 1], with a fixed
number of steps per throw. All three configurations use the same integrator and
step count (``--integrator``, ``--steps``: rk4 and 1500 steps, dt <= 2 ms, what the
default contact stiffness allows), so the ratio is the cost of the contact
terms alone; the contact law (``gv.Contact()`` defaults, 21 samples on the arm) is
evaluated at every stage whether or not anything touches. Also reported, from a
separate run saving every step (batch ``--check-batch``): the deepest penetration
and the fraction of throws that touched anything or ended non-finite.

Obstacles: one sphere (r = 10 cm) at (0.75, -0.55, 0), which every throw hits; 12
capsules (r = 1.5 cm, 0.4 m long, along z) on a 3 x 4 grid across the swing's
upper half, some in reach and some not; and the same with either broad phase
(``Contact.nearest`` 4: the law on each piece's 4 nearest capsules; ``Contact.pairs`` 16: the
law on at most 16 (piece, capsule) pairs in reach along the link).

    python experiments/benchmarks/bench_contact.py [--repeats 5] [--batch 1024] [--json benchmarks/contact.json]

The machine's load average is recorded with the numbers (``uptime``): on a shared
machine the times are upper bounds; rerun on an idle one.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from bench_sim import actions, load_average, timed  # this folder is on sys.path when run as a script

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation

THETA_F = float(np.deg2rad(210.0))


def layouts() -> dict[str, gv.Contact | None]:
    sphere = gv.Sphere(centre=(0.75, -0.55, 0.0), radius=0.1)
    capsules = tuple(gv.Capsule(start=(x, y, -0.2), end=(x, y, 0.2), radius=0.015)
                     for x in (0.55, 0.8, 1.05) for y in (-0.9, -0.5, -0.1, 0.3))
    return {"none": None, "sphere": gv.Contact(obstacles=(sphere,)), "12 capsules": gv.Contact(obstacles=capsules),
            "12 capsules nearest 4": gv.Contact(obstacles=capsules, nearest=4),
            "12 capsules pairs 16": gv.Contact(obstacles=capsules, pairs=16)}


def make_throws(contact, n_steps: int, integrator: str, save_every: int | None = None):
    arm = gv.paper_arm(tip_force=5.886).replace(contact=contact)
    save = save_every or n_steps

    def throw(T, delta):
        traj = gv.simulate(arm, delta * T, n_steps=n_steps, save_every=save, integrator=integrator,
                           check_stability=False, base_angle=lambda t: THETA_F * (t / T) ** 2)
        return traj.tip[-1], traj.contact_gap, traj.in_contact

    return jax.jit(jax.vmap(throw))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--check-batch", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--integrator", default="rk4")
    ap.add_argument("--steps", type=int, default=1500)  # dt <= 2 ms for the longest throw
    ap.add_argument("--json", type=str, default=None)
    ap.add_argument("--layouts", type=str, default="none,sphere,12 capsules,12 capsules nearest 4,12 capsules pairs 16",
                    help="comma-separated, 'none' first")
    args = ap.parse_args()
    before = load_average()
    print(before)
    rows: list[dict] = []
    chosen = [name.strip() for name in args.layouts.split(",")]
    for name, contact in ((n, c) for n, c in layouts().items() if n in chosen):
        throws = make_throws(contact, args.steps, args.integrator)
        t0 = time.perf_counter()
        compile_s, run_s = timed(throws, *actions(args.batch), repeats=args.repeats)
        check = make_throws(contact, args.steps, args.integrator, save_every=1)
        tip, gap, touched = check(*actions(args.check_batch, seed=1))
        row = dict(layout=name, batch=args.batch, throws_per_s=args.batch / run_s, median_run_s=run_s,
                   compile_s=compile_s, loadavg=os.getloadavg(),
                   deepest_penetration_m=float(-jnp.min(gap)) if gap.size else 0.0,
                   fraction_touching=float(jnp.mean(jnp.any(touched, axis=-1))),
                   fraction_nonfinite=float(jnp.mean(~jnp.all(jnp.isfinite(tip), axis=-1))),
                   wall_s=time.perf_counter() - t0)
        rows.append(row)
        print(f"{name:>12}: {row['throws_per_s']:9.0f} throws/s (median of {args.repeats}: {run_s:.3f} s), "
              f"compile {compile_s:.1f} s, deepest penetration {row['deepest_penetration_m'] * 1e3:.2f} mm, "
              f"touching {row['fraction_touching']:.0%}, non-finite {row['fraction_nonfinite']:.0%}", flush=True)
        base = rows[0]["throws_per_s"]
        for r in rows:
            r["slowdown_vs_first"] = base / r["throws_per_s"]
        if args.json:  # after every layout: an interrupted run keeps what it measured
            with open(args.json, "w") as fh:
                json.dump(dict(command=shlex.join(["python", "experiments/benchmarks/bench_contact.py", *sys.argv[1:]]),
                               integrator=args.integrator, n_steps=args.steps, rows=rows, load_average_before=before,
                               load_average_after=load_average(), getloadavg_after=os.getloadavg(),
                               cpu_count=jax.local_device_count(),
                               jax=jax.__version__), fh, indent=2)
    print("slowdown against the first layout: "
          + ", ".join(f"{r['layout']}: {r['slowdown_vs_first']:.2f}x" for r in rows))


if __name__ == "__main__":
    main()
