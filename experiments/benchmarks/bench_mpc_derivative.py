"""The gradient planner's cost on a task: compile time, memory and run time of its plan's value
(``MPC.cost``, forward) and value and gradient (``jax.value_and_grad``, reverse mode), with the
dynamics' solves traced entry by entry or stacked (``gvsjax.core.linalg.stacked_solves``).

Each (layout, pass) runs in a fresh process: one episode state of ``--task`` from ``reset`` (key 0), a
plan of ``--horizon`` actions drawn uniform in [-0.3, 0.3] (seed 0), simulated in the task's
training precision. Reported: tracing and lowering time, XLA compile time, the process's peak
resident memory after compiling (it includes the forward programs' few hundred MB), the lowered
program's size (lines of StableHLO), and the median of ``--repeats`` blocked calls at batch
``--batch`` (``vmap`` over copies of the state). The loss values must agree between layouts.

    python experiments/benchmarks/bench_mpc_derivative.py --task follow_target --horizon 5
    python experiments/benchmarks/bench_mpc_derivative.py --report
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
JSON_PATH = os.path.join(ROOT, "benchmarks", "mpc_derivative.json")
LAYOUTS = {"entry by entry": 0, "stacked": 1}  # 0: the library's default threshold


def worker(task: str, horizon: int, batch: int, layout: int, mode: str, repeats: int) -> dict:
    import gvsjax  # noqa: F401, I001  (first: it configures JAX)
    import jax
    import jax.numpy as jnp
    import numpy as np

    from gvsjax.core import linalg
    from gvsjax.mpc import DERIVATIVE_STACKED_MIN_DOFS, MPC, MPCConfig
    from gvsjax.tasks import make

    env = make(task)
    mpc = MPC(env, env.default_params(), MPCConfig(horizon=horizon, iterations=1))
    obs, state = env.reset(jax.random.PRNGKey(0), mpc.model)
    plan = jnp.asarray(np.random.default_rng(0).uniform(-0.3, 0.3, (horizon, env.action_size)), obs.dtype)
    plans, states = jnp.broadcast_to(plan, (batch, *plan.shape)), jax.tree.map(
        lambda x: jnp.broadcast_to(x, (batch, *x.shape)), state)
    f = jax.value_and_grad(mpc.cost) if mode == "reverse" else mpc.cost
    fn = jax.jit(jax.vmap(f))
    # the stacked rows trace as the gradient planner does
    with linalg.stacked_solves(DERIVATIVE_STACKED_MIN_DOFS) if layout else contextlib.nullcontext():
        t0 = time.perf_counter()
        lowered = fn.lower(plans, states)
        t1 = time.perf_counter()
        compiled = lowered.compile()
        t2 = time.perf_counter()
    out = jax.block_until_ready(compiled(plans, states))
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(compiled(plans, states))
        times.append(time.perf_counter() - t)
    value = out[0] if mode == "reverse" else out
    return {"lower_s": t1 - t0, "compile_s": t2 - t1, "peak_rss_gb": resource.getrusage(
        resource.RUSAGE_SELF).ru_maxrss / 1e6, "hlo_lines": lowered.as_text().count("\n"),
        "run_ms_median": 1e3 * float(np.median(times)), "run_ms_all": [1e3 * t for t in times],
        "loss": float(value[0])}


def report(path: str = JSON_PATH) -> str:
    d = json.loads(open(path).read())
    lines = [f"{d['task']}, a plan of {d['horizon']} control steps, batch {d['batch']} "
             f"(load before / after: {d['load_before'][0]:.1f} / {d['load_after'][0]:.1f})", "",
             "| layout | pass | lower s | compile s | peak memory GB | StableHLO lines | run ms (median) |",
             "|---|---|---|---|---|---|---|"]
    for r in d["rows"]:
        lines.append(f"| {r['layout']} | {r['mode']} | {r['lower_s']:.0f} | {r['compile_s']:.0f} | "
                     f"{r['peak_rss_gb']:.1f} | {r['hlo_lines']:,} | {r['run_ms_median']:.1f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", default="follow_target")
    ap.add_argument("--horizon", type=int, default=5)
    ap.add_argument("--batch", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--layouts", nargs="+", default=list(LAYOUTS), choices=list(LAYOUTS))
    ap.add_argument("--json", default=JSON_PATH)
    ap.add_argument("--report", action="store_true", help="print the table of --json")
    ap.add_argument("--worker", nargs=2, metavar=("LAYOUT", "MODE"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.report:
        print(report(args.json))
        return
    if args.worker:
        layout, mode = args.worker
        print(json.dumps(worker(args.task, args.horizon, args.batch, int(layout), mode, args.repeats)))
        return
    rows, load_before = [], os.getloadavg()
    for name in args.layouts:
        for mode in ("forward", "reverse"):
            cmd = [sys.executable, __file__, "--task", args.task, "--horizon", str(args.horizon), "--batch",
                   str(args.batch), "--repeats", str(args.repeats), "--worker", str(LAYOUTS[name]), mode]
            out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
            row = {"layout": name, "mode": mode, **json.loads(out.strip().splitlines()[-1])}
            print(row, flush=True)
            rows.append(row)
    losses = [r["loss"] for r in rows]
    if max(losses) - min(losses) > 1e-4 * max(1.0, abs(losses[0])):
        raise SystemExit(f"the layouts disagree on the plan's cost: {losses}")
    record = {"command": "python experiments/benchmarks/bench_mpc_derivative.py " + " ".join(sys.argv[1:]),
              "task": args.task, "horizon": args.horizon, "batch": args.batch, "repeats": args.repeats,
              "load_before": load_before, "load_after": os.getloadavg(), "rows": rows}
    tmp = args.json + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(record, fh, indent=2)
    os.replace(tmp, args.json)
    print(report(args.json))


if __name__ == "__main__":
    main()
