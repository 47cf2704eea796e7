"""The pick-and-place task: profiles, mappings, step chaining, reachable targets.

Two compilations in all (the target tables' episode and the batched env step),
so the module runs in well under a minute.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import gvsjax  # noqa: F401  (sets the XLA flag and x64 before JAX starts)
from gvsjax.tasks import make
from gvsjax.tasks import pickplace as pp


@pytest.fixture(scope="module")
def env_and_params():
    env = make("pickplace")
    return env, pp.make_params(n_pairs=6, n_test=2, seed=3)


@pytest.fixture(scope="module")
def batched_step(env_and_params):
    env, _ = env_and_params
    return jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))


def test_cycloid_profile_ends_at_rest():
    s = pp.cycloid
    ds = jax.grad(s)
    dds = jax.grad(ds)
    for u in (0.0, 1.0):
        assert abs(float(ds(u))) < 1e-12 and abs(float(dds(u))) < 1e-12
    assert float(s(0.0)) == 0.0 and abs(float(s(1.0)) - 1.0) < 1e-15
    # sinusoidal velocity: peak at mid-step, 2 x the mean rate
    angle, pull = pp.controls(0.3, -1.2, 5.0, 20.0, 5.0)
    rate = jax.grad(angle)
    assert abs(float(angle(5.0)) + 1.2) < 1e-12 and abs(float(rate(5.0))) < 1e-12
    assert abs(float(rate(2.5)) - 2 * (-1.5) / 5.0) < 1e-12
    assert abs(float(pull(0.0)) - 5.0) < 1e-12 and abs(float(pull(5.0)) - 20.0) < 1e-12


def test_action_mapping_hand_values(env_and_params):
    _, P = env_and_params
    a = jnp.array([[-1.0, -1.0], [1.0, 1.0], [0.0, 0.0], [0.5, -0.5], [3.0, -7.0]])
    theta, T = pp.action_to_physical(a, P)
    np.testing.assert_allclose(theta, [-math.pi, math.pi, 0.0, math.pi / 2, math.pi], atol=1e-15)
    np.testing.assert_allclose(T, [0.0, 30.0, 15.0, 7.5, 0.0], atol=1e-12)
    back = pp.physical_to_action(theta, T, P)
    np.testing.assert_allclose(back, np.clip(a, -1, 1), atol=1e-12)


def test_observation_hand_values(env_and_params):
    _, P = env_and_params
    band = P.radius_range
    assert 0.98 < band[0] < band[1] <= 1.0 + 1e-9  # the reachable band hugs the 1 m circle
    P = P.replace(radius_range=(0.0, math.inf))  # no clipping for the hand values
    state = pp.PickPlaceState(q=jnp.array([math.pi / 2, 0.75, -1.5]), qd=jnp.array([0.0, 0.2, -0.4]),
                              tension=jnp.array(10.0), step=jnp.array(1, jnp.int32),
                              targets=jnp.array([[0.9, -0.4], [-0.7, -0.7]]))
    obs = pp.observe(state, P)
    s, v = P.q_scale, P.qd_scale
    # polar target: angle from hanging / pi, (radius - 0.99 m) / 1 cm
    expect = [0.5, 0.75 / s, -1.5 / s, 0.0, 0.2 / v, -0.4 / v,
              -0.25, (0.7 * math.sqrt(2) - 0.99) / 0.01, 1.0]
    np.testing.assert_allclose(obs, expect, atol=1e-12)
    assert obs.shape == (9,)
    obs0 = pp.observe(state.replace(step=jnp.array(0, jnp.int32)), P)
    np.testing.assert_allclose(obs0[6:], [math.atan2(0.9, 0.4) / math.pi,
                                          (math.hypot(0.9, 0.4) - 0.99) / 0.01, 0.0], atol=1e-12)
    upright = pp.target_features(jnp.array([[1e-9, 1.0], [-1e-9, 1.0], [1.0, 0.0]]), P)
    np.testing.assert_allclose(upright[:, 0], [1.0, -1.0, 0.5], atol=1e-8)  # the seam at +-pi
    # off-band radii are clipped onto the band
    clipped = pp.target_features(jnp.array([[0.0, -0.5], [0.0, -1.5]]), P.replace(radius_range=(0.985, 1.0)))
    np.testing.assert_allclose(clipped[:, 1], [-0.5, 1.0], atol=1e-12)
    cart = pp.observe(state, P.replace(target_obs="cartesian"))
    np.testing.assert_allclose(cart[6:8], [-0.7, -0.7], atol=1e-12)


def test_reward_hand_values(env_and_params):
    _, P = env_and_params
    assert abs(float(pp.reward_of(0.05, P)) - 0.8) < 1e-3  # the paper's calibration
    assert float(pp.reward_of(0.0, P)) == 1.0
    assert abs(float(pp.reward_of(0.2, P)) - math.exp(-4.46 * 0.2)) < 1e-12


def test_stored_actions_reach_targets_and_steps_chain(env_and_params, batched_step):
    """Re-simulate the table rows with the env: each step ends on its target; step 2
    starts where step 1 ended; the joint ends at the commanded angle at rest."""
    env, P = env_and_params
    n = P.pick.shape[0]
    keys = jax.random.split(jax.random.PRNGKey(0), n)
    obs, state = jax.vmap(env.reset_to, in_axes=(0, None))(jnp.stack([P.pick, P.place], 1), P)
    obs1, s1, r1, done1, info1 = batched_step(keys, state, P.pick_action, P)
    assert not np.any(done1) and np.all(info1["valid"])
    np.testing.assert_array_less(info1["distance"], 1e-9)
    np.testing.assert_allclose(r1, 1.0, atol=1e-8)
    theta1, T1 = pp.action_to_physical(P.pick_action, P)
    np.testing.assert_allclose(s1.q[:, 0], theta1, atol=1e-12)  # commanded angle reached
    np.testing.assert_allclose(s1.qd[:, 0], 0.0, atol=1e-12)  # with zero joint velocity
    np.testing.assert_allclose(s1.tension, T1, atol=1e-12)
    np.testing.assert_allclose(obs1[:, 8], 1.0)
    np.testing.assert_allclose(obs1[:, 6:8], pp.target_features(P.place, P), atol=1e-12)

    # step 2 from step 1's end state: the table's place tips (simulated by ``episode``
    # from rest through both steps) are reached exactly
    obs2, s2, r2, done2, info2 = batched_step(keys, s1, P.place_action, P)
    assert np.all(done2) and np.all(info2["valid"])
    np.testing.assert_array_less(info2["distance"], 1e-9)
    # and a different start state changes step 2's outcome (the state is really carried)
    moved = s1.replace(q=s1.q.at[:, 1].add(0.5), qd=s1.qd.at[:, 1].add(3.0))
    _, _, _, _, info_m = batched_step(keys, moved, P.place_action, P)
    assert np.all(np.asarray(info_m["distance"]) > 1e-6)

    # a diverged state: invalid, done, reward 0, finite observation
    bad = s1.replace(q=s1.q.at[0, 1].set(jnp.nan))
    obs_b, s_b, r_b, done_b, info_b = batched_step(keys, bad, P.place_action, P)
    assert not bool(info_b["valid"][0]) and bool(done_b[0]) and float(r_b[0]) == 0.0
    assert np.all(np.isfinite(obs_b[0])) and np.all(info_b["valid"][1:])
    assert not np.any(info_b["truncated"])


def test_reset_draws_table_rows_of_its_split(env_and_params):
    env, P = env_and_params
    keys = jax.random.split(jax.random.PRNGKey(1), 64)
    for split, (lo, hi) in (("train", (0, 4)), ("test", (4, 6))):
        Ps = P.replace(split=split)
        assert pp.row_range(Ps) == (lo, hi)
        obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, Ps)
        rows = {int(np.argmin(np.abs(np.asarray(P.pick) - t).sum(1))) for t in np.asarray(state.targets[:, 0])}
        assert rows <= set(range(lo, hi))
        np.testing.assert_allclose(obs[:, :6], 0.0)
        np.testing.assert_allclose(obs[:, 8], 0.0)


def test_reset_without_target_tables_says_how_to_build_them():
    env = make("pickplace")
    bare = pp.PickPlaceParams(arm=gvsjax.paper_arm(tendon_offset=0.025))  # step works, reset needs tables
    with pytest.raises(ValueError, match="no target tables.*make_params"):
        env.reset(jax.random.PRNGKey(0), bare)
