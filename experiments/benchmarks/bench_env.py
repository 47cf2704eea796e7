"""Environment steps per second of registered tasks at a batch size (random actions).

The batch runs ``jit(vmap(step))`` with auto-reset (as PPO's rollout does) for
``--steps`` steps inside one ``lax.scan``, on the task's training params; the time is
the median of ``--repeats`` calls after a compiling one. Several tasks, or variants of
one (``TASK:name=value:name=value`` replaces fields of its training params, values as
``train_variant.py`` reads them), are
timed in turn in one process, call by call, so that their ratio does not depend on
the machine's drift. Plain tasks' results merge into a JSON file, one entry per task
and batch; variants are printed only.

    python experiments/benchmarks/bench_env.py --task reach_pose --batch 1024
    python experiments/benchmarks/bench_env.py --task reach_obstacles reach_obstacles:residual_scale=0 --batch 256
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import jax

sys.path.append(str(Path(__file__).resolve().parents[1] / "studies"))  # train_variant, in the studies folder
from train_variant import check_overrides, parse

import gvsjax as gv  # noqa: F401  (XLA flags first)
from gvsjax.tasks import auto_reset_step, make

ROOT = Path(__file__).resolve().parents[2]


def parse_case(spec: str) -> tuple[str, dict]:
    """``TASK`` or ``TASK:name=value:name=value`` -> (task, overrides)."""
    task, *items = spec.split(":")
    if not all("=" in item for item in items):
        raise SystemExit(f"--task {spec!r}: expected TASK:name=value:name=value")
    return task, {name: _value(value) for name, value in (item.split("=", 1) for item in items)}


def _value(text: str):
    """A number or tuple as ``train_variant`` reads it, else the string (e.g. ``targets=box``)."""
    try:
        return parse(text)
    except ValueError:
        return text


def prepare(spec: str, batch: int, steps: int):
    """The jitted timed call of one case, its params and a reset batch of states."""
    task, overrides = parse_case(spec)
    env = make(task)
    params = env.train_params()
    check_overrides(task, params, overrides)
    params = dataclasses.replace(params, **overrides)
    step = jax.vmap(auto_reset_step(env), in_axes=(0, 0, 0, None))

    @jax.jit
    def run(key, state, params):
        def body(state, k):
            k_act, k_step = jax.random.split(k)
            action = jax.random.uniform(k_act, (batch, env.action_size), minval=-1.0, maxval=1.0)
            _, state, reward, _, _ = step(jax.random.split(k_step, batch), state, action, params)
            return state, reward.sum()

        return jax.lax.scan(body, state, jax.random.split(key, steps))

    _, state = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(jax.random.split(jax.random.PRNGKey(0), batch), params)
    return run, params, state


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--task", required=True, nargs="+", help="TASK or TASK:name=value:... (several: timed in turn)")
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--steps", type=int, default=20, help="env steps per timed call")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "env_throughput.json"))
    args = ap.parse_args()
    cases = {spec: prepare(spec, args.batch, args.steps) for spec in args.task}
    states, first, times = {}, {}, {spec: [] for spec in cases}
    for spec, (run, params, state) in cases.items():
        t0 = time.perf_counter()
        states[spec], _ = jax.block_until_ready(run(jax.random.PRNGKey(1), state, params))
        first[spec] = time.perf_counter() - t0
    for i in range(args.repeats):
        for spec, (run, params, _) in cases.items():
            t0 = time.perf_counter()
            states[spec], _ = jax.block_until_ready(run(jax.random.PRNGKey(2 + i), states[spec], params))
            times[spec].append(time.perf_counter() - t0)
    rows = []
    for spec in cases:
        rate = args.batch * args.steps / statistics.median(times[spec])
        row = {"task": spec, "batch": args.batch, "env_steps_per_s": rate, "first_call_s": first[spec],
               "times_s": times[spec], "cpus": os.cpu_count(), "machine": platform.machine(),
               "jax": jax.__version__, "load_average_1min": os.getloadavg()[0]}
        print(json.dumps(row))
        rows.append(row)
    if len(cases) > 1:
        base = rows[0]["env_steps_per_s"]
        print("relative to the first:", ", ".join(f"{r['task']} {r['env_steps_per_s'] / base:.3f}" for r in rows))
    path = Path(args.json)
    plain = [r for r in rows if ":" not in r["task"]]
    if plain:
        keys = {(r["task"], r["batch"]) for r in plain}
        saved = json.loads(path.read_text()) if path.exists() else []
        kept = [r for r in saved if (r["task"], r["batch"]) not in keys]
        path.write_text(json.dumps(sorted(kept + plain, key=lambda r: (r["task"], r["batch"])), indent=1) + "\n")


if __name__ == "__main__":
    main()
