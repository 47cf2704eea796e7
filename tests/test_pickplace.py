"""The pick-and-place task (gvsjax.tasks.pickplace): profiles, mappings, observation, reward,
step chaining, non-finite actions and blown-up states, reachable targets, and the episode figure.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import capture_figures, finite_line, no_compile
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

import gvsjax  # noqa: F401  (sets the XLA flag and x64 before JAX starts)
from gvsjax.tasks import make
from gvsjax.tasks import pickplace as pp
from gvsjax.tasks.pickplace.env import QD_BOUND, _reset_state

TENDON_ARM = gvsjax.paper_arm(tendon_offset=0.025)


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


@settings(max_examples=30, deadline=None)
@given(shape=st.lists(st.integers(0, 3), max_size=3).map(tuple).filter(lambda s: s != (2,)))
def test_action_of_wrong_shape_is_rejected_while_tracing(shape):
    env = pp.PickPlace()
    params = pp.PickPlaceParams(arm=TENDON_ARM)  # no target tables: step does not read them
    state = _reset_state(jnp.asarray([[0.5, -0.8], [-0.5, -0.8]]))
    step = lambda a: env.step(jax.random.PRNGKey(0), state, a, params)  # noqa: E731
    with no_compile(), pytest.raises(ValueError, match=r"action has shape .* expected \(2,\)"):
        jax.eval_shape(step, jax.ShapeDtypeStruct(shape, jnp.float64))


def test_non_finite_action_is_replaced_by_the_centre_and_flagged(env_and_params, batched_step):
    _, P = env_and_params
    n = P.pick.shape[0]  # the batch size of the other tests: the compiled step is reused
    actions = jnp.array([[math.nan, 0.5], [0.2, math.inf], [-math.inf, math.nan], [0.3, -0.4],
                         [0.0, 0.0], [-0.5, 0.9]])
    assert actions.shape[0] == n
    _, state = jax.vmap(pp.PickPlace().reset_to, in_axes=(0, None))(jnp.stack([P.pick, P.place], 1), P)
    obs, state, reward, done, info = batched_step(jax.random.split(jax.random.PRNGKey(0), n), state, actions, P)
    assert info["valid"].tolist() == [False, False, False, True, True, True]
    assert done[:3].all() and np.array_equal(reward[:3], [0.0, 0.0, 0.0]) and np.all(reward[3:] > 0)
    # the simulated action was the centre of the box: theta_F = 0, tension = 15 N
    np.testing.assert_array_equal(info["theta_final"][:3], 0.0)
    np.testing.assert_array_equal(info["tension"][:3], P.tension_max / 2)
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(state.q))


@pytest.mark.extended
def test_blow_up_is_flagged_even_while_finite():
    # 300 RK4 steps per 5 s step: dt = 16.7 ms, above the 13.9 ms stability limit; the
    # integration grows without reaching inf, so only the magnitude bound can catch it
    params = pp.PickPlaceParams(arm=TENDON_ARM, n_steps=300, integrator="rk4")
    action = jnp.array([[1.0 / math.pi, -1.0 / 3.0]])  # theta_F = 1 rad, 10 N

    @jax.jit
    def run(state, action):
        out = jax.vmap(lambda a: pp.PickPlace().step(jax.random.PRNGKey(0), state, a, params))(action)
        theta, tension = pp.action_to_physical(action[0], params)
        return out, pp.run_step(params, state.q, state.qd, state.tension, theta, tension)

    (_, _, reward, done, info), traj = run(_reset_state(jnp.asarray([[0.5, -0.8], [-0.5, -0.8]])), action)
    q, qd = np.asarray(traj.q[-1]), np.asarray(traj.qd[-1])
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(qd))
    assert np.max(np.abs(qd)) > QD_BOUND  # blown up (a sane step stays below 3)
    assert not bool(info["valid"][0]) and bool(done[0]) and float(reward[0]) == 0.0


def test_episode_figure_and_gif_draw_the_episode_the_env_plays(env_and_params, tmp_path, monkeypatch):
    """Fig. 6 of a table row: finite arm shapes from the joint, both tip paths ending on the row's
    targets (the drawing's 500 RK4 steps end within 0.2 mm of the env's), finite controls; and the
    task's GIF (``animate``, the same drawn episode: one compiled program for both)."""
    env, P = env_and_params
    captured = capture_figures(monkeypatch)
    actions = np.stack([P.pick_action[0], P.place_action[0]])
    targets = np.stack([P.pick[0], P.place[0]])
    pp.figures.episode_figure(pp.PickPlaceParams(arm=TENDON_ARM), actions, targets, tmp_path / "fig6.png")
    lines = captured["fig6.png"]
    for k in range(2):  # the two shape panels
        panel = [ln for ln in lines if ln["axes"] == k]
        arms = [ln for ln in panel if ln["label"].startswith("_") and ln["x"].size > 2]
        assert len(arms) >= 10  # a shape every 0.5 s of the 5 s step
        for a in arms:
            assert np.all(np.isfinite(a["x"])) and np.all(np.isfinite(a["y"]))
            assert abs(a["x"][0]) < 1e-12 and abs(a["y"][0]) < 1e-12  # from the joint
        tip = finite_line(panel, "tip path", min_points=100)
        assert np.hypot(tip["x"][-1] - targets[k, 0], tip["y"][-1] - targets[k, 1]) < 1e-3
        finite_line(panel, "target", min_points=1)
    theta, pull = (np.asarray(x) for x in pp.action_to_physical(jnp.asarray(actions), P))
    angle = [ln for ln in lines if ln["axes"] == 2 and ln["x"].size > 2]  # not the step's boundary
    tension = [ln for ln in lines if ln["axes"] == 3]
    assert len(angle) == len(tension) == 1
    for curve in angle + tension:
        assert curve["x"].size > 100 and np.all(np.isfinite(curve["x"])) and np.all(np.isfinite(curve["y"]))
    assert abs(angle[0]["y"][-1] - np.degrees(theta[1])) < 1e-6  # at rest on the commanded angle
    np.testing.assert_allclose(tension[0]["y"][[0, -1]], [0.0, pull[1]], atol=1e-9)  # ramps 0 N -> T2

    # 500 drawing steps per 5 s step, saved every 5th: 201 states over both steps, a frame every 5th (0.25 s)
    gif = env.animate(tmp_path / "pp.gif", action=",".join(str(a) for a in actions.ravel()), dpi=30)
    with Image.open(gif) as im:
        assert im.format == "GIF" and im.n_frames == 41
