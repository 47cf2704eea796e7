"""Where a PPO update's time goes: the pieces of ``gvsjax.ppo.update`` timed apart.

Builds the training program of ``python -m gvsjax.train task=...`` (the task's defaults and
training targets, the same ``key=value`` overrides) and times, each as its own jitted call
at the config's ``num_envs`` (median of ``--repeats`` runs of ``--calls`` calls each):

* ``reset``: ``num_envs`` target draws (the task's ``reset``, vmapped);
* ``step``: ``num_envs`` env steps with random actions (the physics);
* ``collect``: the rollout (``num_steps`` policy evaluations, steps and auto-resets);
* ``update``: a whole PPO update (collect, GAE, ``update_epochs`` x ``num_minibatches`` Adam steps);
* ``learn``: ``update`` minus ``collect``, i.e. the gradient steps.

    python experiments/benchmarks/profile_training.py [--json out.json] [task=basketball sim_dtype=float32 ...]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import jax
from bench_sim import load_average  # this folder is on sys.path when run as a script

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax.ppo import build_config, init, update
from gvsjax.ppo.rollout import collect
from gvsjax.tasks import make
from gvsjax.train import parse_args, task_defaults, training_params


def timed(fn, arg, calls: int, repeats: int) -> tuple[float, float]:
    """(first call's seconds, median over ``repeats`` of the seconds per call of ``calls`` calls)."""
    t0 = time.perf_counter()
    jax.block_until_ready(fn(arg))
    first = time.perf_counter() - t0
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            out = fn(arg)
        jax.block_until_ready(out)
        runs.append((time.perf_counter() - t0) / calls)
    return first, statistics.median(runs)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", default=None)
    ap.add_argument("--calls", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=5)
    args, rest = ap.parse_known_args(argv)
    if not any(r.startswith("task=") for r in rest):
        rest = ["task=basketball"] + rest
    run, overrides = parse_args(rest)
    config = build_config(task_defaults(run["task"]), run["preset"], overrides)
    env = make(run["task"])
    params = training_params(env, run["train_targets"], run["sim_dtype"])
    state = init(config, env, params, jax.random.PRNGKey(config.seed))
    n = config.num_envs
    keys = jax.random.split(jax.random.PRNGKey(1), n)
    _, env_state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    actions = jax.random.uniform(jax.random.PRNGKey(2), (n, env.action_size), minval=-1, maxval=1)

    pieces = {
        "reset": (jax.jit(lambda k: jax.vmap(env.reset, in_axes=(0, None))(k, params)), keys),
        "step": (jax.jit(lambda a: jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, env_state, a, params)),
                 actions),
        "collect": (jax.jit(lambda s: collect(config, env, params, s)), state),
        "update": (jax.jit(lambda s: update(config, env, params, s)), state),
    }
    result: dict = {"task": run["task"], "sim_dtype": run["sim_dtype"] or "float64", "num_envs": n,
                    "num_steps": config.num_steps, "epochs": config.update_epochs,
                    "minibatches": config.num_minibatches, "ms": {}, "compile_s": {}}
    for name, (fn, arg) in pieces.items():
        first, per_call = timed(fn, arg, args.calls, args.repeats)
        result["ms"][name] = 1e3 * per_call
        result["compile_s"][name] = first
        print(f"{name:8s} {1e3 * per_call:9.2f} ms per call   (first call {first:.1f} s)", flush=True)
    result["ms"]["learn"] = result["ms"]["update"] - result["ms"]["collect"]
    episodes = n * config.num_steps / env.episode_length
    result["episodes_per_s"] = episodes / (result["ms"]["update"] / 1e3)
    result["load"] = load_average()
    print(f"learn    {result['ms']['learn']:9.2f} ms per update (update - collect)")
    print(f"{result['episodes_per_s']:,.0f} episodes/s; load {result['load']}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return result


if __name__ == "__main__":
    main()
