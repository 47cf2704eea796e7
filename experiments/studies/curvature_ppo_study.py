"""Algorithms, settings and observations for the benchmark tasks: one training run per call, its
result kept.

    python experiments/studies/curvature_ppo_study.py --task follow_target --name defaults --episodes 2048
    python experiments/studies/curvature_ppo_study.py --task follow_target --name sac --episodes 4000 -- algo=sac
    python experiments/studies/curvature_ppo_study.py --task follow_target --name rel-short --relative \\
        --episodes 2048 -- num_steps=8 num_minibatches=4 update_epochs=8

Trains ``--task`` with its defaults (PPO, or SAC with ``algo=sac``) plus the ``key=value`` overrides
after ``--`` (as ``python -m gvsjax.train``), with ``--relative`` appending the tip-to-target vector to the
benchmark's observation, and evaluates it on ``--eval`` held-out episodes. Writes
``benchmarks/curvature_ppo_study/<task>_<name>_e<episodes>_s<seed>.json``: the command, the config, the timing,
the evaluation (the deterministic policy on held-out episodes) and the learning curve (per update: the mean
episode reward, and the benchmark's discounted returns of the last 500 finished training episodes, whose
actions were sampled; older runs kept instead each update's mean ``episode_benchmark_return``).

    python experiments/studies/curvature_ppo_study.py --table     # the results so far, as a markdown table
    python experiments/studies/curvature_ppo_study.py --figure    # figures/curvature_learning_curves.png
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shlex
import sys
from pathlib import Path

import gvsjax.train
from gvsjax.tasks import make, register

ROOT = Path(__file__).resolve().parents[2]


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
    keep = ("update", "episodes", "wall_s", "episode_reward", "episode_benchmark_return", "episode_distance",
            "entropy", "approx_kl", "episodes_completed", "train_discounted_return_average",
            "train_discounted_return_start", "train_failed_fraction", "train_window_episodes")
    with open(run / "metrics.csv") as f:
        rows = [{k: float(row[k]) for k in keep if row.get(k) not in (None, "", "nan")} for row in csv.DictReader(f)]
    offset, last = 0.0, 0.0
    for r in rows:  # a resumed run's clock restarts: carry the wall time on across the legs
        if "wall_s" in r:
            if r["wall_s"] < last:
                offset += last
            last = r["wall_s"]
            r["wall_s"] += offset
    # a SAC run has a row per iteration: ~500 of the rows without a finished episode, and the others
    # merged until each holds num_envs episodes
    stride = max(1, len(rows) // 500)
    num_envs = json.loads((run / "config.json").read_text())["num_envs"]
    ended = smoothed([r for r in rows if "episode_benchmark_return" in r], num_envs)
    return sorted([r for i, r in enumerate(rows) if i % stride == 0 and "episode_benchmark_return" not in r] + ended,
                  key=lambda r: r["update"])


def train_seconds(d: dict) -> float:
    """Training wall time over every leg of a run (a resumed run's ``timing`` is its last leg's)."""
    return d["timing"]["train_s"] + sum(leg["train_s"] for leg in d.get("earlier_legs", []))


def env_steps(d: dict) -> int:
    """The env steps of a kept run: updates x num_envs x num_steps (PPO), iterations x num_envs (SAC)."""
    return d["timing"]["updates"] * d["config"]["num_envs"] * d["config"].get("num_steps", 1)


def smoothed(points: list[dict], at_least: int) -> list[dict]:
    """Consecutive curve points merged until each holds ``at_least`` finished episodes, the return
    weighted by episode count (a SAC iteration often ends one episode; a PPO update ends many)."""
    out, group = [], []
    for c in points:
        group.append(c)
        if sum(g.get("episodes_completed", at_least) for g in group) >= at_least:
            w = [g.get("episodes_completed", 1) for g in group]
            ret = sum(wi * g["episode_benchmark_return"] for wi, g in zip(w, group)) / sum(w)
            out.append({**group[-1], "episode_benchmark_return": ret, "episodes_completed": sum(w)})
            group = []
    return out


def training_returns(d: dict) -> str:
    """The benchmark's logged metric at a run's end: the discounted returns (averaged over start steps /
    from the first step) of its last 500 finished training episodes, sampled actions; "-" for older runs."""
    last = [c for c in d["curve"] if "train_discounted_return_average" in c]
    if not last:
        return "-"
    c = last[-1]
    return (f"{c['train_discounted_return_average']:.1f} / {c['train_discounted_return_start']:.1f}"
            f" ({100 * c.get('train_failed_fraction', 0.0):.1f}% failed)")


def table(folder: Path = ROOT / "benchmarks" / "curvature_ppo_study") -> str:
    """A markdown table of every kept run: its variant, budget, wall time, the training's discounted returns
    (the published metric) and the evaluation of the deterministic policy."""
    lines = ["| task | algorithm | variant | seed | overrides | env steps | train s (load) "
             "| training: last 500 episodes, sampled actions: discounted return avg / start (failed) "
             "| eval episodes | evaluation, deterministic: discounted return avg / start (failed) | evaluation |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for path in sorted(folder.glob("*.json")):
        d = json.loads(path.read_text())
        e = d["eval"]
        steps = env_steps(d)
        command = d["command"].split(" -- ")
        overrides = command[1] if len(command) > 1 else ""
        physical = {k: v for k, v in e.items() if isinstance(v, (int, float)) and k not in
                    ("seed", "n_episodes", "valid_fraction", "failed_fraction", "gamma", "settle_s")}
        physical.update({f"{k} median": v["median"] for k, v in e.items() if isinstance(v, dict) and "median" in v
                         and not k.startswith(("discounted", "return"))})
        shown = ", ".join(f"{k} {v:.3g}" for k, v in physical.items())
        legs = [*d.get("earlier_legs", []), d]
        load = ", ".join("/".join(f"{x:.1f}" for x in leg.get("load_average", [])) or "?" for leg in legs)
        algo = d["config"].get("algo") or "ppo"
        lines.append(f"| {d['task']} | {algo} | {d['name']}{' (+ tip-to-target)' if d['relative_obs'] else ''} | "
                     f"{d['seed']} | {overrides} | {steps / 1e6:.2f}M | {train_seconds(d):.0f} ({load}) | "
                     f"{training_returns(d)} | {e['n_episodes']} | "
                     f"{e['discounted_return_average']['mean']:.1f} / {e['discounted_return_start']['mean']:.1f} "
                     f"({100 * (1.0 - e['valid_fraction']):.1f}%) | {shown} |")
    return "\n".join(lines)


def figure(folder: Path = ROOT / "benchmarks" / "curvature_ppo_study",
           path: Path = ROOT / "figures" / "curvature_learning_curves.png") -> Path:
    """Each task's training curves in the benchmark's metric (the discounted return averaged over start steps
    of the last 500 finished training episodes, sampled actions; older runs: the mean of the episodes finished
    in each update) against env steps and wall time, the deterministic policy's evaluation on held-out episodes
    at the end (a dot), and the published SAC's final value (a dashed line, their training metric)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from gvsjax.utils import plots

    runs = [json.loads(p.read_text()) for p in sorted(folder.glob("*.json"))]
    row_of = lambda task: task.removesuffix("_frame")  # noqa: E731  (ik_4d_frame beside ik_4d)
    tasks = sorted({row_of(d["task"]) for d in runs})
    fig, axes = plt.subplots(len(tasks), 2, figsize=(13, 3.2 * len(tasks)), squeeze=False)
    colors = plt.get_cmap("tab20").colors  # a task can hold more runs than the default cycle's 10 colours
    for row, task in zip(axes, tasks):
        env = make(task)
        for i, d in enumerate(d for d in runs if row_of(d["task"]) == task):
            color = colors[i % len(colors)]
            key = "train_discounted_return_average"
            points = [c for c in d["curve"] if key in c]
            if not points:  # an older run: its per-update means, merged
                key = "episode_benchmark_return"
                points = smoothed([c for c in d["curve"] if key in c], d["config"]["num_envs"])
            label = (f"{d['config'].get('algo') or 'ppo'} {d['name']} s{d['seed']}, {env_steps(d) / 1e6:.2g}M"
                     + (f" ({d['task']})" if d["task"] != task else ""))
            final = d["eval"]["discounted_return_average"]["mean"]
            total = env_steps(d)
            for ax, x_of, end in ((row[0], lambda c: c["update"], total),
                                  (row[1], lambda c: c["wall_s"] / 60, train_seconds(d) / 60)):
                if points:
                    x = np.array([x_of(c) for c in points], float)
                    if ax is row[0]:
                        x = x * env_steps(d) / d["timing"]["updates"]
                    ax.plot(x, [c[key] for c in points], lw=1, color=color, label=label)
                    ax.plot([end], [final], "o", color=color)
                else:
                    ax.plot([end], [final], "o", color=color, label=label + " (evaluation only)")
        for ax, xlabel in zip(row, ("environment steps", "training wall time (min)")):
            ax.axhline(env.published_return, ls="--", color="k", lw=1, label="published SAC, 5M steps (training)")
            ax.set(xlabel=xlabel, ylabel="discounted return (averaged)", title=task)
            ax.grid(alpha=0.3)
        row[0].ticklabel_format(axis="x", style="sci", scilimits=(0, 0))  # steps as 1e6 x, labels apart
        row[1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.02, 0.5))  # outside: curves stay visible
    fig.suptitle("lines: training, the last 500 episodes with sampled actions (older runs: each update's "
                 "episodes); dots: evaluation, held-out episodes, deterministic", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.98))
    return plots.save(fig, path)


def main(argv: list[str]) -> int:
    if argv == ["--table"]:
        print(table())
        return 0
    if argv == ["--figure"]:
        print(figure())
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
    p.add_argument("--resume", action="store_true", help="continue the run from its last checkpoint")
    args = p.parse_args(argv[:split])
    overrides = argv[split + 1:]
    task = relative_variant(args.task) if args.relative else args.task
    load_before = os.getloadavg()[1]
    tag = f"{args.task}_{args.name}_e{args.episodes}_s{args.seed}"
    run = Path(args.runs) / tag
    out = ROOT / "benchmarks" / "curvature_ppo_study" / f"{tag}.json"
    earlier: list[dict] = []
    if args.resume:  # the legs before this one, for the total wall time
        kept = json.loads(out.read_text()) if out.exists() else {}
        if (run / "timing.json").exists():  # the last leg ran to its end
            leg = json.loads((run / "timing.json").read_text())
        else:  # it was stopped: its time up to the checkpoint, from the metrics log (whose clock runs on
            # across the legs before it)
            last = curve(run)[-1] if (run / "metrics.csv").exists() else {}
            before = sum(x["train_s"] for x in kept.get("earlier_legs", []))
            leg = {"train_s": last.get("wall_s", 0.0) - before, "updates": int(last.get("update", 0)), "stopped": True}
        earlier = [*kept.get("earlier_legs", []), {**leg, "load_average": kept.get("load_average", [])}]
    code = gvsjax.train.main([f"task={task}", f"out={run}", f"total_episodes={args.episodes}",
                              f"eval_targets={args.eval}", f"seed={args.seed}", "progress=false",
                              *(["resume=true"] if args.resume else []), *overrides])
    if code:
        return code
    result = {
        "command": "python experiments/studies/curvature_ppo_study.py " + shlex.join(argv),
        "task": args.task, "name": args.name, "relative_obs": args.relative, "seed": args.seed,
        "config": json.loads((run / "config.json").read_text()),
        "timing": json.loads((run / "timing.json").read_text()),
        "eval": json.loads((run / "eval.json").read_text()),
        "curve": curve(run),
        # 5-minute load averages on a 2-core machine: > 2 means the wall times were shared
        "load_average": [load_before, os.getloadavg()[1]],
        **({"earlier_legs": earlier} if earlier else {}),
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
