"""The evaluation command line (gvsjax.evaluate): a run folder or its checkpoint file, the
task's metrics, per-episode table and figures written (with finite drawn data), and bad
arguments or a wrong path as exit code 2 naming the problem, before anything compiles."""

import gvsjax  # noqa: F401, I001  (first: it configures JAX)
import csv
import dataclasses
import json

import jax
import numpy as np
import pytest
from helpers import capture_figures, finite_line, no_compile

from gvsjax import evaluate
from gvsjax.ppo import PPOConfig, init
from gvsjax.ppo import checkpoint as ckpt
from gvsjax.tasks import make

CONFIG = PPOConfig(num_envs=4, num_steps=1, num_minibatches=1, shared_hidden=(8,))
REWARDS = [0.2, 0.35, 0.5]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A basketball run folder as ``gvsjax.train`` leaves it: config.json, metrics.csv and the
    checkpoint of a (small, untrained) policy."""
    out = tmp_path_factory.mktemp("run")
    env = make("basketball")
    state = init(CONFIG, env, env.default_params(), jax.random.PRNGKey(0))
    config = {"task": "basketball", "train_targets": "", "sim_dtype": "float64", **dataclasses.asdict(CONFIG)}
    ckpt.save(out / ckpt.FILE_NAME, state, config, "basketball", 3)
    (out / "config.json").write_text(json.dumps(config))
    with open(out / "metrics.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["update", "episodes", "episode_reward", "episodes_completed"])
        w.writerows([i, 4 * (i + 1), r, 4] for i, r in enumerate(REWARDS))
    return out


@pytest.mark.extended
def test_run_folder_is_evaluated_into_itself(run_dir, capsys, monkeypatch):
    figures = capture_figures(monkeypatch)
    assert evaluate.main([f"checkpoint={run_dir}", "n_targets=4", "seed=7"]) == 0
    printed = capsys.readouterr().out
    assert "eval on 4 targets" in printed and f"wrote into {run_dir}/" in printed
    result = json.loads((run_dir / "eval.json").read_text())
    assert (result["task"], result["seed"], result["n_targets"]) == ("basketball", 7, 4)
    assert result["checkpoint"] == str(run_dir / ckpt.FILE_NAME)
    with open(run_dir / "eval_throws.csv", newline="") as f:
        throws = list(csv.DictReader(f))
    assert len(throws) == 4 and list(throws[0]) == ["target_x", "target_y", "T", "delta", "miss_m"]
    miss = np.array([float(t["miss_m"]) for t in throws])
    assert np.all(np.isfinite(miss)) and result["max_m"] == pytest.approx(miss.max())
    assert result["success_rate_10cm"] == np.mean(miss < 0.10)
    # the figures: the learning curve of the folder's metrics.csv, the histogram, the median throw
    per_update = finite_line(figures["learning_curve.png"], "per update (mean over its episodes)", min_points=3)
    np.testing.assert_allclose(per_update["y"], REWARDS)
    finite_line(figures["learning_curve.png"], "100-episode moving average", min_points=3)
    assert finite_line(figures["error_histogram.png"], "bars", min_points=11)["y"].sum() == pytest.approx(100.0)
    arm = finite_line(figures["throw.png"], "arm at release", min_points=3)
    ball = finite_line(figures["throw.png"], "ball", min_points=200)
    assert abs(arm["x"][0]) < 1e-12 and abs(arm["y"][0]) < 1e-12  # the arm's base
    assert (arm["x"][-1], arm["y"][-1]) == pytest.approx((ball["x"][0], ball["y"][0]), abs=1e-12)


def test_folder_without_a_checkpoint_is_named(tmp_path, capsys):
    with no_compile():
        assert evaluate.main([f"checkpoint={tmp_path}"]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path) in err and "without checkpoint.ckpt" in err


@pytest.mark.parametrize("args, words", [
    ([], ["checkpoint=PATH is required"]),
    (["checkpoint=/nonexistent.ckpt"], ["'/nonexistent.ckpt' does not exist"]),
    (["checkpoint={run}", "n_targets=0"], ["n_targets=0 is invalid"]),
    (["checkpoint={run}", "seed=-2"], ["seed=-2 is invalid"]),
    (["checkpoint={run}", "n_targets=many"], ["n_targets='many' is invalid"]),
    (["checkpoint={run}", "episodes=3"], ["unknown key 'episodes'", "n_targets"]),
    (["checkpoint={run}", "task=pickplace"], ["checkpoint is for task='basketball', not 'pickplace'"]),
    (["checkpoint={run}/checkpoint.ckpt", "task=pickplace"], ["checkpoint is for task='basketball'"]),
])
def test_bad_arguments_exit_2(run_dir, capsys, args, words):
    with no_compile():
        assert evaluate.main([a.format(run=run_dir) for a in args]) == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err


def test_help(capsys):
    assert evaluate.main(["--help"]) == 0
    assert "checkpoint=RUN_DIR" in capsys.readouterr().out
