"""Wall time until the default training reaches the paper's quality (the aim: <= 2 minutes).

Runs ``python -m gvsjax.train``'s program (task defaults, the task's training
targets, ``updates_per_call`` chunks of ~8k episodes) and, between chunks,
evaluates the deterministic policy (``make_policy``) on the same 1000 held-out
targets as ``gvsjax.evaluate`` (seed 1_000_003 + seed; the throws and metrics of
``Basketball.evaluate``, compiled once for all chunks). Evaluation time is excluded from
the training clock; the first chunk's compile time is included (and also
reported apart). Prints when each quality level is first reached:

* ``paper``: 100% of targets within 10 cm and >= 55% within 1 cm (Armanini et al.);
* ``55% < 1 cm`` and ``99% < 10 cm`` separately; ``90% < 1 cm`` (a stricter aim).

    python experiments/studies/time_to_quality.py [--json out.json] [seed=0 ...any gvsjax.train key=value]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[1] / "benchmarks"))  # bench_sim, in the benchmarks folder
from bench_sim import load_average

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax.ppo import build_config, init, make_policy, make_update, num_updates
from gvsjax.tasks import make
from gvsjax.tasks.basketball import miss_metrics
from gvsjax.train import default_updates_per_call, parse_args, task_defaults, training_params, use_compile_cache

LEVELS = {
    "paper (100% < 10 cm, >= 55% < 1 cm)": lambda m: m["success_rate_10cm"] >= 1.0 and m["within_1cm"] >= 0.55,
    "55% < 1 cm": lambda m: m["within_1cm"] >= 0.55,
    "99% < 10 cm": lambda m: m["success_rate_10cm"] >= 0.99,
    "99% < 10 cm and 85% < 1 cm": lambda m: m["success_rate_10cm"] >= 0.99 and m["within_1cm"] >= 0.85,
    "90% < 1 cm": lambda m: m["within_1cm"] >= 0.90,
}


def evaluator(config, env, env_params, n_targets: int, seed: int):
    """``metrics(network params)`` of the deterministic policy on the targets of ``reset`` keys of
    ``seed``, as ``env.evaluate`` computes them. The network params are an argument of one jitted
    program: ``env.evaluate`` takes a policy closed over its params, so it compiles per call."""
    keys = jax.random.split(jax.random.PRNGKey(seed), n_targets)

    @jax.jit
    def misses(net_params):
        obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, env_params)
        action = make_policy(config, env.action_size, net_params)(obs)
        _, _, _, _, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, state, action, env_params)
        return jnp.where(info["valid"], info["cost"], jnp.inf)

    return lambda net_params: miss_metrics(np.asarray(misses(net_params), float))


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", default=None, help="write the curve and the first-reached times here")
    ap.add_argument("--n-targets", type=int, default=1000)
    args, rest = ap.parse_known_args(argv)
    run, overrides = parse_args(["task=basketball"] + rest)
    if run["compile_cache"]:  # before anything compiles
        use_compile_cache(run["compile_cache"])
    config = build_config(task_defaults(run["task"]), run["preset"], overrides)
    env = make(run["task"])
    eval_params = env.default_params()  # evaluation simulates in float64 whatever training uses
    train_params = training_params(env, run["train_targets"], run["sim_dtype"])
    eval_seed = 1_000_003 + config.seed
    evaluate = evaluator(config, env, eval_params, args.n_targets, eval_seed)
    state = init(config, env, train_params, jax.random.PRNGKey(config.seed))
    per_call = default_updates_per_call(config, env.episode_length)
    step = make_update(config, env, train_params, updates_per_call=per_call)
    total = num_updates(config, env.episode_length)
    clock, curve, first = 0.0, [], {}
    compile_s = None
    while int(state.update) < total:
        t0 = time.perf_counter()
        state, _ = step(state)
        jax.block_until_ready(state)
        dt = time.perf_counter() - t0
        compile_s = dt if compile_s is None else compile_s
        clock += dt
        m = evaluate(state.params)
        row = {"train_s": clock, "episodes": int(state.episodes), **{k: float(v) for k, v in m.items()}}
        curve.append(row)
        for name, reached in LEVELS.items():
            if name not in first and reached(m):
                first[name] = {"train_s": clock, "episodes": row["episodes"]}
        print(f"{clock:7.1f} s {row['episodes']:8d} ep  <10cm {m['success_rate_10cm']:.3f}  "
              f"<1cm {m['within_1cm']:.3f}  median {100 * m['median_m']:.2f} cm  max {100 * m['max_m']:.1f} cm",
              flush=True)
    print(f"\nfirst call (compile + {per_call} updates): {compile_s:.1f} s; machine load: {load_average()}")
    print("| quality | first reached at (s of training) | episodes |\n|---|---|---|")
    for name in LEVELS:
        hit = first.get(name)
        print(f"| {name} | {hit['train_s']:.0f} | {hit['episodes']:,} |" if hit else f"| {name} | not reached | - |")
    result = {"config": {k: getattr(config, k) for k in ("seed", "num_envs", "total_episodes", "antithetic",
                                                          "adaptive_kl", "learning_rate")},
              "train_targets": run["train_targets"], "eval_seed": eval_seed, "compile_s": compile_s,
              "first": first, "curve": curve, "load": load_average()}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return result


if __name__ == "__main__":
    main()
