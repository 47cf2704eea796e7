"""Evaluate a trained policy: deterministic (mean) actions on random reachable targets.

    python -m gvsjax.evaluate task=basketball checkpoint=PATH [n_targets=1000] [seed=S] [out=DIR]

Writes into ``out`` (default: the checkpoint's folder): ``eval.json`` (success
rate < 10 cm, fraction < 1 cm, median / 95th percentile / max miss in m),
``eval_throws.csv`` (``target_x,target_y,T,delta,miss_m``, one row per
target) and the figures ``learning_curve.png`` (Fig. 3, when the folder has a
``metrics.csv``), ``error_histogram.png`` (Fig. 5) and ``throw.png`` (Fig. 4,
the throw at the median miss). Targets are drawn with ``reset`` keys from
``seed``: use a seed the training did not use (training uses ``seed`` for its
own key stream; the default evaluation seed is 1_000_003 + training seed).
"""

from __future__ import annotations

import csv
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax import checkpoint, plots
from gvsjax.ppo import init, make_network, policy_action
from gvsjax.tasks import make, registered

USAGE = __doc__.strip()
KEYS: dict[str, Any] = {"task": "basketball", "checkpoint": "", "n_targets": 1000, "seed": -1, "out": ""}


def load_policy(ckpt_path):
    """(config, env, env_params, network params) from a training checkpoint."""
    from gvsjax.train import config_from_json

    meta = checkpoint.load_raw(ckpt_path)
    config = config_from_json(meta["config"], f"the config saved in {ckpt_path}")
    env = make(meta["task"])
    env_params = env.default_params()
    template = jax.eval_shape(lambda: init(config, env, env_params, jax.random.PRNGKey(0)))
    template = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), template)
    state = checkpoint.restore_state(template, meta["train_state"])  # CheckpointError if mismatched
    return config, env, env_params, state.params


_ROLLOUTS: dict[tuple, Callable] = {}  # jitted rollouts per (task, network), reused in-process
_NETWORK_FIELDS = ("network", "shared_hidden", "actor_hidden", "critic_hidden", "activation",
                   "std_mode", "init_log_std", "min_log_std")


def rollout(config, env, env_params, params, n_targets: int, seed: int) -> dict[str, np.ndarray]:
    """Targets (n, 2), actions, T, delta, miss (m) of the deterministic policy."""
    key = (env.name,) + tuple(getattr(config, f) for f in _NETWORK_FIELDS)
    if key not in _ROLLOUTS:
        apply_fn = make_network(config, env.action_size).apply

        @jax.jit
        def run(params, keys):
            obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, env_params)
            action = policy_action(params, apply_fn, obs.astype(jnp.float32)).astype(jnp.float64)
            _, _, _, _, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
                keys, state, action, env_params)
            return state.target, action, info

        _ROLLOUTS[key] = run
    target, action, info = _ROLLOUTS[key](params, jax.random.split(jax.random.PRNGKey(seed), n_targets))
    miss = np.asarray(info["cost"], float)
    miss = np.where(np.asarray(info["valid"]), miss, np.inf)
    return {"target": np.asarray(target), "action": np.asarray(action),
            "T": np.asarray(info["T"]), "delta": np.asarray(info["delta"]), "miss": miss}


def metrics(miss: np.ndarray) -> dict[str, float]:
    """Summary of misses (m)."""
    return {
        "n_targets": int(len(miss)),
        "success_rate_10cm": float(np.mean(miss < 0.10)),
        "within_1cm": float(np.mean(miss < 0.01)),
        "within_5mm": float(np.mean(miss < 0.005)),
        "median_m": float(np.median(miss)),
        "p95_m": float(np.percentile(miss, 95)),
        "max_m": float(np.max(miss)),
        "mean_m": float(np.mean(miss)),
    }


def write_throws_csv(path, r: dict[str, np.ndarray]) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["target_x", "target_y", "T", "delta", "miss_m"])
        for t, T, d, m in zip(r["target"], r["T"], r["delta"], r["miss"]):
            w.writerow([f"{t[0]:.6f}", f"{t[1]:.6f}", f"{T:.6f}", f"{d:.6f}", f"{m:.6e}"])


def evaluate_run(ckpt_path, out, n_targets: int = 1000, seed: int = 1_000_003) -> dict:
    """Evaluate the checkpoint and write eval.json, eval_throws.csv and the figures to ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    config, env, env_params, params = load_policy(ckpt_path)
    if hasattr(env, "evaluate"):  # a task with its own evaluation (e.g. pickplace)
        result = env.evaluate(config, env_params, params, out, n_targets, seed)
        if (out / "metrics.csv").exists():
            plots.learning_curve(out / "metrics.csv", out / "learning_curve.png")
        return result
    r = rollout(config, env, env_params, params, n_targets, seed)
    result = {"task": env.name, "checkpoint": str(ckpt_path), "seed": seed, **metrics(r["miss"])}
    (out / "eval.json").write_text(json.dumps(result, indent=2))
    write_throws_csv(out / "eval_throws.csv", r)
    if (out / "metrics.csv").exists():
        plots.learning_curve(out / "metrics.csv", out / "learning_curve.png")
    plots.error_histogram(r["miss"], out / "error_histogram.png")
    i = int(np.argsort(r["miss"])[len(r["miss"]) // 2])  # a typical throw: the median miss
    plots.throw(env_params, r["target"][i], float(r["T"][i]), float(r["delta"][i]),
                out / "throw.png", miss_m=float(r["miss"][i]))
    return result


def summary(result: dict) -> str:
    if "success_rate_10cm" not in result:  # a task's own result: its module formats it
        mod = sys.modules.get(f"gvsjax.tasks.{result.get('task')}")
        return mod.summary(result) if mod is not None and hasattr(mod, "summary") else json.dumps(result)
    return (f"eval on {result['n_targets']} targets (seed {result['seed']}): "
            f"success<10cm {100 * result['success_rate_10cm']:.1f}%, "
            f"<1cm {100 * result['within_1cm']:.1f}%, median {100 * result['median_m']:.2f} cm, "
            f"p95 {100 * result['p95_m']:.2f} cm, max {100 * result['max_m']:.2f} cm")


def parse_key_values(argv: list[str], defaults: dict[str, Any]) -> dict[str, Any]:
    """``["key=value", ...]`` over ``defaults``, each value parsed by its default's type."""
    args = dict(defaults)
    for item in argv:
        key, sep, text = item.partition("=")
        if not sep or key not in defaults:
            raise ValueError(f"bad argument {item!r}; valid keys: {sorted(defaults)} (key=value)")
        try:
            args[key] = type(defaults[key])(text)
        except ValueError:
            raise ValueError(f"{key}={text!r} is invalid; expected {type(defaults[key]).__name__}") from None
    return args


def parse_args(argv: list[str]) -> dict:
    args = parse_key_values(argv, KEYS)
    if not args["checkpoint"]:
        raise ValueError("checkpoint=PATH is required")
    if args["task"] not in registered():
        raise ValueError(f"task={args['task']!r} is unknown; choose one of {registered()}")
    if args["n_targets"] < 1:
        raise ValueError(f"n_targets={args['n_targets']} is invalid; expected an int >= 1")
    if args["seed"] < -1:
        raise ValueError(f"seed={args['seed']} is invalid; expected an int >= 0 (or -1: 1_000_003)")
    return args


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if any(a in ("-h", "--help", "help") for a in argv):
        print(USAGE)
        return 0
    try:
        args = parse_args(argv)
        ckpt = Path(args["checkpoint"])
        meta_task = checkpoint.load_raw(ckpt)["task"]
        if meta_task != args["task"]:
            raise ValueError(f"checkpoint is for task={meta_task!r}, not {args['task']!r}")
        out = Path(args["out"]) if args["out"] else ckpt.parent
        seed = args["seed"] if args["seed"] >= 0 else 1_000_003
        result = evaluate_run(ckpt, out, args["n_targets"], seed)
    except (ValueError, checkpoint.CheckpointError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(summary(result))
    print(f"wrote into {out}/: eval.json and the figures (see --help)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
