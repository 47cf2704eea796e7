"""Scale-out (gvsjax.utils.sharding): a run on 2 virtual CPU devices equals the single-device run.

The 2-device run is this file executed as a script in a subprocess with
``XLA_FLAGS=--xla_force_host_platform_device_count=2`` (the device count is
fixed when JAX starts); the single-device run is the same workload in the
test process. Also: a learning-rate/seed sweep entry equals the lone run.
"""

import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import gvsjax  # noqa: F401  (before JAX starts)

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bandit_env import BanditEnv  # noqa: E402

from gvsjax.ppo import PPOConfig, make_train  # noqa: E402
from gvsjax.utils.sharding import batched  # noqa: E402

CONFIG = PPOConfig(num_envs=16, num_steps=2, num_minibatches=2, update_epochs=2,
                   learning_rate=3e-3, shared_hidden=(16,), total_episodes=16 * 2 * 3,
                   finetune_fraction=0.0)


def _release_tip(T, delta):
    arm = gvsjax.paper_arm(tip_force=5.886)
    law = lambda t: 3.665 * (t / T) ** 2  # noqa: E731
    return gvsjax.simulate(arm, delta * T, n_steps=200, save_every=200, base_angle=law,
                           check_stability=False).tip[-1]


def _devices(x) -> int:
    return len(x.sharding.device_set)


def workload() -> dict[str, np.ndarray]:
    """A short PPO training and a batched simulation; how their arrays were placed."""
    env = BanditEnv()
    state, metrics = make_train(CONFIG, env, env.default_params())(jax.random.PRNGKey(0))
    params = jnp.concatenate([jnp.ravel(x) for x in jax.tree.leaves(state.params)])
    # 6 throws: split 3 + 3 over 2 devices; 5 throws: padded to 6, cut back to 5
    T6, d6 = jnp.linspace(0.6, 2.5, 6), jnp.linspace(0.86, 0.99, 6)
    tips6 = batched(_release_tip)(T6, d6)
    tips5 = batched(_release_tip)(T6[:5], d6[:5])
    return {"params": np.asarray(params), "reward": np.asarray(metrics["episode_reward"]),
            "tips6": np.asarray(tips6), "tips5": np.asarray(tips5),
            "devices": np.array([len(jax.devices()), _devices(state.last_obs),
                                 _devices(state.env_state.target), _devices(tips6)]),
            "shard_rows": np.array([s.data.shape[0] for s in state.last_obs.addressable_shards])}


@pytest.mark.slow
@pytest.mark.extended
def test_two_devices_equal_one_device(tmp_path):
    out = tmp_path / "two.npz"
    env = dict(os.environ)
    env["XLA_FLAGS"] = (env.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=2").strip()
    env.pop("GVSJAX_SHARDING", None)
    subprocess.run([sys.executable, __file__, str(out)], env=env, check=True, timeout=600)
    two = dict(np.load(out))
    one = workload()

    # really split: 2 devices, the 16 envs as 8 + 8, the 6 throws over both devices
    np.testing.assert_array_equal(two["devices"], [2, 2, 2, 2])
    np.testing.assert_array_equal(two["shard_rows"], [8, 8])
    np.testing.assert_array_equal(one["devices"], [1, 1, 1, 1])
    # the physics is row by row, but XLA compiles the partitioned program separately and
    # may round a few float64 operations differently: measured <= 2 ulp (4e-16 m)
    np.testing.assert_allclose(two["tips6"], one["tips6"], rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(two["tips5"], one["tips5"], rtol=1e-13, atol=1e-14)
    np.testing.assert_array_equal(two["tips5"], two["tips6"][:5])  # padding is cut back
    # float32 PPO: the network's matmuls on 8 rows per device and the cross-device sums
    # (advantage statistics, metrics) round differently in the last bit, ~1e-7
    np.testing.assert_allclose(two["params"], one["params"], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(two["reward"], one["reward"], rtol=1e-5, atol=1e-6)
    assert np.isfinite(one["params"]).all() and not np.array_equal(one["params"], 0 * one["params"])


def test_learning_rate_sweep_entry_equals_lone_run():
    env = BanditEnv()
    train = make_train(CONFIG, env, env.default_params())
    keys = jax.random.split(jax.random.PRNGKey(1), 2)
    rates = jnp.array([1e-3, 1e-2])
    sweep_state, sweep_metrics = jax.jit(jax.vmap(train))(keys, rates)
    lone_config = CONFIG.replace(learning_rate=1e-2)
    lone_state, lone_metrics = make_train(lone_config, env, env.default_params())(keys[1])
    for s, lone in zip(jax.tree.leaves(sweep_state.params), jax.tree.leaves(lone_state.params)):
        # vmapped matmuls may round differently from the unbatched ones in float32
        np.testing.assert_allclose(s[1], lone, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(sweep_metrics["learning_rate"][1], lone_metrics["learning_rate"])
    np.testing.assert_allclose(sweep_metrics["learning_rate"][0], 1e-3)  # each entry its own rate


if __name__ == "__main__":
    np.savez(sys.argv[1], **workload())
