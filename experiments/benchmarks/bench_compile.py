"""Compile time of spatial rods against Gauss points and DoFs, and their step time, for two source trees.

Models (1 m clamped spatial rods, r = 5 cm, E = 5 MPa, 1000 kg/m^3, eta = 1e5 Pa s, gravity 9.81
m/s^2 along -y, all six strains active, Legendre basis; ``n_gauss`` Gauss points per link):

- ``rod<k>``: one soft link, every strain of order k, 6 (k + 1) DoFs (``gv.rod_3d(order=k)``);
  rod0 is the SoRoMoX comparison's one-segment rod (``experiments/benchmarks/bench_soromox.py``, b1);
- ``chain<k>``: k soft links of length 1/k, every strain of order 0, on fixed joints, 6 k DoFs
  (the SoRoMoX comparison's b2 and b4 at 5 Gauss points).

Each (model, n_gauss) is measured once per source tree (``--trees NAME=PATH,...``: each worker
imports ``gvsjax`` from PATH, so the code before and after a change run side by side in one
session, interleaved, each in a fresh process), with every soft link's recursion left at "auto"
(``--recursion`` forces one). Measured for a jitted, vmapped
``gv.simulate(robot, T, q0=q0, n_steps=N, save_every=N, integrator="ars443", check_stability=False)``
from a bent state at rest (angular strains ~ N(0, 0.2^2), seed 0), float64:

- compile time at batch 1: ``jit(vmap(run)).lower(T)`` (tracing and lowering) plus ``.compile()``
  (XLA), as the first call pays it;
- step time: the median of ``--repeats`` calls of the compiled program divided by N, at batch 1 and,
  for the Gauss points of ``--big-gauss``, at batch ``--big-batch`` (another compile, not reported);
- the lowered program's size (lines of StableHLO) and the tip after N steps (the trees must agree).

``os.getloadavg()`` is recorded before and after every worker: on a shared machine the times are
upper bounds, and the before / after ratios of one session are the comparable numbers.

    python experiments/benchmarks/bench_compile.py --trees before=/path/to/old/checkout,after=.
    python experiments/benchmarks/bench_compile.py --models rod0 --gauss 5 --trees after=.   # one point
    python experiments/benchmarks/bench_compile.py --report                                  # the table from the JSON
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
JSON_PATH = os.path.join(ROOT, "benchmarks", "compile_time.json")
MODELS = ("rod0", "rod1", "rod3", "chain2", "chain4")
DT = 1e-3  # s


def build(gv, model: str, n_gauss: int, recursion: str):
    """The robot of ``model`` with ``n_gauss`` Gauss points per link and every soft link's ``recursion``."""
    if model.startswith("rod"):
        robot = gv.rod_3d(order=int(model[3:]), n_gauss=n_gauss, gravity=9.81)
    else:
        k = int(model[5:])
        link = gv.rod_3d(length=1.0 / k, order=0, n_gauss=n_gauss).links[0]
        robot = gv.Robot(links=(link,) * k, gravity=9.81)
    return robot.replace(links=tuple(link.replace(recursion=recursion) for link in robot.links))


def dofs(model: str) -> int:
    return 6 * (int(model[3:]) + 1) if model.startswith("rod") else 6 * int(model[5:])


def min_gauss(model: str) -> int:
    """The fewest Gauss points the basis allows (highest order + 1)."""
    return int(model[3:]) + 1 if model.startswith("rod") else 1


def initial_state(robot) -> np.ndarray:
    """N(0, 0.2^2) on every angular strain coefficient, 0 elsewhere (seed 0)."""
    rng = np.random.default_rng(0)
    mask: list[bool] = []
    for link in robot.links:
        mask += [False] * link.joint.n_dofs
        for c, order in enumerate(link.basis.orders):
            mask += [c < 3] * (order + 1)
    return np.where(np.array(mask), 0.2 * rng.normal(size=len(mask)), 0.0)


def worker(args) -> dict:
    """One (model, n_gauss) in this process, with the ``gvsjax`` on ``sys.path``."""
    import jax
    import jax.numpy as jnp

    import gvsjax as gv  # configures JAX before any computation
    from gvsjax.core import scan

    robot = build(gv, args.models, int(args.gauss), args.recursion)
    q0 = jnp.asarray(initial_state(robot))
    n = args.steps

    def run(T):
        return gv.simulate(robot, T, q0=q0, n_steps=n, save_every=n, integrator="ars443",
                           check_stability=False).tip[-1]

    out = dict(gvsjax=os.path.dirname(gv.__file__), uses_scan=[scan.uses_scan(link, robot.n_dofs)
                                                               for link in robot.links])
    for batch in (1, args.big_batch) if args.big else (1,):
        fn = jax.jit(jax.vmap(run))
        T = n * DT * (1.0 + 0.2 * jnp.linspace(0.0, 1.0, batch))
        t0 = time.perf_counter()
        lowered = fn.lower(T)
        t1 = time.perf_counter()
        compiled = lowered.compile()
        t2 = time.perf_counter()
        tip = np.asarray(jax.block_until_ready(compiled(T)))
        runs = []
        for _ in range(args.repeats):
            t3 = time.perf_counter()
            jax.block_until_ready(compiled(T))
            runs.append(time.perf_counter() - t3)
        key = "b1" if batch == 1 else "big"
        out[key] = dict(batch=batch, lower_s=t1 - t0, xla_compile_s=t2 - t1, compile_s=t2 - t0,
                        hlo_lines=lowered.as_text().count("\n"), runs_s=runs,
                        step_s=float(np.median(runs)) / n, tip=tip[0].tolist(), finite=bool(np.isfinite(tip).all()))
    return out


def run_worker(model: str, n_gauss: int, tree: str, path: str, big: bool, args) -> dict:
    """``worker`` in a child process importing gvsjax from ``path``, under ``--budget`` s."""
    env = dict(os.environ, PYTHONPATH=os.path.abspath(path))
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", "--models", model, "--gauss", str(n_gauss),
           "--recursion", args.recursion, "--steps", str(args.steps), "--repeats", str(args.repeats),
           "--big-batch", str(args.big_batch)] + (["--big"] if big else [])
    row = dict(model=model, dofs=dofs(model), n_gauss=n_gauss, tree=tree, recursion=args.recursion,
               load_before=os.getloadavg())
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=args.budget, cwd="/")
        if proc.returncode:
            row.update(status="error", reason=proc.stderr.strip().splitlines()[-1:])
        else:
            row.update(status="ok", **json.loads(proc.stdout.strip().splitlines()[-1]))
    except subprocess.TimeoutExpired:
        row.update(status="timeout", reason=f"over --budget {args.budget:.0f} s")
    row.update(wall_s=time.perf_counter() - t0, load_after=os.getloadavg())
    return row


def ratios(rows: list[dict], base: str, new: str) -> list[dict]:
    """new / base compile and step times per (model, n_gauss) measured on both trees."""
    by = {(r["model"], r["n_gauss"], r["tree"]): r for r in rows if r.get("status") == "ok"}
    out = []
    for (model, g, tree), r in by.items():
        b = by.get((model, g, base))
        if tree != new or b is None:
            continue
        res = dict(model=model, n_gauss=g, compile=r["b1"]["compile_s"] / b["b1"]["compile_s"],
                   step_b1=r["b1"]["step_s"] / b["b1"]["step_s"],
                   tip_diff_m=float(np.max(np.abs(np.subtract(r["b1"]["tip"], b["b1"]["tip"])))))
        if "big" in r and "big" in b:
            res["step_big"] = r["big"]["step_s"] / b["big"]["step_s"]
        out.append(res)
    return out


def report(data: dict) -> None:
    trees = list(data["trees"])
    print(f"load: {data.get('load_start')} -> {data.get('load_end')}")
    print("| model | DoFs | Gauss pts | " + " | ".join(f"{t}: compile s, step ms b1 / b{data['big_batch']}"
                                                  for t in trees) + " |")
    print("|---|---|---|" + "---|" * len(trees))
    by = {(r["model"], r["n_gauss"], r["tree"]): r for r in data["rows"]}
    for model, g in dict.fromkeys((r["model"], r["n_gauss"]) for r in data["rows"]):
        cells = []
        for t in trees:
            r = by.get((model, g, t))
            if r is None or r.get("status") != "ok":
                cells.append("-" if r is None else r["status"])
                continue
            big = f" / {r['big']['step_s'] * 1e3:.3g}" if "big" in r else ""
            cells.append(f"{r['b1']['compile_s']:.1f}, {r['b1']['step_s'] * 1e3:.3g}{big}")
        print(f"| {model} | {dofs(model)} | {g} | " + " | ".join(cells) + " |")
    for c in data.get("ratios", []):
        print(c)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--gauss", default="2,3,4,5,6,7,8", help="Gauss points per link")
    ap.add_argument("--trees", default=f"after={ROOT}", help="NAME=PATH,...: where each worker imports gvsjax")
    ap.add_argument("--recursion", default="auto", help="every soft link's SoftLink.recursion")
    ap.add_argument("--steps", type=int, default=100, help="integrator steps per call (N)")
    ap.add_argument("--repeats", type=int, default=5, help="timed calls per batch (median)")
    ap.add_argument("--big-batch", type=int, default=1024)
    ap.add_argument("--big-gauss", default="2,5,8", help="Gauss points also timed at --big-batch")
    ap.add_argument("--budget", type=float, default=900.0, help="s per worker")
    ap.add_argument("--notes", default="", help="what the trees are (kept in the JSON)")
    ap.add_argument("--json", default=JSON_PATH)
    ap.add_argument("--merge", action="store_true", help="keep the JSON's rows not measured again")
    ap.add_argument("--report", action="store_true", help="only print the table of --json")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--big", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(args)))
        return
    if args.report:
        with open(args.json) as fh:
            report(json.load(fh))
        return
    trees = dict(t.split("=", 1) for t in args.trees.split(","))
    models = [m.strip() for m in args.models.split(",")]
    gauss = [int(g) for g in args.gauss.split(",")]
    big = {int(g) for g in args.big_gauss.split(",") if g}
    old, commands = [], []
    if args.merge and os.path.exists(args.json):
        with open(args.json) as fh:
            previous = json.load(fh)
        old, commands = previous["rows"], previous.get("commands", [previous.get("command")])
    command = shlex.join(["python", "experiments/benchmarks/bench_compile.py", *sys.argv[1:]])
    data = dict(integrator="ars443", dtype="float64", n_steps=args.steps, dt=DT, repeats=args.repeats,
                big_batch=args.big_batch, trees={k: os.path.abspath(v) for k, v in trees.items()},
                cpu_count=os.cpu_count(), notes=args.notes, load_start=os.getloadavg(), rows=[],
                commands=[c for c in commands if c] + [command])
    for model in models:
        for g in gauss:
            if g < min_gauss(model):
                continue
            for tree, path in trees.items():
                row = run_worker(model, g, tree, path, g in big, args)
                b1 = row.get("b1", {})
                print(f"{model} n_gauss={g} {tree}: {row['status']} compile {b1.get('compile_s', float('nan')):.1f} s"
                      f" step {b1.get('step_s', float('nan')) * 1e3:.3g} ms, load {row['load_before'][0]:.2f}",
                      flush=True)
                data["rows"].append(row)
                done = {(r["model"], r["n_gauss"], r["tree"]) for r in data["rows"]}
                rows = [r for r in old if (r["model"], r["n_gauss"], r["tree"]) not in done] + data["rows"]
                names = list(trees)
                out = dict(data, rows=rows, load_end=os.getloadavg(),
                           ratios=ratios(rows, names[0], names[-1]) if len(names) > 1 else [])
                tmp = args.json + ".tmp"
                with open(tmp, "w") as fh:
                    json.dump(out, fh, indent=1)
                os.replace(tmp, args.json)  # after every worker: a stopped run keeps what it measured
    report(out)


if __name__ == "__main__":
    main()
