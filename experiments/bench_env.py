"""Environment steps per second of any registered task at a batch size (random actions).

The batch runs ``jit(vmap(step))`` with auto-reset (as PPO's rollout does) for
``--steps`` steps inside one ``lax.scan``; the time is the median of
``--repeats`` calls after a compiling one. Results merge into a JSON file,
one entry per task and batch.

    python experiments/bench_env.py --task reach_pose --batch 1024
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import jax

import gvsjax as gv  # noqa: F401  (XLA flags first)
from gvsjax.tasks import auto_reset_step, make

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--task", required=True)
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--steps", type=int, default=20, help="env steps per timed call")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "env_throughput.json"))
    args = ap.parse_args()
    env = make(args.task)
    params = env.train_params()
    step = jax.vmap(auto_reset_step(env), in_axes=(0, 0, 0, None))

    @jax.jit
    def run(key, state):
        def body(state, k):
            k_act, k_step = jax.random.split(k)
            action = jax.random.uniform(k_act, (args.batch, env.action_size), minval=-1.0, maxval=1.0)
            _, state, reward, _, _ = step(jax.random.split(k_step, args.batch), state, action, params)
            return state, reward.sum()

        return jax.lax.scan(body, state, jax.random.split(key, args.steps))

    _, state = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(jax.random.split(jax.random.PRNGKey(0), args.batch),
                                                                params)
    t0 = time.perf_counter()
    state, _ = jax.block_until_ready(run(jax.random.PRNGKey(1), state))
    compile_s = time.perf_counter() - t0
    times = []
    for i in range(args.repeats):
        t0 = time.perf_counter()
        state, _ = jax.block_until_ready(run(jax.random.PRNGKey(2 + i), state))
        times.append(time.perf_counter() - t0)
    rate = args.batch * args.steps / statistics.median(times)
    row = {"task": args.task, "batch": args.batch, "env_steps_per_s": rate, "first_call_s": compile_s,
           "times_s": times, "cpus": os.cpu_count(), "machine": platform.machine(), "jax": jax.__version__,
           "load_average_1min": os.getloadavg()[0]}
    print(json.dumps(row))
    path = Path(args.json)
    rows = [r for r in (json.loads(path.read_text()) if path.exists() else [])
            if (r["task"], r["batch"]) != (args.task, args.batch)]
    path.write_text(json.dumps(sorted(rows + [row], key=lambda r: (r["task"], r["batch"])), indent=1) + "\n")


if __name__ == "__main__":
    main()
