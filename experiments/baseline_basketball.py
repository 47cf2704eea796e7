"""Differentiable-physics baseline vs PPO on the same held-out basketball targets.

    python experiments/baseline_basketball.py [run_dir] [n_targets=1000] [seed=1000003]

Draws the targets exactly as ``gvsjax.evaluate`` does (``reset`` keys from
``seed``), solves each by Gauss-Newton through the simulator
(``gvsjax.baseline``), and writes ``baseline_eval.json``,
``baseline_throws.csv`` and ``baseline_error_histogram.png`` into ``run_dir``
(default ``figures/``). If ``run_dir/eval.json`` exists (a PPO evaluation with
the same seed), both summaries are printed side by side.
"""

import json
import sys
from pathlib import Path

import jax
import numpy as np

import gvsjax  # noqa: F401
from gvsjax import baseline, evaluate, plots
from gvsjax.tasks import make


def main(run_dir="figures", n_targets="1000", seed="1000003"):
    out = Path(run_dir)
    out.mkdir(parents=True, exist_ok=True)
    n, seed = int(n_targets), int(seed)
    env = make("basketball")
    params = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(seed), n)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    targets = np.asarray(state.target)
    r = baseline.solve_targets(params, targets)
    r["target"] = targets
    result = {"method": "gauss-newton through the simulator", "seed": seed,
              "seconds": r["seconds"], **evaluate.metrics(r["miss"])}
    (out / "baseline_eval.json").write_text(json.dumps(result, indent=2))
    evaluate.write_throws_csv(out / "baseline_throws.csv", r)
    plots.error_histogram(r["miss"], out / "baseline_error_histogram.png")
    print("baseline:", evaluate.summary(result), f"({r['seconds']:.0f} s)")
    ppo = out / "eval.json"
    if ppo.exists():
        p = json.loads(ppo.read_text())
        if p.get("seed") == seed and p.get("n_targets") == n:
            print("PPO:     ", evaluate.summary(p))


if __name__ == "__main__":
    main(*sys.argv[1:])
