"""Checkpoints (gvsjax.ppo.checkpoint): atomic writes, a run folder or a file as the path,
damaged or missing files named in a ``CheckpointError`` before anything compiles, states of
another shape refused, stale temporary files removed, and ``load_policy``/``make_policy`` (the
network alone restored)."""

import gvsjax  # noqa: F401, I001  (first: it configures JAX)
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from bandit_env import BanditEnv
from helpers import raises_naming
from hypothesis import given, settings
from hypothesis import strategies as st

from gvsjax.ppo import PPOConfig, init, policy_action
from gvsjax.ppo import checkpoint as ckpt
from gvsjax.ppo.networks import make_network
from gvsjax.tasks import base


@pytest.fixture(scope="module")
def good_checkpoint(tmp_path_factory):
    path = tmp_path_factory.mktemp("ckpt") / ckpt.FILE_NAME
    state = {"w": jnp.arange(6.0).reshape(2, 3), "n": jnp.asarray(7, jnp.int32)}
    ckpt.save(path, state, {"num_envs": 4}, "basketball", 7)
    return path, path.read_bytes(), state


def test_save_writes_atomically_and_load_raw_reads_it_back(good_checkpoint):
    path, _, _ = good_checkpoint
    meta = ckpt.load_raw(path)
    assert (meta["step"], meta["task"], meta["config"], meta["extra"]) == (7, "basketball", {"num_envs": 4}, {})
    assert not list(path.parent.glob("*.tmp"))  # the temporary file was renamed over the target


def test_run_folder_or_file(good_checkpoint, tmp_path):
    path, _, _ = good_checkpoint
    assert ckpt.resolve(path.parent) == path and ckpt.resolve(path) == path
    assert ckpt.load_raw(path.parent)["step"] == 7  # a folder holding checkpoint.ckpt loads it
    raises_naming("does not exist", ckpt.load_raw, tmp_path / "nope.ckpt", exc=ckpt.CheckpointError)
    message = raises_naming(str(tmp_path), ckpt.load_raw, tmp_path, exc=ckpt.CheckpointError)
    assert "is a folder without checkpoint.ckpt" in message


@settings(max_examples=50, deadline=None)
@given(data=st.data())
def test_truncated_or_flipped_bytes_are_detected(good_checkpoint, tmp_path_factory, data):
    path, blob, _ = good_checkpoint
    truncate = data.draw(st.booleans(), label="truncate")
    if truncate:
        cut = data.draw(st.integers(0, len(blob) - 1), label="length")
        bad = blob[:cut]
    else:
        at = data.draw(st.integers(0, len(blob) - 1), label="position")
        flip = data.draw(st.integers(1, 255), label="xor")
        bad = blob[:at] + bytes([blob[at] ^ flip]) + blob[at + 1:]
    target = tmp_path_factory.mktemp("bad") / ckpt.FILE_NAME
    target.write_bytes(bad)
    message = raises_naming(str(target), ckpt.load_raw, target, exc=ckpt.CheckpointError)
    assert ("truncated" if truncate else "corrupted") in message


def test_checkpoint_of_another_shape_is_refused(good_checkpoint):
    path, _, state = good_checkpoint
    loaded, meta = ckpt.load(path, jax.tree.map(jnp.zeros_like, state))
    assert meta["step"] == 7 and np.array_equal(loaded["w"], state["w"]) and loaded["n"].dtype == jnp.int32
    raises_naming("shape", ckpt.load, path, {"w": jnp.zeros((3, 3)), "n": jnp.zeros((), jnp.int32)},
                  exc=ckpt.CheckpointError)
    raises_naming("does not match", ckpt.load, path, {"v": jnp.zeros(2)}, exc=ckpt.CheckpointError)


def test_stale_temporary_files_are_removed(tmp_path):
    path = tmp_path / ckpt.FILE_NAME
    stale = [tmp_path / f".{ckpt.FILE_NAME}.{i}.tmp" for i in range(2)]
    for p in stale:
        p.write_bytes(b"half a write")
    (tmp_path / "other.tmp").write_bytes(b"not ours")
    assert ckpt.remove_stale_temps(path) == sorted(stale)
    assert [p.name for p in tmp_path.iterdir()] == ["other.tmp"]


def test_load_policy_restores_the_trained_network(tmp_path, monkeypatch):
    monkeypatch.setitem(base._REGISTRY, "bandit", BanditEnv)
    env = BanditEnv()
    config = PPOConfig(num_envs=4, num_steps=1, num_minibatches=1, shared_hidden=(8,), seed=3)
    state = init(config, env, env.default_params(), jax.random.PRNGKey(3))
    state = state.replace(params=jax.tree.map(lambda x: x + 0.25, state.params))  # not a fresh init
    ckpt.save(tmp_path / ckpt.FILE_NAME, state, {"task": "bandit", "sim_dtype": "float64",
                                                 **dataclasses.asdict(config)}, "bandit", 5)
    loaded_config, loaded_env, env_params, params = ckpt.load_policy(tmp_path)
    assert loaded_config == config and isinstance(loaded_env, BanditEnv)
    jax.tree.map(np.testing.assert_array_equal, params, state.params)
    obs = jnp.asarray(np.random.default_rng(0).uniform(-1, 1, (5, 2)))
    actions = ckpt.make_policy(config, env.action_size, params)(obs)
    assert actions.shape == (5, 2) and actions.dtype == jnp.float64 and float(jnp.max(jnp.abs(actions))) <= 1.0
    expected = policy_action(state.params, make_network(config, 2).apply, obs.astype(jnp.float32))
    np.testing.assert_array_equal(actions, np.asarray(expected, np.float64))
    # a checkpoint whose env state has another structure (the env gained a state field since):
    # the policy still loads, resuming is refused
    ckpt.save(tmp_path / ckpt.FILE_NAME, state.replace(env_state={"older": jnp.zeros(4)}),
              {"task": "bandit", "sim_dtype": "float64", **dataclasses.asdict(config)}, "bandit", 5)
    jax.tree.map(np.testing.assert_array_equal, ckpt.load_policy(tmp_path)[3], state.params)
    raises_naming("does not match", ckpt.load, tmp_path, state, exc=ckpt.CheckpointError)
