"""What reverse-mode derivatives cost against the forward pass: compile time, memory and run time.

Each case runs in a fresh process, once forward and once with ``jax.value_and_grad``:

- ``step:TASK``: one control step of a task at batch ``--batch`` in its training precision (float32),
  from ``reset`` states (keys 0..batch-1) and actions drawn uniform in [-0.5, 0.5] (seed 0); the value is
  the batch's summed reward, differentiated with respect to the actions;
- ``window:TASK``: ``--horizon`` control steps (a ``lax.scan`` of ``env.step``) with an MLP policy
  (two hidden layers of 64, tanh) choosing the actions from the observations; the value is the summed
  reward, differentiated with respect to the policy's parameters (one update of a learner through the
  simulator, without the optimiser);
- ``sim:ROBOT``: ``simulate`` of ``gv.rod_3d(order=0)`` (6 DoFs), ``gv.tendon_arm()`` or
  ``gv.paper_arm()`` over 0.2 s in 20 ars443 steps at batch ``--batch``, float32, from perturbed initial
  strains; the value is the summed tip position, differentiated with respect to q0 and qd0.

Reported: XLA compile time (CPU seconds of the process, which a busy machine inflates less than wall
time), the lowered program's size (lines of StableHLO), the process's peak resident memory, and the
median over ``--repeats`` calls (wall time). The values of the two passes must agree.

    python experiments/benchmarks/bench_gradient.py                  # every case
    python experiments/benchmarks/bench_gradient.py --cases step:follow_target sim:rod6
    python experiments/benchmarks/bench_gradient.py --report
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
JSON_PATH = os.path.join(ROOT, "benchmarks", "gradient.json")
CASES = ("step:follow_target", "step:ik_4d", "step:obstacles_3d", "window:follow_target", "sim:rod6",
         "sim:tendon_arm", "sim:paper_arm")


def _case(name: str, batch: int, horizon: int):
    """(function of one argument, that argument) for a case."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    import gvsjax as gv
    from gvsjax.tasks import make

    kind, what = name.split(":")
    rng = np.random.default_rng(0)
    if kind == "sim":
        robot = {"rod6": lambda: gv.rod_3d(order=0), "tendon_arm": gv.tendon_arm, "paper_arm": gv.paper_arm}[what]()
        n = robot.n_dofs
        x0 = jnp.asarray(0.1 * rng.normal(size=(batch, 2, n)), jnp.float32)

        def sim(x):
            one = lambda x: jnp.sum(gv.simulate(robot, 0.2, n_steps=20, q0=x[0], qd0=x[1], integrator="ars443",
                                                save_every=20, check_stability=False, dtype="float32").tip[-1])
            return jnp.sum(jax.vmap(one)(x))

        return sim, x0
    env = make(what)
    params = env.with_sim_dtype(env.default_params(), "float32")
    keys = jax.random.split(jax.random.PRNGKey(0), batch)
    _, states = jax.vmap(lambda k: env.reset(k, params))(keys)
    if kind == "step":
        actions = jnp.asarray(rng.uniform(-0.5, 0.5, (batch, env.action_size)), jnp.float32)
        return (lambda a: jnp.sum(jax.vmap(lambda k, s, a: env.step(k, s, a, params)[2])(keys, states, a)),
                actions)
    obs0 = jax.vmap(lambda s: env.observe(s, params))(states)
    sizes = (obs0.shape[-1], 64, 64, env.action_size)
    weights = [(jnp.asarray(rng.normal(size=(a, b)) / np.sqrt(a), jnp.float32), jnp.zeros(b, jnp.float32))
               for a, b in zip(sizes[:-1], sizes[1:])]

    def policy(w, obs):
        for W, b in w:
            obs = obs @ W + b
            obs = jnp.tanh(obs)  # the last layer too: actions in [-1, 1]
        return obs

    def window(w):
        def one(carry, k):
            obs, s = carry
            obs, s, r, _, _ = jax.vmap(lambda kk, s, o: env.step(kk, s, policy(w, o), params))(
                jax.random.split(k, batch), s, obs)
            return (obs, s), jnp.sum(r)
        _, r = jax.lax.scan(one, (obs0, states), jax.random.split(jax.random.PRNGKey(1), horizon))
        return jnp.sum(r)

    return window, weights


def worker(name: str, mode: str, batch: int, horizon: int, repeats: int) -> dict:
    import gvsjax  # noqa: F401, I001  (first: it configures JAX)
    import jax
    import numpy as np

    f, x = _case(name, batch, horizon)
    fn = jax.jit(jax.value_and_grad(f) if mode == "reverse" else f)
    t0 = time.process_time()
    lowered = fn.lower(x)
    t1 = time.process_time()
    compiled = lowered.compile()
    t2 = time.process_time()
    out = jax.block_until_ready(compiled(x))
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(compiled(x))
        times.append(time.perf_counter() - t)
    value = out[0] if mode == "reverse" else out
    grad_norm = float(np.sqrt(sum(np.sum(np.square(g)) for g in jax.tree.leaves(out[1])))) if mode == "reverse" \
        else None
    return {"lower_cpu_s": t1 - t0, "compile_cpu_s": t2 - t1, "hlo_lines": lowered.as_text().count("\n"),
            "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6,
            "run_ms_median": 1e3 * float(np.median(times)), "value": float(value), "grad_norm": grad_norm}


def report(path: str = JSON_PATH) -> str:
    d = json.loads(open(path).read())
    load = (f"load before / after: {d['load_before'][0]:.1f} / {d['load_after'][0]:.1f}" if d["load_before"]
            else "load not recorded")
    lines = [f"batch {d['batch']}, window of {d['horizon']} control steps, float32 ({load})", "",
             "| case | compile CPU s, forward / reverse | ratio | run ms, forward / reverse | ratio | "
             "peak GB (reverse) | StableHLO lines, forward / reverse |",
             "|---|---|---|---|---|---|---|"]
    for case in dict.fromkeys(r["case"] for r in d["rows"]):
        f, r = (next(x for x in d["rows"] if x["case"] == case and x["mode"] == m) for m in ("forward", "reverse"))
        if "timeout_s" in f or "timeout_s" in r:
            slow = "forward" if "timeout_s" in f else "reverse"
            lines.append(f"| {case} | {slow} not compiled within {d['timeout_s']:.0f} s | | | | | |")
            continue
        lines.append(f"| {case} | {f['compile_cpu_s']:.0f} / {r['compile_cpu_s']:.0f} | "
                     f"{r['compile_cpu_s'] / f['compile_cpu_s']:.1f}x | {f['run_ms_median']:.1f} / "
                     f"{r['run_ms_median']:.1f} | {r['run_ms_median'] / f['run_ms_median']:.1f}x | "
                     f"{r['peak_rss_gb']:.1f} | {f['hlo_lines']:,} / {r['hlo_lines']:,} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--horizon", type=int, default=32)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per process")
    ap.add_argument("--json", default=JSON_PATH)
    ap.add_argument("--report", action="store_true", help="print the table of --json")
    ap.add_argument("--worker", nargs=2, metavar=("CASE", "MODE"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.report:
        print(report(args.json))
        return
    if args.worker:
        print(json.dumps(worker(*args.worker, args.batch, args.horizon, args.repeats)))
        return
    rows, load_before = [], os.getloadavg()
    for case in args.cases:
        for mode in ("forward", "reverse"):
            cmd = [sys.executable, __file__, "--batch", str(args.batch), "--horizon", str(args.horizon),
                   "--repeats", str(args.repeats), "--worker", case, mode]
            try:
                out = subprocess.run(cmd, capture_output=True, text=True, check=True, timeout=args.timeout).stdout
                row = {"case": case, "mode": mode, **json.loads(out.strip().splitlines()[-1])}
            except subprocess.TimeoutExpired:  # recorded: a pass that does not compile in time is a result
                row = {"case": case, "mode": mode, "timeout_s": args.timeout}
            print(row, flush=True)
            rows.append(row)
        f, r = rows[-2].get("value"), rows[-1].get("value")
        if f is not None and r is not None and abs(f - r) > 1e-4 * max(1.0, abs(f)):
            raise SystemExit(f"{case}: the passes disagree on the value: {f} and {r}")
    record = {"command": "python experiments/benchmarks/bench_gradient.py " + " ".join(sys.argv[1:]),
              "batch": args.batch, "horizon": args.horizon, "repeats": args.repeats, "timeout_s": args.timeout,
              "load_before": load_before, "load_after": os.getloadavg(), "rows": rows}
    tmp = args.json + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(record, fh, indent=2)
    os.replace(tmp, args.json)
    print(report(args.json))


if __name__ == "__main__":
    main()
