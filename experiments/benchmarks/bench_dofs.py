"""Cost against degrees of freedom of spatial rods (issue 20, "3D at scale").

Two families of clamped spatial rods (1 m, r = 5 cm, E = 5 MPa, 1000 kg/m^3, eta = 1e5 Pa s,
gravity 9.81 m/s^2 along -y), all six strains active, Legendre basis:

- ``rod<k>``, k = 0..5: one soft link, every strain of order k (``gv.rod_3d(order=k)``), 6 (k + 1)
  DoFs, n_gauss = k + 2;
- ``chain<k>``, k = 1..6: k soft links of length 1/k, every strain of order 0, joined by fixed
  joints (a piecewise-constant-strain rod of k pieces), 6 k DoFs, n_gauss = 2 per link.

n_gauss = order + 2 per link in both: one more than the fewest the basis allows (order + 1), as
the other benchmarks do (``bench_scaling``: n_modes + 2), so in both families the Gauss points
grow with the DoFs, as when a user refines a model. ``chain1`` is the same robot as ``rod0``.

Each configuration is run with every soft link's ``SoftLink.recursion`` = "unrolled" and = "scan"
(both compute the same sums; the tips must agree to ~1e-12 m). ``--recursions scan-scalar`` (or
``unrolled-scalar``) runs that recursion with every SPD solve in scalar form, where from
``linalg.STACKED_MIN_DOFS`` DoFs it would run on stacked arrays: the crossover of the two solve
layouts. Measured for a jitted, vmapped
``gv.simulate(robot, T, n_steps=N, save_every=N, integrator="ars443", check_stability=False)``
over a batch of durations T (N dt (1 + 0.2 i / (batch - 1)), dt = 1 ms) from a random bent
state at rest (angular strains ~ N(0, 0.2^2), seed 0), at batch 1 and 1024:

- compile time: ``jit(vmap(run)).lower(T)`` (trace and lowering) plus ``.compile()`` (XLA);
- step time: the median of ``--repeats`` calls of the compiled program, divided by N (seconds per
  step of the whole batch);
- memory: the compiled program's planned memory (``compiled.memory_analysis()``: arguments +
  outputs + temporaries - aliased) and the measuring process's peak RSS (compilation included);
- the size of the lowered program (lines of its StableHLO text);
- the tip difference between the two recursions (the batch-1 tip and 16 lanes of the batch).

Every (configuration, recursion) runs in its own process with a time budget (``--budget`` s for
both batches): one over budget is killed and recorded as such (with what it measured before), and
the larger configurations of its family with the same recursion are then skipped. The unrolled
recursion is skipped beyond ``--unrolled-max-dofs`` DoFs (its compile time grows fastest). The
reason for every skip is in the JSON, which is rewritten after each configuration, so a stopped run
keeps what it measured (``--merge`` adds to an existing file instead of starting a new one).
Reported at the end: the fitted exponent p of step time ~ n^p and compile time ~ n^p per family,
recursion and batch, and the scan / unrolled ratios. ``--replot`` redraws the figure
(``figures/bench_dofs.png``: compile time, memory and step time vs DoFs, log axes, an n^2 line).

    python experiments/benchmarks/bench_dofs.py --quick                          # rod0-1, chain1-2 (28 min at load 6)
    python experiments/benchmarks/bench_dofs.py                                  # everything (hours)
    python experiments/benchmarks/bench_dofs.py --configs rod2,rod3 --recursions scan --merge
    python experiments/benchmarks/bench_dofs.py --configs rod1,rod2,rod3,chain2 --recursions scan-scalar --merge
    python experiments/benchmarks/bench_dofs.py --replot

The load average is recorded with every row (``uptime``): on a shared machine the times are
upper bounds.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_sim import load_average  # noqa: E402

from gvsjax.core import integrators, linalg, scan  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FIG = os.path.join(ROOT, "figures")
DT = 1e-3
RECURSIONS = ("unrolled", "scan")
# "<recursion>-scalar": that recursion with every SPD solve in scalar form (``linalg.STACKED_MIN_DOFS``
# out of reach), to measure the crossover of the two solve layouts
SCALAR = "-scalar"
CONFIGS = tuple(f"rod{k}" for k in range(6)) + tuple(f"chain{k}" for k in range(1, 7))
QUICK = ("rod0", "rod1", "chain1", "chain2")
N_LANES = 16  # lanes of the big batch kept for the tip comparison


def build(config: str, recursion: str) -> gv.Robot:
    """The robot of ``config`` with every soft link's ``recursion``."""
    if config.startswith("rod"):
        order = int(config[3:])
        robot = gv.rod_3d(order=order, n_gauss=order + 2, gravity=9.81)
    elif config.startswith("chain"):
        k = int(config[5:])
        link = gv.rod_3d(length=1.0 / k, order=0, n_gauss=2).links[0]  # joint: fixed
        robot = gv.Robot(links=(link,) * k, gravity=9.81)
    else:
        raise ValueError(f"unknown configuration {config!r}; choose from {CONFIGS}")
    recursion = recursion.removesuffix(SCALAR)
    if recursion not in (*RECURSIONS, "auto"):
        raise ValueError(f"recursion={recursion!r}: expected one of {RECURSIONS}, optionally with {SCALAR!r}")
    return robot.replace(links=tuple(link.replace(recursion=recursion) for link in robot.links))


def describe(config: str) -> dict:
    robot = build(config, "auto")
    links = robot.links
    return dict(config=config, family="rod" if config.startswith("rod") else "chain", dofs=robot.n_dofs,
                n_links=len(links), order=max(links[0].basis.orders), n_gauss_per_link=links[0].n_gauss,
                n_gauss_total=sum(link.n_gauss for link in links),
                auto_recursion="scan" if scan.uses_scan(links[-1], robot.n_dofs) else "unrolled",
                ars443_layout=("stacked" if len(robot.free) >= linalg.STACKED_MIN_DOFS
                               else "folded" if len(robot.free) >= integrators.FOLD_MIN_DOFS else "split"))


def initial_state(robot: gv.Robot) -> np.ndarray:
    """A bent, twisted rest-velocity state: N(0, 0.2^2) on every angular strain coefficient."""
    rng = np.random.default_rng(0)
    mask = []
    for link in robot.links:
        mask += [False] * link.joint.n_dofs
        for c, order in enumerate(link.basis.orders):
            mask += [c < 3] * (order + 1)
    return np.where(np.array(mask), 0.2 * rng.normal(size=len(mask)), 0.0)


def durations(batch: int, n_steps: int) -> jnp.ndarray:
    return n_steps * DT * (1.0 + 0.2 * jnp.linspace(0.0, 1.0, batch))


def planned_bytes(compiled) -> dict:
    mem = compiled.memory_analysis()
    if mem is None:
        return {}
    return dict(xla_planned_bytes=int(mem.argument_size_in_bytes + mem.output_size_in_bytes
                                      + mem.temp_size_in_bytes - mem.alias_size_in_bytes),
                xla_temp_bytes=int(mem.temp_size_in_bytes))


def measure(config: str, recursion: str, batches, n_steps: int, repeats: int, out: str) -> None:
    """One (configuration, recursion) in this process; ``out`` is rewritten after each batch."""
    robot = build(config, recursion)
    if recursion.endswith(SCALAR):
        linalg.STACKED_MIN_DOFS = 10**9
    q0 = jnp.asarray(initial_state(robot))
    row = dict(describe(config), recursion=recursion, uses_scan=scan.uses_scan(robot.links[-1], robot.n_dofs),
               n_steps=n_steps, dt=DT, repeats=repeats, load_start=load_average(), batches=[])

    def run(T):
        return gv.simulate(robot, T, q0=q0, n_steps=n_steps, save_every=n_steps, integrator="ars443",
                           check_stability=False).tip[-1]

    fn = jax.jit(jax.vmap(run))
    for batch in batches:
        T = durations(batch, n_steps)
        t0 = time.perf_counter()
        lowered = fn.lower(T)
        t1 = time.perf_counter()
        compiled = lowered.compile()
        t2 = time.perf_counter()
        tips = np.asarray(jax.block_until_ready(compiled(T)))  # the first call (warm-up)
        runs = []
        for _ in range(repeats):
            t3 = time.perf_counter()
            jax.block_until_ready(compiled(T))
            runs.append(time.perf_counter() - t3)
        run_s = float(np.median(runs))
        lanes = np.unique(np.linspace(0, batch - 1, min(batch, N_LANES)).round().astype(int))
        row["batches"].append(dict(
            batch=batch, lower_s=t1 - t0, xla_compile_s=t2 - t1, compile_s=t2 - t0,
            hlo_lines=lowered.as_text().count("\n"), run_s=run_s, runs_s=runs, step_s=run_s / n_steps,
            arm_steps_per_s=batch * n_steps / run_s, finite=bool(np.all(np.isfinite(tips))),
            tip_lanes=lanes.tolist(), tips=tips[lanes].tolist(), **planned_bytes(compiled)))
        row["peak_rss_bytes"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # so far
        row["batches"][-1]["peak_rss_bytes_so_far"] = row["peak_rss_bytes"]
        row["load_end"] = load_average()
        _write(out, row)
        print(f"  {config} {recursion} batch {batch}: compile {t2 - t0:.1f} s (lower {t1 - t0:.1f}), "
              f"step {run_s / n_steps * 1e3:.3g} ms, planned "
              f"{row['batches'][-1].get('xla_planned_bytes', 0) / 2**20:.1f} MiB", flush=True)


def _write(path: str, obj) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(obj, fh, indent=1)
    os.replace(tmp, path)


# ---------------------------------------------------------------------------------- the driver


def run_one(config, recursion, args) -> dict:
    """``measure`` in a child process under the time budget; the row it wrote (possibly partial)."""
    fd, out = tempfile.mkstemp(suffix=".json", prefix="bench_dofs_")
    os.close(fd)
    os.remove(out)
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", "--configs", config, "--recursions", recursion,
           "--batches", args.batches, "--steps", str(args.steps), "--repeats", str(args.repeats), "--worker-out", out]
    t0 = time.perf_counter()
    status, reason = "ok", None
    try:
        proc = subprocess.run(cmd, timeout=args.budget)
        if proc.returncode:
            status, reason = "error", f"worker exited with code {proc.returncode}"
    except subprocess.TimeoutExpired:  # subprocess.run has killed the child (its pid only)
        status, reason = "timeout", f"over the budget of {args.budget:.0f} s (--budget) for both batches"
    row = dict(describe(config), recursion=recursion, batches=[])
    if os.path.exists(out):
        with open(out) as fh:
            row = json.load(fh)
        os.remove(out)
    row.update(status=status, wall_s=time.perf_counter() - t0)
    if reason:
        row["reason"] = reason
    return row


def compare(rows) -> list[dict]:
    """Per configuration measured both ways: the tip difference and the scan / unrolled ratios."""
    by = {(r["config"], r["recursion"]): r for r in rows if r.get("batches")}
    out = []
    for config in dict.fromkeys(r["config"] for r in rows):
        a, b = by.get((config, "unrolled")), by.get((config, "scan"))
        if not (a and b):
            continue
        res = dict(config=config, dofs=a["dofs"])
        diffs = []
        for ba in a["batches"]:
            bb = next((x for x in b["batches"] if x["batch"] == ba["batch"]), None)
            if bb is None:
                continue
            diffs.append(float(np.max(np.abs(np.array(ba["tips"]) - np.array(bb["tips"])))))
            res[f"step_scan_over_unrolled_b{ba['batch']}"] = bb["step_s"] / ba["step_s"]
            res[f"compile_scan_over_unrolled_b{ba['batch']}"] = bb["compile_s"] / ba["compile_s"]
        if diffs:
            res["tip_max_abs_diff_m"] = max(diffs)
            out.append(res)
    return out


def series(rows, key):
    """{(family, recursion, batch): (dofs, values)} of the measured rows, sorted by DoFs."""
    out: dict = {}
    for r in rows:
        for b in r.get("batches", []):
            out.setdefault((r["family"], r["recursion"], b["batch"]), []).append((r["dofs"], key(b, r)))
    return {k: tuple(map(np.array, zip(*sorted(v)))) for k, v in out.items()}


def fits(rows) -> list[dict]:
    """Least-squares exponents p of step time ~ n^p and compile time ~ n^p (n = DoFs)."""
    out = []
    step, comp = series(rows, lambda b, r: b["step_s"]), series(rows, lambda b, r: b["compile_s"])
    for key, (n, t) in sorted(step.items()):
        if len(set(n.tolist())) < 2:
            continue
        family, recursion, batch = key
        nc, c = comp[key]
        out.append(dict(family=family, recursion=recursion, batch=int(batch), dofs=n.tolist(),
                        step_exponent=float(np.polyfit(np.log(n), np.log(t), 1)[0]),
                        compile_exponent=float(np.polyfit(np.log(nc), np.log(c), 1)[0]),
                        points=len(n)))
    return out


def plot(res, path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import ticker

    rows = [r for r in res["rows"] if r.get("batches")]
    if not rows:
        return
    panels = [("compile time (s): trace + lower + XLA", lambda b, r: b["compile_s"], None),
              ("memory (MiB): XLA planned, and the process's peak RSS", lambda b, r: b.get("xla_planned_bytes",
                                                                                          np.nan) / 2**20, None),
              ("step time, batch 1 (ms per step)", lambda b, r: b["step_s"] * 1e3, 1),
              ("step time, batch 1024 (ms per step)", lambda b, r: b["step_s"] * 1e3, 1024)]
    colour = {"unrolled": "C0", "scan": "C1", "scan-scalar": "C2", "unrolled-scalar": "C3"}
    marker = {"rod": "o", "chain": "s"}
    fig, axs = plt.subplots(2, 2, figsize=(10, 7.5))
    for ax, (title, key, only) in zip(axs.flat, panels):
        curves = {k: v for k, v in series(rows, key).items() if only is None or k[2] == only}
        for (family, recursion, batch), (n, y) in sorted(curves.items()):
            ls = "-" if only is not None or batch != 1 else "--"
            label = f"{family}, {recursion}" + ("" if only is not None else f", batch {batch}")
            ax.loglog(n, y, marker=marker[family], ls=ls, color=colour.get(recursion, "k"), label=label,
                      mfc="none" if batch == 1 and only is None else None)
        allx = np.concatenate([n for n, _ in curves.values()]) if curves else np.array([])
        ally = np.concatenate([y for _, y in curves.values()]) if curves else np.array([])
        good = np.isfinite(ally) & (ally > 0)
        if good.any():
            n0, n1 = allx.min(), max(allx.max(), 2 * allx.min())
            y0 = float(np.exp(np.mean(np.log(ally[good & (allx == allx.min())]))))
            xs = np.geomspace(n0, n1, 20)
            ax.loglog(xs, y0 * (xs / n0) ** 2, ":", color="gray", label="$\\propto n^2$")
        if title.startswith("memory"):  # compilation's footprint: one value per process (both batches)
            for family, recursion in dict.fromkeys((r["family"], r["recursion"]) for r in rows):
                pts = sorted((r["dofs"], r["peak_rss_bytes"] / 2**20) for r in rows
                             if (r["family"], r["recursion"]) == (family, recursion) and "peak_rss_bytes" in r)
                if pts:
                    ax.loglog(*zip(*pts), marker="x" if family == "rod" else "+", ls="-.",
                              color=colour.get(recursion, "k"), label=f"{family}, {recursion}, peak RSS")
        if title.startswith("compile"):  # issue 20's targets
            ax.loglog([6, 24], [15, 30], "k*", ms=9, ls="none", zorder=6, label="target (15 s at 6, 30 s at 24 DoFs)")
        ax.set_xlabel("DoFs n")
        ax.set_title(title, fontsize=10)
        ax.set_xlim(5, 42)
        ax.set_xticks([6, 12, 18, 24, 30, 36])
        ax.xaxis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_locator(ticker.NullLocator())
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, hi * (hi / lo) ** 0.7)  # headroom: the legend sits above the curves
        ax.yaxis.set_major_locator(ticker.LogLocator(base=10, subs=(1.0,) if hi / lo > 1e3 else (1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_locator(ticker.NullLocator())
        ax.grid(True, which="major", alpha=0.3)
        if curves:
            ax.legend(fontsize=6.5, framealpha=0.5, loc="upper left", ncol=2)  # the targets (zorder 6) show through
    quick = " (--quick)" if res.get("quick") else ""
    fig.suptitle(f"Spatial rods, ars443, {res.get('n_steps')} steps of {DT * 1e3:g} ms{quick}; "
                 f"load {res.get('load_start', '').split('load average:')[-1].strip()}", fontsize=9)
    fig.tight_layout()
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def print_tables(res) -> None:
    print(f"\nload at start: {res.get('load_start')}\nload at end:   {res.get('load_end')}")
    print("\n| config | DoFs | Gauss pts | recursion | batch | compile s (lower + XLA) | step ms | "
          "arm-steps/s | XLA planned MiB | peak RSS MiB (so far) | StableHLO lines | status |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in res["rows"]:
        if not r.get("batches"):
            print(f"| {r['config']} | {r['dofs']} | {r['n_gauss_total']} | {r['recursion']} | "
                  f"{'- | ' * 7}{r.get('status')}: {r.get('reason', '')} |")
        for b in r.get("batches", []):
            print(f"| {r['config']} | {r['dofs']} | {r['n_gauss_total']} | {r['recursion']} | {b['batch']} | "
                  f"{b['compile_s']:.1f} ({b['lower_s']:.1f} + {b['xla_compile_s']:.1f}) | {b['step_s'] * 1e3:.3g} | "
                  f"{b['arm_steps_per_s']:,.0f} | {b.get('xla_planned_bytes', 0) / 2**20:.2f} | "
                  f"{b.get('peak_rss_bytes_so_far', r.get('peak_rss_bytes', 0)) / 2**20:,.0f} | {b['hlo_lines']:,} | "
                  f"{r.get('status')} |")
    print("\n| config | DoFs | max tip difference (m) | step scan / unrolled, batch 1 / 1024 | "
          "compile scan / unrolled, batch 1 / 1024 |")
    print("|---|---|---|---|---|")
    for c in res["compare"]:
        print(f"| {c['config']} | {c['dofs']} | {c['tip_max_abs_diff_m']:.1e} | "
              f"{c.get('step_scan_over_unrolled_b1', math.nan):.2f} / "
              f"{c.get('step_scan_over_unrolled_b1024', math.nan):.2f} | "
              f"{c.get('compile_scan_over_unrolled_b1', math.nan):.2f} / "
              f"{c.get('compile_scan_over_unrolled_b1024', math.nan):.2f} |")
    print("\n| family | recursion | batch | DoFs | step time ~ n^p | compile time ~ n^p |")
    print("|---|---|---|---|---|---|")
    for f in res["fits"]:
        print(f"| {f['family']} | {f['recursion']} | {f['batch']} | {','.join(map(str, f['dofs']))} | "
              f"{f['step_exponent']:.2f} | {f['compile_exponent']:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help=f"only {','.join(QUICK)}")
    ap.add_argument("--configs", default=None, help=f"comma-separated, of {','.join(CONFIGS)}")
    ap.add_argument("--recursions", default=",".join(RECURSIONS))
    ap.add_argument("--batches", default="1,1024")
    ap.add_argument("--steps", type=int, default=100, help="integrator steps per call (N)")
    ap.add_argument("--repeats", type=int, default=5, help="timed calls per batch (median)")
    ap.add_argument("--budget", type=float, default=1800.0, help="s per configuration and recursion (both batches)")
    ap.add_argument("--unrolled-max-dofs", type=int, default=24, help="skip the unrolled recursion beyond this")
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "scaling_dofs.json"))
    ap.add_argument("--figure", default=os.path.join(FIG, "bench_dofs.png"))
    ap.add_argument("--merge", action="store_true", help="keep the rows of --json not measured again")
    ap.add_argument("--replot", action="store_true", help="only plot and print --json")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--worker-out", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    configs = QUICK if args.quick else tuple(c.strip() for c in (args.configs or ",".join(CONFIGS)).split(","))
    recursions = tuple(r.strip() for r in args.recursions.split(","))
    batches = [int(b) for b in args.batches.split(",")]
    for c in configs:
        describe(c)  # unknown names fail here
    if args.worker:
        measure(configs[0], recursions[0], batches, args.steps, args.repeats, args.worker_out)
        return
    if args.replot:
        with open(args.json) as fh:
            res = json.load(fh)
        plot(res, args.figure)
        print_tables(res)
        return

    configs = sorted(configs, key=lambda c: (not c.startswith("rod"), describe(c)["dofs"]))
    old = []
    if args.merge and os.path.exists(args.json):
        with open(args.json) as fh:
            old = json.load(fh)["rows"]
    res = dict(quick=args.quick, n_steps=args.steps, dt=DT, repeats=args.repeats, batches=batches,
               budget_s=args.budget, unrolled_max_dofs=args.unrolled_max_dofs, integrator="ars443",
               cpu_count=os.cpu_count(), jax=jax.__version__, load_start=load_average(), rows=[])
    print("load at start:", res["load_start"], flush=True)
    over: set = set()  # (family, recursion) that went over budget
    for config in configs:
        info = describe(config)
        for recursion in recursions:
            if recursion == "unrolled" and info["dofs"] > args.unrolled_max_dofs:
                row = dict(info, recursion=recursion, batches=[], status="skipped",
                           reason=f"{info['dofs']} DoFs > --unrolled-max-dofs {args.unrolled_max_dofs}")
            elif (info["family"], recursion) in over:
                row = dict(info, recursion=recursion, batches=[], status="skipped",
                           reason=f"a smaller {info['family']} with the {recursion} recursion went over the budget")
            else:
                print(f"{config} ({info['dofs']} DoFs), {recursion}:", flush=True)
                row = run_one(config, recursion, args)
                if row["status"] == "timeout":
                    over.add((info["family"], recursion))
                if row["status"] != "ok":
                    print(f"  {row['status']}: {row['reason']}", flush=True)
            res["rows"].append(row)
            done = {(r["config"], r["recursion"]) for r in res["rows"]}
            rows = [r for r in old if (r["config"], r["recursion"]) not in done] + res["rows"]
            out = dict(res, rows=rows, load_end=load_average(), compare=compare(rows), fits=fits(rows))
            _write(args.json, out)  # after every configuration: a stopped run keeps what it measured
    plot(out, args.figure)
    print_tables(out)


if __name__ == "__main__":
    main()
