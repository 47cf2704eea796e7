"""The task base (gvsjax.tasks.base): the non-finite action policy (``sanitize_action``,
``bounded``), the registry's checks (``make``, lazy ``"module:attr"`` entries) and the
``Environment`` defaults a task inherits (spaces, training variants, simulator dtype)."""

import gvsjax  # noqa: F401, I001  (first: it configures JAX)
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from bandit_env import BanditEnv

from gvsjax.tasks import base, make, register, registered


def test_sanitize_action_policy():
    a, ok = base.sanitize_action(jnp.array([0.3, -0.2]), 2)
    assert bool(ok) and np.array_equal(a, [0.3, -0.2])
    for bad in ([math.nan, 0.5], [0.1, math.inf], [-math.inf, math.nan]):
        a, ok = base.sanitize_action(jnp.array(bad), 2)
        assert not bool(ok) and np.array_equal(a, [0.0, 0.0])
    a, ok = base.sanitize_action(jnp.array([1, -1]), 2)  # ints are cast, not rejected
    assert bool(ok) and jnp.issubdtype(a.dtype, jnp.floating)
    with pytest.raises(ValueError, match=r"action has shape \(3,\).*expected \(2,\)"):
        base.sanitize_action(jnp.zeros(3), 2)
    assert bool(base.bounded(jnp.array([1.0, -2.0]), 2.0))
    for x in ([2.5, 0.0], [math.nan, 0.0], [math.inf, 0.0]):
        assert not bool(base.bounded(jnp.array(x), 2.0))


def test_registry_makes_environments_only(monkeypatch):
    monkeypatch.setattr(base, "_REGISTRY", dict(base._REGISTRY))  # registrations undone after the test
    register("not_an_env", dict)
    with pytest.raises(TypeError, match="not_an_env.*not an Environment"):
        make("not_an_env")
    register("lazy_bandit", "bandit_env:BanditEnv")  # imported on first use
    assert base._REGISTRY["lazy_bandit"] == "bandit_env:BanditEnv"
    assert "lazy_bandit" in registered() and isinstance(make("lazy_bandit"), BanditEnv)
    with pytest.raises(ValueError, match=r"task='chess' is unknown; choose one of \[.*'basketball'"):
        make("chess")


def test_environment_defaults():
    env = BanditEnv()
    assert env.action_space().shape == (2,) and np.array_equal(env.action_space().high, [1.0, 1.0])
    assert env.observation_space().shape == (2,) and np.all(np.isinf(env.observation_space().low))
    jax.tree.map(np.testing.assert_array_equal, env.train_params(), env.default_params())
    with pytest.raises(ValueError, match="train_targets='mixed' is invalid for task='bandit'.*single training"):
        env.train_params("mixed")
    params = env.default_params()
    assert env.with_sim_dtype(params, "float64") is params
    with pytest.raises(ValueError, match="sim_dtype='float32' is invalid for task='bandit'"):
        env.with_sim_dtype(params, "float32")
    with pytest.raises(ValueError, match="task='bandit' has no animation"):
        env.animate("never.gif")
    assert env.render(params, None, None) is None and env.ppo_defaults == {} and env.train_variants == ()


def test_draw_index_follows_the_weights():
    """Frequencies of 200k inverse-CDF draws (jit of vmap) match the weights, zero weights included."""
    weight = np.array([0.0, 1.0, 3.0, 0.0, 6.0, 0.5])
    cdf = jnp.asarray(np.cumsum(weight))  # unnormalised: the last entry is the total
    keys = jax.random.split(jax.random.PRNGKey(0), 200_000)
    index = np.asarray(jax.jit(jax.vmap(base.draw_index, in_axes=(0, None)))(keys, cdf))
    counts = np.bincount(index, minlength=len(weight))
    expected = weight / weight.sum() * len(keys)
    assert counts[weight == 0].sum() == 0
    # within 5 binomial standard deviations of the expected counts
    np.testing.assert_array_less(np.abs(counts - expected), 5 * np.sqrt(expected + 1))
