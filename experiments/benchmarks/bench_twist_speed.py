"""What the twisting arm costs the 3D benchmark envs: steps/s before and after, interleaved in one process.

* before: ``follow_target`` with the arm rigid in torsion (``curvature_arm(torsion=False)``) and ``ars443``;
  ``ik_4d`` with ``ars443`` at 4 steps per 0.1 s (at 2 its twisting arm diverges).
* after: the tasks' defaults (the arm twisting freely, ``ars443_frozen_mass`` at 2 steps per 0.1 s).

Each case is ``bench_env``'s timed call (``jit(vmap(step))`` with auto-reset, random actions, training
params: float32); the four cases are timed in turn, call by call, ``--repeats`` rounds, so that the
machine's drift (other jobs) falls on all of them alike; the rate is the median.

    python experiments/benchmarks/bench_twist_speed.py [--batch 64] [--repeats 7]

Writes benchmarks/twist_speed.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
import gvsjax as gv  # noqa: I001  (XLA flags first)
import jax

from gvsjax.tasks import auto_reset_step, make

OUT = Path(__file__).resolve().parents[2] / "benchmarks" / "twist_speed.json"


def cases() -> dict:
    """name -> (env, params)."""
    out = {}
    for task in ("follow_target", "ik_4d"):
        env = make(task)
        params = env.with_sim_dtype(env.train_params(), env.train_sim_dtype)  # as gvsjax.train
        arm = params.arm
        if task == "follow_target":
            old = dataclasses.replace(arm, robot=gv.curvature_arm(torsion=False), integrator="ars443")
        else:
            old = dataclasses.replace(arm, integrator="ars443", n_substeps=4)
        out[f"{task} before"] = (env, dataclasses.replace(params, arm=old))
        out[f"{task} after"] = (env, params)
    return out


def prepare(env, params, batch: int, steps: int):
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
    return run, state


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--steps", type=int, default=20, help="env steps per timed call")
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    runs = {name: (prepare(env, params, args.batch, args.steps), params) for name, (env, params) in cases().items()}
    states, times = {}, {name: [] for name in runs}
    for name, ((run, state), params) in runs.items():  # compile
        states[name], _ = jax.block_until_ready(run(jax.random.PRNGKey(1), state, params))
    load = [os.getloadavg()[0]]
    for i in range(args.repeats):
        for name, ((run, _), params) in runs.items():
            t0 = time.perf_counter()
            states[name], _ = jax.block_until_ready(run(jax.random.PRNGKey(2 + i), states[name], params))
            times[name].append(time.perf_counter() - t0)
        load.append(os.getloadavg()[0])
    rates = {name: args.batch * args.steps / statistics.median(t) for name, t in times.items()}
    for name, rate in rates.items():
        print(f"{name:22s} {rate:8.0f} env steps/s")
    for task in ("follow_target", "ik_4d"):
        print(f"{task}: after / before = {rates[f'{task} after'] / rates[f'{task} before']:.2f}")
    out = {"batch": args.batch, "steps_per_call": args.steps, "repeats": args.repeats, "dtype": "float32",
           "command": f"python experiments/benchmarks/bench_twist_speed.py --batch {args.batch} "
                      f"--repeats {args.repeats}",
           "load_average_1min": load, "cpus": os.cpu_count(), "jax": jax.__version__,
           "env_steps_per_s": rates, "times_s": times}
    OUT.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
