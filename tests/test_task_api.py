"""A task defined here, registered with one line, runs through every generic front end:
``python -m gvsjax.train``, ``python -m gvsjax.evaluate``, Gymnasium (``check_env``),
``animate``, with no change to any of them."""

from __future__ import annotations

import csv
import json

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct
from gymnasium.utils.env_checker import check_env

import gvsjax  # noqa: F401  (before JAX starts its backend)
import gvsjax.gym as gg
from gvsjax import animate, evaluate, train
from gvsjax.tasks import Box, Environment, make, register, registered


@struct.dataclass
class PointParams:
    gain: float = 0.5  # position change per unit action


@struct.dataclass
class PointState:
    x: jax.Array  # (1,)
    target: jax.Array  # (1,)
    t: jax.Array


class PointReach(Environment):
    """Move a point on a line to a target in three steps: x += gain * action."""

    name = "point_reach"
    obs_size = 2
    action_size = 1
    episode_length = 3
    ppo_defaults = dict(num_envs=16, num_steps=3, num_minibatches=2, update_epochs=2, shared_hidden=(16,),
                        total_episodes=2000, learning_rate=3e-3, gamma=1.0)

    def default_params(self):
        return PointParams()

    def observation_space(self, params=None):
        return Box(-np.full(2, 2.0), np.full(2, 2.0))

    def reset(self, key, params):
        target = jax.random.uniform(key, (1,), minval=-1.0, maxval=1.0)
        state = PointState(x=jnp.zeros(1), target=target, t=jnp.zeros((), jnp.int32))
        return jnp.concatenate([state.x, target]), state

    def step(self, key, state, action, params):
        a = jnp.clip(jnp.reshape(action, (1,)), -1.0, 1.0)
        x = jnp.clip(state.x + params.gain * a, -2.0, 2.0)
        state = PointState(x=x, target=state.target, t=state.t + 1)
        reward = jnp.exp(-4.0 * jnp.abs(x - state.target)[0])
        done = state.t >= self.episode_length
        info = {"distance": jnp.abs(x - state.target)[0], "valid": jnp.ones((), bool),
                "truncated": jnp.zeros((), bool)}
        return jnp.concatenate([x, state.target]), state, reward, done, info


register("point_reach", PointReach)  # the one line a task adds


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("point_reach")
    assert train.main(["task=point_reach", f"out={out}", "progress=false", "eval_targets=64"]) == 0
    return out


def test_registered_and_made():
    assert "point_reach" in registered()
    assert isinstance(make("point_reach"), PointReach)


def test_train_writes_a_run_and_its_evaluation(run_dir):
    config = json.loads((run_dir / "config.json").read_text())
    assert config["task"] == "point_reach" and config["num_envs"] == 16  # the task's ppo_defaults
    result = json.loads((run_dir / "eval.json").read_text())
    assert result["task"] == "point_reach" and result["n_episodes"] == 64
    assert result["valid_fraction"] == 1.0
    # the return is a sum of three rewards in (0, 1]: the default evaluation adds them up
    assert 0.0 < result["mean_return"] <= 3.0
    with open(run_dir / "eval_episodes.csv", newline="") as f:
        returns = [float(r["return"]) for r in csv.DictReader(f)]
    assert len(returns) == 64 and np.isclose(np.mean(returns), result["mean_return"])
    assert (run_dir / "learning_curve.png").stat().st_size > 0


def test_evaluate_accepts_the_run_folder(run_dir, tmp_path):
    assert evaluate.main([f"checkpoint={run_dir}", "n_targets=32", "seed=5", f"out={tmp_path}"]) == 0
    result = json.loads((tmp_path / "eval.json").read_text())
    assert result["task"] == "point_reach" and result["n_episodes"] == 32 and result["seed"] == 5
    assert evaluate.main([f"checkpoint={run_dir}", "task=basketball"]) == 2  # not this run's task


def test_gymnasium_env_passes_check_env():
    ids = gg.register_all()
    assert "gvsjax/PointReach-v0" in ids
    env = gym.make("gvsjax/PointReach-v0")
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    total = 0.0
    for _ in range(3):
        obs, reward, terminated, truncated, _ = env.step(np.zeros(1, np.float32))
        total += reward
    assert terminated and not truncated and 0 < total <= 3
    vec = gym.make_vec("gvsjax/PointReach-v0", num_envs=4)
    obs, _ = vec.reset(seed=0)
    obs, reward, terminated, truncated, info = vec.step(np.zeros((4, 1), np.float32))
    assert obs.shape == (4, 2) and reward.shape == (4,)


def test_animate_names_a_task_without_animation(capsys):
    assert animate.main(["task=point_reach"]) == 2
    assert "has no animation" in capsys.readouterr().err
