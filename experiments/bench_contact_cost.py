"""The cost of contact on the obstacle tasks' 3D arm, against the number of obstacles and the batch.

The arm is reach_obstacles' (``gv.soft_arm`` with the task's penalty and 11 contact
samples), stepped by ``gv.simulate`` with ``ars443`` at a 5 ms step from rest under
random held tendon tensions (up to ``--tension`` N), ``jit(vmap)``-ed over a batch.
Layouts: no contact at all (``Robot.contact`` None, the reference), the contact
with no obstacles (the samples' kinematics and J^T w alone), one sphere in
reach (r 0.1 m at (0.35, 0, 0.75)), and 1, 4, 12 or 48 capsules: the first of the
cage's bars (``reach_obstacles.layouts.cage``: twelve 3 cm bars) and the cage turned
by 90, 180 and 270 degrees about the arm (48 bars all round it). Cost per arm-step
(us) is the call's time over batch x steps; every layout of a batch is compiled
first and then timed in ``--rounds`` round-robin rounds (A B C ... A B C ...), so the
ratios to the contact-free step are taken within one run under the same load; each
time is the median over the rounds. A separate saved run reports the deepest
penetration and the fraction of runs that touched, so a change of the law that
changes the physics shows.

    python experiments/bench_contact_cost.py --json benchmarks/contact_cost.json
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv  # noqa: F401  (XLA flags first)
from gvsjax.tasks.reach_obstacles.layouts import cage, contact_arm, turn

DT = 5e-3  # s
SPHERE = gv.Sphere(centre=(0.35, 0.0, 0.75), radius=0.1)


def bars(n: int) -> tuple:
    """The first ``n`` of the cage's bars and of its copies turned by 90, 180 and 270 degrees."""
    c = cage()
    out = []
    for k in range(4):
        yaw = 0.5 * np.pi * k
        s, e = (np.asarray(turn(jnp.asarray(c[x]), yaw)) for x in ("start", "end"))
        out += [gv.Capsule(start=tuple(map(float, a)), end=tuple(map(float, b)), radius=float(r))
                for a, b, r in zip(s, e, c["radius"])]
    return tuple(out[:n])


def layouts(names: list[str]) -> dict[str, tuple | None]:
    table: dict[str, tuple | None] = {"none": None, "0 obstacles": (), "sphere": (SPHERE,)}
    table.update({f"{n} capsules": bars(n) for n in (1, 4, 12, 48)})
    return {k: table[k] for k in names}


def robot(obstacles):
    arm = contact_arm()
    if obstacles is None:
        return arm.replace(contact=None)
    return arm.replace(contact=arm.contact.replace(obstacles=obstacles))


def runner(obstacles, n_steps: int, dtype, save: bool = False):
    """jit(vmap) of tensions (batch, 8) -> final q (or the saved gaps)."""
    r = robot(obstacles)

    def run(tension):
        tr = gv.simulate(r, n_steps * DT, n_steps=n_steps, tendon_force=tension, integrator="ars443", dtype=dtype,
                         save_every=1 if save else n_steps, check_stability=False)
        return (tr.contact_gap, tr.q[-1]) if save else tr.q[-1]

    return jax.jit(jax.vmap(run))


def tensions(batch: int, high: float, dtype, seed: int = 0):
    return jax.random.uniform(jax.random.PRNGKey(seed), (batch, 8), dtype, maxval=high)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 64, 1024])
    ap.add_argument("--layouts", nargs="+", default=["none", "sphere", "1 capsules", "4 capsules", "12 capsules",
                                                     "48 capsules"])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--tension", type=float, default=300.0)
    ap.add_argument("--check-steps", type=int, default=100, help="steps of the saved run (penetration)")
    ap.add_argument("--check-batch", type=int, default=64)
    ap.add_argument("--dtype", default="float64")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    dtype = jnp.dtype(args.dtype)
    chosen = layouts(args.layouts)
    out: dict = dict(dt=DT, integrator="ars443", dtype=args.dtype, steps_per_call=args.steps, rounds=args.rounds,
                     tension_max=args.tension, loadavg_before=os.getloadavg(), jax=jax.__version__, rows=[],
                     accuracy=[])
    for name, obs in chosen.items():  # the physics: deepest penetration over a longer saved run
        gap, q = runner(obs, args.check_steps, dtype, save=True)(tensions(args.check_batch, args.tension, dtype, 1))
        row = dict(layout=name, deepest_penetration_m=float(-jnp.min(gap)) if gap.size else 0.0,
                   fraction_touching=float(jnp.mean(jnp.any(gap < 0, axis=(-2, -1)))) if gap.size else 0.0,
                   fraction_finite=float(jnp.mean(jnp.all(jnp.isfinite(q), axis=-1))))
        out["accuracy"].append(row)
        print(row, flush=True)
    for batch in args.batches:
        x = tensions(batch, args.tension, dtype)
        fns, compile_s = {}, {}
        for name, obs in chosen.items():
            fns[name] = runner(obs, args.steps, dtype)
            t0 = time.perf_counter()
            jax.block_until_ready(fns[name](x))
            compile_s[name] = time.perf_counter() - t0
        times: dict[str, list] = {name: [] for name in chosen}
        for _ in range(args.rounds):
            for name, f in fns.items():
                t0 = time.perf_counter()
                jax.block_until_ready(f(x))
                times[name].append(time.perf_counter() - t0)
        ref = statistics.median(times["none"]) if "none" in times else None
        for name in chosen:
            s = statistics.median(times[name])
            row = dict(layout=name, batch=batch, median_call_s=s, us_per_arm_step=1e6 * s / (batch * args.steps),
                       times_s=times[name], first_call_s=compile_s[name],
                       ratio_to_no_contact=s / ref if ref else None, loadavg=os.getloadavg())
            out["rows"].append(row)
            print(f"batch {batch:5d} {name:>12}: {row['us_per_arm_step']:8.2f} us/arm-step"
                  + (f", {row['ratio_to_no_contact']:.2f}x" if ref else ""), flush=True)
        if args.json:  # after every batch: an interrupted run keeps what it measured
            out["loadavg_after"] = os.getloadavg()
            with open(args.json, "w") as fh:
                json.dump(out, fh, indent=2)


if __name__ == "__main__":
    main()
