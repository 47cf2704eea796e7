"""Evaluate a trained policy: its deterministic (mean) actions on fresh episodes.

    python -m gvsjax.evaluate checkpoint=RUN_DIR [n_targets=1000] [seed=S] [out=DIR] [task=NAME]

``checkpoint`` is a run folder (holding checkpoint.ckpt) or the checkpoint
file; ``task`` (optional) must match the checkpoint's. Writes into ``out``
(default: the run folder): ``eval.json`` (the task's metrics), the task's
per-episode table (basketball: ``eval_throws.csv``), its figures, and
``learning_curve.png`` (paper Fig. 3) when the folder has ``metrics.csv``.
Episodes come from ``reset`` keys of ``seed``: use a seed the training did not
use (the default, 1_000_003, is the one ``python -m gvsjax.train`` evaluates
seed-0 runs with).
"""

from __future__ import annotations

import csv
import gc
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax import keyvalue, plots
from gvsjax.ppo import checkpoint as ckpt
from gvsjax.tasks import EvalResult

USAGE = __doc__.strip()
KEYS: dict[str, Any] = {"task": "", "checkpoint": "", "n_targets": 1000, "seed": -1, "out": ""}


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
    summary = {"task": env.name, "checkpoint": str(path), "seed": seed, **result.metrics}
    (out / "eval.json").write_text(json.dumps(summary, indent=2))
    write_rows(out / env.rows_file, result.rows)
    env.figures(env_params, result, out)
    if (out / "metrics.csv").exists():
        plots.learning_curve(out / "metrics.csv", out / "learning_curve.png")
    return summary


def parse_args(argv: list[str]) -> dict:
    args = {**KEYS, **keyvalue.parse(argv, {k: keyvalue.typed(v) for k, v in KEYS.items()})}
    if not args["checkpoint"]:
        raise ValueError("checkpoint=PATH is required (a run folder or its checkpoint.ckpt)")
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
        path = ckpt.resolve(args["checkpoint"])
        task = ckpt.load_raw(path)["task"]
        if args["task"] and task != args["task"]:
            raise ValueError(f"checkpoint is for task={task!r}, not {args['task']!r}")
        out = Path(args["out"]) if args["out"] else path.parent
        seed = args["seed"] if args["seed"] >= 0 else 1_000_003
        result = evaluate_run(path, out, args["n_targets"], seed)
    except (ValueError, ckpt.CheckpointError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    from gvsjax.tasks import make

    print(make(task).summary(result))
    print(f"wrote into {out}/: eval.json, the per-episode table and the figures (see --help)")
    return 0


if __name__ == "__main__":
    # a run traces programs of ~10^5 long-lived objects; Python's full collections would rescan
    # every imported module's objects each time (~20% of the trace time)
    gc.freeze()
    sys.exit(main())
