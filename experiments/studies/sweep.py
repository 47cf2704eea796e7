"""A PPO hyperparameter sweep in one compiled call: seeds x learning rates, vmapped.

    python experiments/studies/sweep.py                                     # 2 seeds x 2 rates, short
    python experiments/studies/sweep.py --seeds 4 --rates 3e-4,1e-3,3e-3 --episodes 400000 --out runs/sweep.json

``make_train(config, env, params)`` is a pure function of the PRNG key and the
phase-1 learning rate, so ``jax.vmap(train)(keys, rates)`` trains every agent
at once (and, with several devices, each agent's env batch is split over
them: ``gvsjax.utils.sharding``). Every agent is then evaluated like
``gvsjax.evaluate`` (its deterministic policy, ``gvsjax.ppo.make_policy``, on
``--n-targets`` held-out episodes by the task's ``evaluate``). Other hyperparameters
come from the task's defaults (``gvsjax.train.task_defaults``, as the CLI)
plus ``key=value`` overrides.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax.ppo import PPOConfig, from_overrides, make_policy, make_train
from gvsjax.tasks import make
from gvsjax.train import task_defaults, training_params


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--task", default="basketball")
    p.add_argument("--seeds", type=int, default=2, help="seeds per learning rate (0, 1, ...)")
    p.add_argument("--rates", default="3e-4,1e-3", help="comma-separated phase-1 learning rates")
    p.add_argument("--episodes", type=int, default=4096, help="training episodes per agent")
    p.add_argument("--num-envs", type=int, default=256, help="environments per agent")
    p.add_argument("--n-targets", type=int, default=1000, help="held-out evaluation targets")
    p.add_argument("--eval-seed", type=int, default=1_000_003)
    p.add_argument("--out", default="runs/sweep.json")
    p.add_argument("overrides", nargs="*", help="PPOConfig key=value overrides")
    args = p.parse_args(argv)
    try:
        args.rates = [float(r) for r in args.rates.split(",")]
    except ValueError:
        p.error(f"--rates={args.rates!r} must be comma-separated floats")
    if args.seeds < 1 or args.episodes < 1 or args.num_envs < 1 or args.n_targets < 1:
        p.error("--seeds, --episodes, --num-envs and --n-targets must be >= 1")
    if any(not r > 0 for r in args.rates):
        p.error(f"--rates={args.rates} must be > 0")
    return args


def main(argv=None) -> dict:
    args = parse_args(argv)
    env = make(args.task)
    env_params = env.default_params()  # evaluation's
    train_params = training_params(env)  # the task's training distribution, as gvsjax.train
    defaults = dict(task_defaults(args.task))
    defaults.update(num_envs=args.num_envs, total_episodes=args.episodes)
    config = PPOConfig().replace(**defaults)
    if args.overrides:
        config = from_overrides(config, args.overrides)
    # every (rate, seed) pair is one agent
    grid = [(r, s) for r in args.rates for s in range(args.seeds)]
    keys = jnp.stack([jax.random.PRNGKey(s) for _, s in grid])
    rates = jnp.asarray([r for r, _ in grid])

    t0 = time.perf_counter()
    states, curves = jax.jit(jax.vmap(make_train(config, env, train_params)))(keys, rates)
    jax.block_until_ready(states)
    train_s = time.perf_counter() - t0

    agents = []
    for i, (rate, seed) in enumerate(grid):
        params = jax.tree.map(lambda x, i=i: x[i], states.params)
        policy = make_policy(config, env.action_size, params)
        result = env.evaluate(env_params, policy, args.n_targets, args.eval_seed).metrics
        agents.append({"learning_rate": rate, "seed": seed,
                       "final_episode_reward": float(curves["episode_reward"][i, -1]), **result})
        print(f"lr {rate:g} seed {seed}: " + ", ".join(
            f"{k} {v:.4g}" for k, v in result.items() if isinstance(v, float)))
    out = {"task": args.task, "agents": len(grid), "train_s_all_agents": train_s,
           "config": {k: v for k, v in vars(config).items()}, "results": agents}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2, default=str))
    print(f"{len(grid)} agents trained in one call in {train_s:.1f} s; wrote {args.out}")
    return out


if __name__ == "__main__":
    main()
