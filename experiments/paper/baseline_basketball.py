"""Differentiable-physics baseline vs PPO on the same held-out basketball targets.

    python experiments/paper/baseline_basketball.py [run_dir] [n_targets=1000] [seed=1000003]

Draws the targets exactly as ``Basketball.evaluate`` does (``reset`` keys from
``seed``), solves each by Gauss-Newton through the simulator
(``gvsjax.tasks.basketball.baseline``), and writes ``baseline_eval.json``,
``baseline_throws.csv`` (the columns of ``eval_throws.csv``) and
``baseline_error_histogram.png`` into ``run_dir`` (default ``figures/``). If
``run_dir/eval.json`` exists (a PPO evaluation with the same seed), both
summaries are printed side by side.
"""

import json
import sys
from pathlib import Path

import jax
import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax.evaluate import write_rows
from gvsjax.tasks import basketball as bb
from gvsjax.tasks.basketball import baseline
from gvsjax.utils import plots


def main(run_dir="figures", n_targets="1000", seed="1000003"):
    if run_dir in ("-h", "--help", "help"):
        print(__doc__.strip())
        return
    out = Path(run_dir)
    out.mkdir(parents=True, exist_ok=True)
    n, seed = int(n_targets), int(seed)
    env = bb.Basketball()
    params = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(seed), n)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    targets = np.asarray(state.target)
    r = baseline.solve_targets(params, targets)
    metrics = bb.miss_metrics(r["miss"])
    result = {"method": "gauss-newton through the simulator", "seed": seed, "seconds": r["seconds"], **metrics}
    (out / "baseline_eval.json").write_text(json.dumps(result, indent=2))
    write_rows(out / "baseline_throws.csv", {"target_x": targets[:, 0], "target_y": targets[:, 1],
                                             "T": r["T"], "delta": r["delta"], "miss_m": r["miss"]})
    plots.error_histogram(r["miss"], out / "baseline_error_histogram.png", title="miss")
    print("baseline:", env.summary(metrics), f"({r['seconds']:.0f} s)")
    ppo = out / "eval.json"
    if ppo.exists():
        p = json.loads(ppo.read_text())
        if p.get("seed") == seed and p.get("n_targets") == n:
            print("PPO:     ", env.summary(p))


if __name__ == "__main__":
    main(*sys.argv[1:])
