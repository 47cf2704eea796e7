"""Evaluate a trained policy (its deterministic, mean actions) or a reference controller on fresh episodes.

    python -m gvsjax.evaluate checkpoint=RUN_DIR [n_targets=1000] [seed=S] [out=DIR] [task=NAME]
    python -m gvsjax.evaluate task=NAME controller=mpc [horizon=10 iterations=10 learning_rate=0.1
                              discount=1.0 gradient=reverse|forward planner=adam|mppi samples=64 noise=0.3
                              temperature=0.1] [n_targets=100] [seed=S] [out=DIR]

``checkpoint`` is a run folder (holding checkpoint.ckpt) or the checkpoint
file; ``task`` (optional) must match the checkpoint's. Writes into ``out``
(default: the run folder): ``eval.json`` (the task's metrics of the deterministic
policy; beside them, under ``training``, the discounted returns of the run's last
finished training episodes, whose actions were sampled), the task's per-episode
table (basketball: ``eval_throws.csv``), its figures, and ``learning_curve.png``
(paper Fig. 3, and both discounted returns) when the folder has ``metrics.csv``.
Episodes come from ``reset`` keys of ``seed``: use a seed the training did not
use (the default, 1_000_003, is the one ``python -m gvsjax.train`` evaluates
seed-0 runs with).

``controller=mpc`` scores ``gvsjax.mpc.MPC`` (receding-horizon control through the
simulator, by its gradients or, with ``planner=mppi``, by sampled plans) instead of a
checkpoint, on the same episodes; ``out`` then defaults to ``runs/mpc_<task>``, and
eval.json adds the controller's settings, its wall time, the part spent compiling and the run time
per control step.
"""

from __future__ import annotations

import csv
import dataclasses
import gc
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax.ppo import checkpoint as ckpt
from gvsjax.tasks import EvalResult
from gvsjax.utils import keyvalue, plots, runlog
from gvsjax.utils.compile_clock import compile_seconds

USAGE = __doc__.strip()
KEYS: dict[str, Any] = {"task": "", "checkpoint": "", "n_targets": -1, "seed": -1, "out": "", "controller": "",
                        "horizon": 10, "iterations": 10, "learning_rate": 0.1, "discount": 1.0, "gradient": "reverse",
                        "planner": "adam", "samples": 64, "noise": 0.3, "temperature": 0.1}
MPC_KEYS = ("horizon", "iterations", "learning_rate", "discount", "gradient", "planner", "samples", "noise",
            "temperature")


def write_rows(path: Path, rows: dict[str, np.ndarray]) -> Path:
    """A CSV with one column per entry of ``rows`` (all of one length)."""
    columns = list(rows)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for i in range(len(rows[columns[0]]) if columns else 0):
            w.writerow([f"{float(rows[c][i]):.9g}" for c in columns])
    return path


def evaluate_run(checkpoint, out, n_episodes: int = 1000, seed: int = 1_000_003) -> dict:
    """Evaluate a checkpoint (file or run folder); write eval.json, the rows and the figures to ``out``.

    Returns eval.json's dict: ``task``, ``checkpoint``, ``seed`` and the task's metrics.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = ckpt.resolve(checkpoint)
    config, env, env_params, net = ckpt.load_policy(path)
    policy = ckpt.make_policy(config, env.action_size, net)
    result: EvalResult = env.evaluate(env_params, policy, n_episodes, seed)
    summary = {"task": env.name, "checkpoint": str(path), "seed": seed,
               "what": f"{n_episodes} held-out episodes, deterministic actions (the policy's mean)", **result.metrics}
    training = runlog.final_training_returns(path.parent / "metrics.csv")
    if training is not None:  # beside it, the training's own metric
        summary["training"] = training
    (out / "eval.json").write_text(json.dumps(summary, indent=2))
    write_rows(out / env.rows_file, result.rows)
    env.figures(env_params, result, out)
    if (out / "metrics.csv").exists():
        plots.learning_curve(out / "metrics.csv", out / "learning_curve.png", summary)
    return summary


def evaluate_controller(task: str, out, config, n_episodes: int = 100, seed: int = 1_000_003) -> dict:
    """Evaluate ``gvsjax.mpc.MPC(config)`` on ``task``'s default params; write eval.json, the rows
    and the figures to ``out``. Returns eval.json's dict (with ``controller`` and ``wall_s``)."""
    from gvsjax import mpc
    from gvsjax.tasks import make

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = make(task)
    params = env.default_params()
    start = time.perf_counter()
    with compile_seconds() as compiling:
        result: EvalResult = env.evaluate(params, mpc.MPC(env, params, config), n_episodes, seed)
    wall = time.perf_counter() - start
    steps = n_episodes * env.episode_length
    # per control step and episode: the batch's wall time less compilation (the batch shares each step)
    who = "MPC"  # what the summary and the figures call the evaluated controller
    summary = {"task": env.name, "who": who, "controller": mpc.describe(config), "seed": seed, "wall_s": wall,
               "compile_s": compiling[0], "wall_ms_per_control_step": 1e3 * wall / steps,
               "run_ms_per_control_step": 1e3 * (wall - compiling[0]) / steps, **result.metrics}
    (out / "eval.json").write_text(json.dumps(summary, indent=2))
    write_rows(out / env.rows_file, result.rows)
    env.figures(params, dataclasses.replace(result, extra={**result.extra, "who": who}), out)
    return summary


def parse_args(argv: list[str]) -> dict:
    given = keyvalue.parse(argv, {k: keyvalue.typed(v) for k, v in KEYS.items()})
    args = {**KEYS, **given}
    if not args["controller"] and set(given) & set(MPC_KEYS):
        raise ValueError(f"{sorted(set(given) & set(MPC_KEYS))} set the controller: add controller=mpc (a checkpoint's "
                         "policy takes none of them)")
    if args["controller"] not in ("", "mpc"):
        raise ValueError(f"controller={args['controller']!r} is invalid; expected 'mpc' (or leave it out and give "
                         "checkpoint=)")
    if args["controller"]:
        if args["checkpoint"]:
            raise ValueError("give either checkpoint= (a trained policy) or controller=mpc, not both")
        if not args["task"]:
            raise ValueError("controller=mpc needs task=NAME")
        from gvsjax import mpc
        from gvsjax.tasks import make

        if not make(args["task"]).accepts_controller:  # (an unknown task's error, too) before anything compiles
            raise ValueError(f"task={args['task']!r} evaluates policies only (an open-loop task); controller=mpc "
                             "runs on the closed-loop tasks")
        args["mpc"] = mpc.MPCConfig(**{k: args[k] for k in MPC_KEYS})
    elif not args["checkpoint"]:
        raise ValueError("checkpoint=PATH is required (a run folder or its checkpoint.ckpt), or controller=mpc")
    if args["n_targets"] < 1 and args["n_targets"] != -1:
        raise ValueError(f"n_targets={args['n_targets']} is invalid; expected an int >= 1 (default: 1000 episodes "
                         "for a checkpoint, 100 for controller=mpc)")
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
        seed = args["seed"] if args["seed"] >= 0 else 1_000_003
        if args["controller"]:
            task = args["task"]
            out = Path(args["out"] or f"runs/mpc_{task}")
            n = 100 if args["n_targets"] < 0 else args["n_targets"]
            result = evaluate_controller(task, out, args["mpc"], n, seed)
            return _report(task, result, out)
        path = ckpt.resolve(args["checkpoint"])
        task = ckpt.load_raw(path)["task"]
        if args["task"] and task != args["task"]:
            raise ValueError(f"checkpoint is for task={task!r}, not {args['task']!r}")
        out = Path(args["out"]) if args["out"] else path.parent
        result = evaluate_run(path, out, 1000 if args["n_targets"] < 0 else args["n_targets"], seed)
    except (ValueError, ckpt.CheckpointError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return _report(task, result, out)


def _report(task: str, result: dict, out: Path) -> int:
    from gvsjax.tasks import make

    print(make(task).summary(result))
    if "wall_s" in result:
        print(f"controller: {result['wall_s']:.0f} s ({result['compile_s']:.0f} s compiling), "
              f"{result['run_ms_per_control_step']:.1f} ms per control step and episode (the batch's run time)")
    print(f"wrote into {out}/: eval.json, the per-episode table and the figures (see --help)")
    return 0


if __name__ == "__main__":
    # a run traces programs of ~10^5 long-lived objects; Python's full collections would rescan
    # every imported module's objects each time (~20% of the trace time)
    gc.freeze()
    sys.exit(main())
