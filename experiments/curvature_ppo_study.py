"""PPO settings and observations for the benchmark tasks: one training run per call, its result kept.

    python experiments/curvature_ppo_study.py --task follow_target --name defaults --episodes 2048
    python experiments/curvature_ppo_study.py --task follow_target --name rel-short --relative \\
        --episodes 2048 -- num_steps=8 num_minibatches=4 update_epochs=8

Trains ``--task`` with its PPO defaults plus the ``key=value`` overrides after ``--`` (as
``python -m gvsjax.train``), with ``--relative`` appending the tip-to-target vector to the
benchmark's observation, and evaluates it on ``--eval`` held-out episodes. Writes
``benchmarks/curvature_ppo_study/<task>_<name>.json``: the command, the config, the timing,
the evaluation and the learning curve (mean episode reward of the stochastic policy per update).

    python experiments/curvature_ppo_study.py --table     # the results so far, as a markdown table
"""

from __future__ import annotations

import argparse
import csv
import json
import shlex
import sys
from pathlib import Path

import gvsjax.train
from gvsjax.tasks import make, register

ROOT = Path(__file__).resolve().parents[1]


def relative_variant(task: str) -> str:
    """Register ``task`` with the tip-to-target vector appended to its observation."""
    base = type(make(task))

    class Relative(base):  # type: ignore[misc, valid-type]
        relative_obs = True
        obs_size = base.obs_size + (2 if base.planar else 3)

    name = f"{task}_relative"
    register(name, Relative)
    return name


def curve(run: Path) -> list[dict]:
    keep = ("update", "episodes", "wall_s", "episode_reward", "episode_distance", "entropy", "approx_kl")
    with open(run / "metrics.csv") as f:
        return [{k: float(row[k]) for k in keep if row.get(k) not in (None, "", "nan")}
                for row in csv.DictReader(f)]


def table(folder: Path = ROOT / "benchmarks" / "curvature_ppo_study") -> str:
    """A markdown table of every kept run: its variant, budget, wall time and evaluation."""
    lines = ["| task | variant | seed | overrides | env steps | train s | discounted return | evaluation |",
             "|---|---|---|---|---|---|---|---|"]
    for path in sorted(folder.glob("*.json")):
        d = json.loads(path.read_text())
        e, t = d["eval"], d["timing"]
        steps = t["episodes"] * make(d["task"]).episode_length
        command = d["command"].split(" -- ")
        overrides = command[1] if len(command) > 1 else ""
        physical = {k: v for k, v in e.items() if isinstance(v, (int, float)) and k not in
                    ("seed", "n_episodes", "valid_fraction", "gamma", "settle_s")}
        shown = ", ".join(f"{k} {v:.3g}" for k, v in physical.items())
        lines.append(f"| {d['task']} | {d['name']}{' (+ tip-to-target)' if d['relative_obs'] else ''} | "
                     f"{d['seed']} | {overrides} | {steps / 1e6:.2f}M | {t['train_s']:.0f} | "
                     f"{e['discounted_return_average']['mean']:.1f} | {shown} |")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if argv == ["--table"]:
        print(table())
        return 0
    split = argv.index("--") if "--" in argv else len(argv)
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--task", required=True)
    p.add_argument("--name", required=True, help="the variant's name in the output file")
    p.add_argument("--relative", action="store_true", help="append the tip-to-target vector to the observation")
    p.add_argument("--episodes", type=int, required=True, help="training episodes")
    p.add_argument("--eval", type=int, default=1000, help="held-out evaluation episodes")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--runs", default="runs/curvature_ppo_study", help="folder of the training runs")
    args = p.parse_args(argv[:split])
    overrides = argv[split + 1:]
    task = relative_variant(args.task) if args.relative else args.task
    run = Path(args.runs) / f"{args.task}_{args.name}_s{args.seed}"
    code = gvsjax.train.main([f"task={task}", f"out={run}", f"total_episodes={args.episodes}",
                              f"eval_targets={args.eval}", f"seed={args.seed}", "progress=false", *overrides])
    if code:
        return code
    result = {
        "command": "python experiments/curvature_ppo_study.py " + shlex.join(argv),
        "task": args.task, "name": args.name, "relative_obs": args.relative, "seed": args.seed,
        "config": json.loads((run / "config.json").read_text()),
        "timing": json.loads((run / "timing.json").read_text()),
        "eval": json.loads((run / "eval.json").read_text()),
        "curve": curve(run),
    }
    out = ROOT / "benchmarks" / "curvature_ppo_study" / f"{args.task}_{args.name}_s{args.seed}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
