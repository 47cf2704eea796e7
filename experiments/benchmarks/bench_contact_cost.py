"""The cost of contact on the obstacle tasks' 3D arm, against the number of obstacles and the batch.

The arm is reach_obstacles' (``gv.soft_arm`` with the task's penalty and 11 contact
samples), stepped by ``gv.simulate`` with ``ars443`` at a 5 ms step from rest under
random held tendon tensions (up to ``--tension`` N), ``jit(vmap)``-ed over a batch.
Layouts: no contact at all (``Robot.contact`` None, the reference), the contact
with no obstacles (the samples' kinematics and J^T w alone), one sphere in
reach (r 0.1 m at (0.35, 0, 0.75)), and 1, 4, 12 or 48 capsules: the first of the
cage's bars (``reach_obstacles.layouts.cage``: twelve 3 cm bars) and the cage turned
by 90, 180 and 270 degrees about the arm (48 bars all round it), with the task's broad
phase (``Contact.pairs``) or another (", all pairs", ", K pairs", ", nearest K"); ", rows split" reads
the recursion's points as the contact did before it read a scanned link's stacked point. Cost per arm-step
(us) is the call's time over batch x steps; every layout of a batch is compiled
first and then timed in ``--rounds`` round-robin rounds (A B C ... A B C ...), so the
ratios to the contact-free step are taken within one run under the same load; each
time is the median over the rounds. A separate saved run reports the deepest
penetration and the fraction of runs that touched, so a change of the law that
changes the physics shows.

    python experiments/benchmarks/bench_contact_cost.py --json benchmarks/contact_cost.json
    python experiments/benchmarks/bench_contact_cost.py --figure figures/contact_cost.png  # from the JSON
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv  # noqa: F401  (XLA flags first)
from gvsjax.core import contact as core_contact
from gvsjax.core.kinematics import rows
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


ROWS_SPLIT = ", rows split"


def layouts(names: list[str]) -> dict[str, tuple | None]:
    table: dict[str, tuple | None] = {"none": None, "0 obstacles": (), "sphere": (SPHERE,)}
    # "N capsules", "N capsules, all pairs", "N capsules, K pairs": the first N bars
    plain = {k: k.removesuffix(ROWS_SPLIT) for k in names}
    return {k: table[b] if b in table else bars(int(b.split(" capsules")[0])) for k, b in plain.items()}


@contextlib.contextmanager
def rows_split(on: bool):
    """With ``on``, the contact reads the recursion's points with each scanned link's stacked point
    split into one point per row (the data path before the samples read the stacked point)."""
    if not on:
        yield
        return
    evaluate = core_contact.evaluate
    core_contact.evaluate = lambda robot, points, *a: evaluate(robot, rows(points), *a)
    try:
        yield
    finally:
        core_contact.evaluate = evaluate


def robot(name: str, obstacles):
    """The task's arm with ``obstacles`` and its broad phase (``Contact.pairs``), or another:
    "N capsules, all pairs" none, "N capsules, K pairs" ``pairs=K``, "N capsules, nearest K"
    ``nearest=K`` (each piece's K nearest)."""
    arm = contact_arm()
    name = name.removesuffix(ROWS_SPLIT)
    if obstacles is None:
        return arm.replace(contact=None)
    contact = arm.contact.replace(obstacles=obstacles)
    variant = name.split(", ")[-1] if ", " in name else ""
    if variant == "all pairs":
        contact = contact.replace(nearest=None, pairs=None)
    elif variant.endswith(" pairs"):
        contact = contact.replace(nearest=None, pairs=int(variant.split()[0]))
    elif variant.startswith("nearest "):
        contact = contact.replace(nearest=int(variant.split()[1]), pairs=None)
    return arm.replace(contact=contact)


def runner(name: str, obstacles, n_steps: int, dtype, save: bool = False):
    """jit(vmap) of tensions (batch, 8) -> final q (or the saved gaps and the final q)."""
    r = robot(name, obstacles)

    def run(tension):
        with rows_split(name.endswith(ROWS_SPLIT)):  # patched while jit traces
            tr = gv.simulate(r, n_steps * DT, n_steps=n_steps, tendon_force=tension, integrator="ars443",
                             dtype=dtype, save_every=1 if save else n_steps, check_stability=False)
        return (tr.contact_gap, tr.q[-1]) if save else tr.q[-1]

    return jax.jit(jax.vmap(run))


def tensions(batch: int, high: float, dtype, seed: int = 0):
    return jax.random.uniform(jax.random.PRNGKey(seed), (batch, 8), dtype, maxval=high)


def figure(path: str, out: str) -> None:
    """The cost ratio against the number of obstacles (largest batch) and against the batch."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = json.loads(Path(path).read_text())
    before_path = Path(path.replace(".json", "_before.json"))
    before = json.loads(before_path.read_text()) if before_path.exists() else None
    top = max(r["batch"] for r in d["rows"])
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))

    def series(data, suffix, batch):
        pts = sorted((int(r["layout"].split()[0]), r["ratio_to_no_contact"]) for r in data["rows"]
                     if r["batch"] == batch and r["layout"].endswith("capsules" + suffix))
        return [x for x, _ in pts], [y for _, y in pts]

    a.plot(*series(d, "", top), "o-", label="now (the task's arm: at most 16 pairs in reach)")
    a.plot(*series(d, ", nearest 4", top), "^-.", label="each piece's 4 nearest")
    a.plot(*series(d, ", all pairs", top), "s--", label="all pairs")
    if before:
        a.plot(*series(before, "", top), "x:", color="grey", label="before")
    for name, style in (("sphere", "C3"), ("0 obstacles", "C7")):
        r = next((r for r in d["rows"] if r["layout"] == name and r["batch"] == top), None)
        if r:
            a.axhline(r["ratio_to_no_contact"], color=style, lw=0.8, ls="-.", label=f"{name} (now)")
    a.axhline(3.0, color="k", lw=0.5, label="target for 12 capsules: 3x")
    a.set_ylim(0.0, None)
    a.set_xscale("log")
    a.set_xticks([1, 4, 12, 48], ["1", "4", "12", "48"])
    a.set_xlabel("capsules")
    a.set_ylabel("cost per step / contact-free step")
    a.set_title(f"batch {top}")
    a.legend(fontsize=7)
    for name in dict.fromkeys(r["layout"] for r in d["rows"]):
        pts = sorted((r["batch"], r["ratio_to_no_contact"]) for r in d["rows"] if r["layout"] == name)
        if name != "none" and len(pts) > 1:
            b.plot([x for x, _ in pts], [y for _, y in pts], "o-", label=name)
    b.set_xscale("log")
    b.set_ylim(1.0, None)
    b.set_xlabel("batch")
    b.set_ylabel("cost per step / contact-free step")
    b.set_title("against the batch")
    b.legend(fontsize=7)
    fig.suptitle(f"contact on the obstacle tasks' arm ({d['integrator']}, {1e3 * d['dt']:g} ms, {d['dtype']})")
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batches", type=int, nargs="*", default=[1, 64, 1024])
    ap.add_argument("--layouts", nargs="+", default=["none", "sphere", "1 capsules", "4 capsules", "12 capsules",
                                                     "48 capsules"])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--tension", type=float, default=1500.0)
    ap.add_argument("--check-steps", type=int, default=200, help="steps of the saved run (penetration)")
    ap.add_argument("--check-batch", type=int, default=32)
    ap.add_argument("--check-layouts", nargs="*", default=None, help="default: --layouts")
    ap.add_argument("--dtype", default="float64")
    ap.add_argument("--json", default=None)
    ap.add_argument("--figure", default=None, help="only draw this png from the JSON at --json")
    ap.add_argument("--append", action="store_true", help="add this run's rows to the JSON at --json")
    args = ap.parse_args()
    if args.figure:
        figure(args.json or "benchmarks/contact_cost.json", args.figure)
        return
    dtype = jnp.dtype(args.dtype)
    chosen = layouts(args.layouts)
    out: dict = dict(dt=DT, integrator="ars443", dtype=args.dtype, steps_per_call=args.steps, rounds=args.rounds,
                     tension_max=args.tension, loadavg_before=os.getloadavg(), jax=jax.__version__, rows=[],
                     accuracy=[], accuracy_batch=args.check_batch, accuracy_steps=args.check_steps)
    if args.append:
        with open(args.json) as fh:
            out = {**json.load(fh), "loadavg_before_appended_run": os.getloadavg()}
    for name, obs in layouts(args.check_layouts if args.check_layouts is not None else args.layouts).items():
        # the physics: deepest penetration over a longer saved run, and the final states' mean (a checksum)
        check = runner(name, obs, args.check_steps, dtype, save=True)
        gap, q = check(tensions(args.check_batch, args.tension, dtype, 1))
        row = dict(layout=name, deepest_penetration_m=float(-jnp.min(gap)) if gap.size else 0.0,
                   fraction_touching=float(jnp.mean(jnp.any(gap < 0, axis=(-2, -1)))) if gap.size else 0.0,
                   fraction_finite=float(jnp.mean(jnp.all(jnp.isfinite(q), axis=-1))),
                   mean_final_q=float(jnp.mean(q)), mean_abs_final_q=float(jnp.mean(jnp.abs(q))))
        out["accuracy"].append(row)
        print(row, flush=True)
    for batch in args.batches:
        x = tensions(batch, args.tension, dtype)
        fns, compile_s = {}, {}
        for name, obs in chosen.items():
            fns[name] = runner(name, obs, args.steps, dtype)
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
