"""Regenerate every figure and table of the paper into one folder, with one command.

    python experiments/paper/reproduce_paper.py [--quick] [--out paper_out]

Runs, in order (each step reuses the project's own scripts and modules):

1. ``basketball_figures.py``: the workspace (Fig. 2 left) and the arm's shapes at release for
   T = 2 s at several delta (Fig. 2 right);
2. ``gvsjax.train`` on basketball (PPO; its final ``gvsjax.evaluate`` writes the learning curve,
   Fig. 3, the throw at the median miss, Fig. 4, and the error histogram, Fig. 5);
3. ``baseline_basketball.py``: the differentiable-physics baseline on the same held-out targets;
4. ``gvsjax.train`` on pick and place, then ``pickplace_figures.py`` (Table I, Fig. 6, the
   reachable band, the learning curve) and ``baseline_pickplace.py`` (the model's best on the
   paper's pair);
5. an index of the folder: ``README.md`` and ``index.json`` (file -> paper figure, description).

``--quick`` trains briefly (minutes in all: the figures show the pipeline, not the final
quality); the default uses the paper-quality settings of the README (basketball 1.2M episodes,
pick and place 120k), and its wall time is mostly those two trainings.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # the sibling experiment scripts, imported as modules

import baseline_basketball
import baseline_pickplace
import basketball_figures
import pickplace_figures

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax import train

SETTINGS = {  # per mode: PPO episodes, evaluation targets, baseline sizes
    "quick": {"bb_episodes": 40_960, "pp_episodes": 10_240, "eval_targets": 200, "pp_baseline_pairs": 4},
    "full": {"bb_episodes": 1_200_000, "pp_episodes": 120_000, "eval_targets": 1000, "pp_baseline_pairs": 16},
}
EVAL_SEED = 1_000_003  # the evaluation targets (train's default for seed 0; never used in training)

# file (relative to the output folder) -> (paper figure or table, what it shows)
INDEX = {
    "basketball_workspace.png": ("Fig. 2 (left)", ("workspace: flight paths over the action box, "
                                                   "the target window and 2000 targets drawn by reset")),
    "basketball_workspace_area.png": ("Fig. 2 (left), variant", "the same with area-uniform targets"),
    "basketball_shapes_T2.png": ("Fig. 2 (right)", "arm at release and ball paths, T = 2 s, several delta"),
    "basketball_run/learning_curve.png": ("Fig. 3", "PPO learning curve (mean episode reward)"),
    "basketball_run/throw.png": ("Fig. 4", "a throw at the median miss: arm at release and ball path"),
    "basketball_run/error_histogram.png": ("Fig. 5", "miss distance histogram on held-out targets"),
    "basketball_run/eval.json": ("Sec. IV-A results", "PPO: success < 10 cm, share < 1 cm, median/p95/max"),
    "basketball_run/eval_throws.csv": ("Sec. IV-A results", "per target: target, T, delta, miss"),
    "basketball_run/metrics.csv": ("Fig. 3 data", "one row per PPO update"),
    "basketball_run/config.json": ("-", "the training configuration (reloadable)"),
    "basketball_run/baseline_eval.json": ("comparison", "Gauss-Newton through the simulator, same targets"),
    "basketball_run/baseline_error_histogram.png": ("comparison", "the baseline's miss histogram"),
    "pickplace_run/learning_curve.png": ("Sec. IV-B", "PPO learning curve, pick and place"),
    "pickplace_run/eval.json": ("Sec. IV-B results", "per-step distance statistics on held-out pairs"),
    "pickplace_run/error_histogram_step1.png": ("Sec. IV-B", "step-1 (pick) distance histogram"),
    "pickplace_run/error_histogram_step2.png": ("Sec. IV-B", "step-2 (place) distance histogram"),
    "pickplace_run/episode_paper_pair.png": ("Fig. 6", "the policy's episode on the paper's pair"),
    "pickplace_run/eval_episodes.csv": ("Sec. IV-B results", "per pair: targets, tips, actions, distances"),
    "pickplace_run/config.json": ("-", "the training configuration (reloadable)"),
    "pickplace/pickplace_table1.md": ("Table I", "the paper's target pair: targets, tips, distances, actions"),
    "pickplace/pickplace_table1.json": ("Table I", "the same as JSON"),
    "pickplace/pickplace_fig6.png": ("Fig. 6", "arm shapes over both steps, joint angle and tension"),
    "pickplace/pickplace_learning_curve.png": ("Sec. IV-B", "reward per step and step-2 distance"),
    "pickplace/pickplace_reachable.png": ("Sec. IV-B (model)", "the reachable band and the paper's pair"),
    "pickplace/baseline_pickplace.json": ("Table I, comparison", "the model's best on the paper's pair (LM)"),
}


def _train(task: str, out: Path, episodes: int, eval_targets: int) -> Path:
    run, overrides = train.parse_args([f"task={task}", f"out={out}", f"total_episodes={episodes}",
                                       f"eval_targets={eval_targets}", f"eval_seed={EVAL_SEED}",
                                       "progress=false"])
    return train.train(run, overrides)


def write_index(out: Path, mode: str, seconds: dict[str, float]) -> None:
    """README.md and index.json listing every output (missing ones flagged)."""
    entries = [{"file": f, "paper": p, "what": w, "exists": (out / f).exists()} for f, (p, w) in INDEX.items()]
    listed = set(INDEX)
    extra = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()
                   and str(p.relative_to(out)) not in listed and p.name not in ("README.md", "index.json")
                   and not p.name.endswith(".ckpt"))
    (out / "index.json").write_text(json.dumps({"mode": mode, "seconds": seconds, "files": entries,
                                                "other_files": extra}, indent=2))
    lines = [f"# Paper figures and tables ({mode} mode)", "",
             "Regenerated by `python experiments/paper/reproduce_paper.py" + (" --quick" if mode == "quick" else "")
             + "`. Wall time per stage (s): " + ", ".join(f"{k} {v:.0f}" for k, v in seconds.items()) + ".",
             "", "| file | paper | what |", "|---|---|---|"]
    lines += [f"| [{e['file']}]({e['file']}) | {e['paper']} | {e['what']}"
              + ("" if e["exists"] else " (**missing**)") + " |" for e in entries]
    if extra:
        lines += ["", "Other files: " + ", ".join(extra)]
    (out / "README.md").write_text("\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small trainings (minutes): shows the pipeline")
    ap.add_argument("--out", default="paper_out", help="output folder (default paper_out/)")
    args = ap.parse_args(argv)
    mode = "quick" if args.quick else "full"
    cfg = SETTINGS[mode]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seconds: dict[str, float] = {}

    def stage(name, fn, *a):
        print(f"\n=== {name} ===", flush=True)
        t0 = time.perf_counter()
        fn(*a)
        seconds[name] = time.perf_counter() - t0

    bb_run, pp_dir = out / "basketball_run", out / "pickplace"
    stage("fig2", basketball_figures.main, out)
    stage("train_basketball", _train, "basketball", bb_run, cfg["bb_episodes"], cfg["eval_targets"])
    stage("baseline_basketball", baseline_basketball.main, str(bb_run), str(cfg["eval_targets"]), str(EVAL_SEED))
    pp_run = out / "pickplace_run"
    stage("train_pickplace", _train, "pickplace", pp_run, cfg["pp_episodes"], cfg["eval_targets"])
    stage("pickplace_figures", pickplace_figures.main, [f"checkpoint={pp_run / 'checkpoint.ckpt'}", f"out={pp_dir}"])
    stage("baseline_pickplace", baseline_pickplace.main, str(cfg["pp_baseline_pairs"]), str(pp_dir))
    write_index(out, mode, seconds)
    print(f"\nall done in {sum(seconds.values()):.0f} s; open {out / 'README.md'} (index of every file)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
