"""reach_obstacles: the layout against its geometry and the statics, the env's contact dynamics
against Newton's statics with the same obstacles, the scene's symmetry, the env under jit/vmap,
bad input, the evaluation's statistics and figures."""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import capture_figures, finite_line

import gvsjax as gv
from gvsjax.tasks import arm3d, make
from gvsjax.tasks import reach_obstacles as ro
from gvsjax.tasks.reach_obstacles.env import final_summary
from gvsjax.tasks.reach_obstacles.layouts import turn


@pytest.fixture(scope="module")
def env():
    return make("reach_obstacles")


@pytest.fixture(scope="module")
def params(env):
    return env.default_params()


@pytest.fixture(scope="module")
def batched(env):
    """reset and step under jit(vmap), made once: the tests below that run a batch of 3 share
    the traced and compiled programs (the params are traced)."""
    return jax.jit(jax.vmap(env.reset, (0, None))), jax.jit(jax.vmap(env.step, (0, 0, 0, None)))


def _segment_distance(P, a, b):
    e = b - a
    t = np.clip((P - a) @ e / (e @ e), 0.0, 1.0)
    return np.linalg.norm(P - (a + t[:, None] * e), axis=-1)


def test_the_cage_is_an_open_cube_around_the_target_that_the_reference_equilibrium_enters():
    """Eleven cube edges of length 2 h (the near face's top edge missing) and a bar of the same
    length under the centre; the rest arm stands clear; the statics of the reference action (no
    contact) put the tip within 3.1 cm of the target with the whole arm >= 10 cm clear of every bar."""
    lay = ro.cage()
    c, h = np.array(ro.layouts.CAGE_TARGET), ro.layouts.CAGE_HALF
    np.testing.assert_allclose(np.linalg.norm(lay["end"] - lay["start"], axis=1), 2 * h, rtol=1e-12)
    mids = np.round((lay["start"] + lay["end"]) / 2 - c, 12)
    edges = {(sx * h, 0.0, sz * h) for sx in (-1, 1) for sz in (-1, 1)} | {
        (0.0, sy * h, sz * h) for sy in (-1, 1) for sz in (-1, 1)} | {(sx * h, sy * h, 0.0) for sx in (-1, 1)
                                                                      for sy in (-1, 1)}
    assert {tuple(m) for m in mids} == (edges - {(-h, 0.0, h)}) | {(0.0, 0.0, -h)}
    arm = arm3d.ArmParams()
    eq = gv.equilibrium(arm.robot, tendon_force=arm3d.tensions(jnp.asarray(ro.ReachObstacles.reference_action), arm),
                        load_scale_steps=4)
    assert bool(eq.converged)
    for q, label in ((np.zeros(arm.robot.n_dofs), "rest"), (np.asarray(eq.q), "reference")):
        pts = np.asarray(gv.backbone(arm.robot, jnp.asarray(q)))
        clear = min(_segment_distance(pts, a, b).min() - r for a, b, r in zip(lay["start"], lay["end"], lay["radius"]))
        assert clear - arm.robot.links[0].radius > 0.1, (label, clear)
    assert np.linalg.norm(pts[-1] - c) < 0.031


def test_turn_is_a_rotation_about_the_vertical():
    x = jnp.array([[0.8, 0.0, 0.35], [0.1, -0.2, 0.3]])
    np.testing.assert_allclose(np.asarray(turn(x, math.pi / 2)), [[0.0, 0.8, 0.35], [0.2, 0.1, 0.3]], atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(np.asarray(turn(x, 0.7)), axis=1), np.linalg.norm(x, axis=1), rtol=1e-14)


def _held_episode(env, batched, params, n_steps, action=None, ramp_steps=0):
    """Three episodes under ``action`` (default: the reference action) raised linearly over
    ``ramp_steps`` then held: the fixed scene, the scene turned by 90 deg, and the fixed scene with
    a NaN first action, all as tendon actions (``absolute``). Returns the last (obs, state, reward,
    info) and the first step's info and reward."""
    params = ro.absolute(params)
    keys = jax.random.split(jax.random.PRNGKey(0), 3)
    reset, step = batched
    _, state = reset(keys, params)
    yaw = jnp.array([0.0, math.pi / 2, 0.0])
    state = dataclasses.replace(state, yaw=yaw, target=turn(jnp.asarray(params.target)[None].repeat(3, 0), yaw))
    policy = ro.held_policy(env, action)
    first = None
    for t in range(n_steps):
        a = policy(jax.vmap(ro.env.observe, in_axes=(0, None))(state, params)) * min(1.0, (t + 1) / (ramp_steps + 1))
        obs, state, reward, done, info = step(keys, state, a.at[2].set(jnp.nan) if t == 0 else a, params)
        first = first or (info, reward)
    return obs, state, reward, info, first


@pytest.mark.slow
def test_the_scene_turns_symmetrically_under_jit_and_vmap_and_the_reward_is_as_documented(env, batched, params):
    """The tendons sit at quarters, so a scene turned by 90 deg gives the same episode turned (the
    yaw, the turned layout and the turned held action all enter). Also: jit(vmap) of reset/step,
    the reward's formula while pressing a bar, a NaN action flagged while the batch runs on."""
    obs, state, reward, info, (info0, reward0) = _held_episode(env, batched, params, 6)
    assert np.asarray(info0["valid"]).tolist() == [True, True, False] and float(reward0[2]) == 0.0
    np.testing.assert_allclose(np.asarray(info["distance"][1]), np.asarray(info["distance"][0]), rtol=1e-7)
    np.testing.assert_allclose(np.asarray(info["depth"][1]), np.asarray(info["depth"][0]), rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(np.asarray(turn(state.tip[0], math.pi / 2)), np.asarray(state.tip[1]), atol=1e-7)
    assert float(state.deepest[0]) > 0.01  # applied at once, the action swings the arm into the bars
    np.testing.assert_allclose(float(state.deepest[1]), float(state.deepest[0]), rtol=1e-5)
    depth, d = float(info["depth"][0]), float(info["distance"][0])
    shaped = 0.5 * (np.exp(-params.k * d) + np.exp(-params.precision * params.k * d))
    np.testing.assert_allclose(float(reward[0]), shaped - params.penetration_weight * min(depth / params.tolerance, 2),
                               rtol=1e-10)
    assert obs.shape == (3, env.obs_size) and np.all(np.isfinite(np.asarray(obs)))


@pytest.mark.extended
def test_held_action_comes_to_rest_on_newtons_statics_with_the_same_obstacles(env, batched, params):
    """Raised slowly, the planar task's reference action lays the arm's end on the bar under the
    target. The env (16 ars443 steps per 0.1 s, the contact explicit) must come to rest where
    Newton's statics with the same obstacles (the contact forces in the residual) put it."""
    action = (0.7, 0.0, 1.0, 0.0)
    _, state, _, _, _ = _held_episode(env, batched, params, 60, action, ramp_steps=15)  # 1.5 s up, 6 s in all
    robot = ro.scene(params, 0.0).robot
    arm = dataclasses.replace(params.arm, robot=robot)
    eq = gv.equilibrium(robot, tendon_force=arm3d.tensions(jnp.asarray(action), arm), load_scale_steps=8)
    assert bool(eq.converged)
    tip_eq = np.asarray(gv.backbone(robot, eq.q))[-1]
    tip_dyn = np.asarray(gv.backbone(robot, state.q[0]))[-1]
    assert np.linalg.norm(tip_eq - tip_dyn) < 2e-3, (tip_eq, tip_dyn)
    assert float(jnp.min(ro.env.gaps(params, 0.0, eq.q, jnp.zeros_like(eq.q)))) < -1e-3  # resting on the bar


def test_bad_input_is_refused_before_compiling(env, params):
    key = jax.random.PRNGKey(0)
    with pytest.raises(ValueError, match="contact samples"):
        env.reset(key, dataclasses.replace(params, arm=arm3d.ArmParams(robot=ro.contact_arm().replace(
            contact=ro.contact_arm().contact.replace(n_points=21)))))
    with pytest.raises(ValueError, match="start, end and radius"):
        env.reset(key, dataclasses.replace(params, radius=jnp.ones(3)))
    with pytest.raises(ValueError, match="yaw_range"):
        env.reset(key, dataclasses.replace(params, yaw_range=-1.0))
    with pytest.raises(ValueError, match="actuation"):
        env.reset(key, dataclasses.replace(params, arm=dataclasses.replace(params.arm, actuation="muscle")))
    with pytest.raises(ValueError, match="tendon groups"):
        env.reset(key, dataclasses.replace(params, arm=arm3d.ArmParams(robot=ro.contact_arm(tendon_ends=(1.0,)))))
    _, state = env.reset(key, params)
    with pytest.raises(ValueError, match="shape"):
        env.step(key, state, jnp.zeros(3), params)


def test_final_summary_counts_divergence_and_deep_penetration_as_failures(params):
    out = {"distance": np.array([[0.5, 0.01], [0.5, 0.02], [0.5, 0.03], [0.5, 0.3]]),
           "depth": np.array([[0.0, 0.0], [0.02, 0.0], [0.0, 0.0], [0.0, 0.0]]),
           "valid": np.array([[True, True], [True, True], [True, False], [True, True]])}
    s = final_summary(out, params)
    assert s["success"] == 0.25 and s["reached"] == 0.5 and s["penetrated"] == 0.25
    assert s["distance_median_m"] == pytest.approx(0.16) and math.isinf(s["distance_p95_m"])


def test_figures_draw_the_medians_and_the_obstacles(params, monkeypatch, tmp_path):
    rng = np.random.default_rng(0)
    n, T = 5, 30
    out = lambda: {"distance": rng.uniform(0.01, 0.5, (n, T)), "depth": rng.uniform(0, 0.02, (n, T)),  # noqa: E731
                   "valid": np.ones((n, T), bool), "q": np.zeros((n, T + 1, 9)),
                   "target": np.tile(np.asarray(params.target), (n, 1)), "yaw": np.zeros(n)}
    pol, held, ramped = out(), out(), out()
    figs = capture_figures(monkeypatch)
    robots = [ro.scene(params, 0.0).robot] * 3
    paths = ro.figures.evaluation_figures(params, {"policy": pol, "held_action": held, "ramped_action": ramped,
                                                   "dt": 0.1}, tmp_path, robots)
    assert [p.name for p in paths] == ["reach_obstacles_over_time.png", "reach_obstacles_final.png"]
    lines = figs["reach_obstacles_over_time.png"]
    line = finite_line([ln for ln in lines if ln["axes"] == 0], "policy, median", min_points=T)
    np.testing.assert_allclose(line["y"], 100 * np.median(pol["distance"], 0))
    line = finite_line([ln for ln in lines if ln["axes"] == 1], "reference action, held, median", min_points=T)
    np.testing.assert_allclose(line["y"], 1000 * np.median(held["depth"], 0))
    line = finite_line([ln for ln in lines if ln["axes"] == 0], "reference action, ramped, median", min_points=T)
    np.testing.assert_allclose(line["y"], 100 * np.median(ramped["distance"], 0))
    bars = [ln for ln in figs["reach_obstacles_final.png"] if ln["axes"] == 0 and ln["x"].size == 2]
    assert len(bars) >= 12  # the cage's bars (the arm's lines have more points)


def test_planar_variant_maps_two_actions_into_the_plane_and_keeps_its_plane():
    env2 = make("reach_obstacles_2d")
    p2 = env2.default_params()
    np.testing.assert_array_equal(np.asarray(env2.full_action(jnp.array([0.3, -0.7]))), [0.3, 0.0, -0.7, 0.0])
    for seed in range(3):
        obs, state = env2.reset(jax.random.PRNGKey(seed), p2)
        assert float(state.target[1]) == 0.0 and abs(float(state.target[0]) - 0.8) <= 0.03
        assert float(jnp.min(state.gap)) > 0.05  # the posts stand clear of the rest arm
    with pytest.raises(ValueError, match="yaw_range"):
        env2.reset(jax.random.PRNGKey(0), dataclasses.replace(p2, yaw_range=0.5))
    with pytest.raises(ValueError, match="target_jitter"):
        env2.reset(jax.random.PRNGKey(0), dataclasses.replace(p2, target_jitter=(0.1, -0.1, 0.0)))


@pytest.mark.extended
def test_planar_posts_let_a_slow_approach_through_and_stop_a_swing():
    """The posts' design claim: the reference action raised over 1.5 s reaches the nominal target
    without touching; applied at once, the swing presses > 1 cm into a post."""
    env2 = make("reach_obstacles_2d")
    p2 = ro.absolute(dataclasses.replace(env2.default_params(), target_jitter=(0.0, 0.0, 0.0)))
    slow, fast = (jax.jit(lambda k, s=s: ro.rollout(env2, p2, ro.held_policy(env2, ramp_s=s), k))(
        jax.random.PRNGKey(0)[None]) for s in (1.5, 0.0))
    assert float(slow["distance"][0, -1]) < 0.05 and float(slow["depth"][0].max()) == 0.0
    assert float(fast["depth"][0].max()) > 0.01


@pytest.mark.slow
def test_planar_variant_observes_its_last_action_and_charges_its_change():
    """The reward's action-rate term against its formula over two steps (from rest, then a change),
    the last action at the end of the observation, under jit."""
    env2 = make("reach_obstacles_2d")
    p2 = dataclasses.replace(ro.absolute(env2.default_params()), action_rate_weight=0.5)  # tendon actions
    key = jax.random.PRNGKey(1)
    obs, state = jax.jit(env2.reset)(key, p2)
    assert obs.shape == (env2.obs_size,) and np.asarray(obs[-2:]).tolist() == [0.0, 0.0]
    step = jax.jit(env2.step)
    before = jnp.zeros(2)
    for a in (jnp.array([0.3, -0.2]), jnp.array([0.1, 0.4])):
        obs, state, reward, _, info = step(key, state, a, p2)
        d = float(info["distance"])
        assert float(info["depth"]) == 0.0  # small actions from rest: the posts stay untouched
        shaped = 0.5 * (np.exp(-p2.k * d) + np.exp(-p2.precision * p2.k * d))
        np.testing.assert_allclose(float(reward), shaped - 0.5 * float(jnp.mean((a - before) ** 2)), rtol=1e-10)
        np.testing.assert_array_equal(np.asarray(obs[-2:]), np.asarray(a))
        before = a
    space = env2.observation_space()
    assert space.low[-3] == 0.0 and space.low[-1] == -1.0 and space.high[-2] == 1.0
    assert np.isinf(space.low[0]) and space.low[33] == ro.env.GAP_RANGE[0] / ro.env.GAP_SCALE
    with pytest.raises(ValueError, match="action_rate_weight"):
        env2.reset(key, dataclasses.replace(p2, action_rate_weight=-0.1))


def test_ramped_baseline_raises_the_turned_reference_action_over_its_rise():
    """The k-th control step (from 1) holds k dt / ramp_s of the action, read from the observed time
    left; the 3D one turns with the scene's yaw (observed as cos, sin)."""
    env2, env3 = make("reach_obstacles_2d"), make("reach_obstacles")
    steps = np.arange(30)
    obs = np.zeros((30, env2.obs_size))
    obs[:, 30], obs[:, 43] = 1.0, 1.0 - steps / 30
    got = np.asarray(jax.jit(ro.held_policy(env2, ramp_s=1.5))(jnp.asarray(obs)))
    frac = np.minimum((steps + 1) * 0.1 / 1.5, 1.0)
    np.testing.assert_allclose(got, frac[:, None] * np.array([0.7, 1.0]), rtol=1e-12)
    obs3 = np.zeros((1, env3.obs_size))
    obs3[0, 31], obs3[0, 43] = 1.0, 1.0 - 2 / 30  # the scene turned by 90 deg, the third step
    got3 = np.asarray(ro.held_policy(env3, ramp_s=1.5)(jnp.asarray(obs3)))[0]
    np.testing.assert_allclose(got3, 0.2 * np.array([0.0, 0.5, 0.0, 0.9]), atol=1e-12)


def test_applied_action_is_the_policys_or_its_correction_to_the_turned_ramp():
    """``applied`` by hand: the policy's action itself with ``residual_scale`` 0; with s > 0 the
    reference turned by the yaw, (k + 1) dt / 1.5 s of it at step k, plus s x the correction, or
    with ``residual_rise`` 1 the sum ramped as a whole; clipped to [-1, 1]; under jit and vmap."""
    env = make("reach_obstacles")
    p = env.default_params()
    rng = np.random.default_rng(0)
    full, yaw, k = rng.uniform(-1, 1, (40, 4)), rng.uniform(-math.pi, math.pi, 40), np.arange(40) % 30
    ref, c, s = np.array(env.reference_action), np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    turned = np.concatenate([ref[0] * c - ref[1] * s, ref[0] * s + ref[1] * c, ref[2] * c - ref[3] * s,
                             ref[2] * s + ref[3] * c], -1)
    f = np.minimum((k + 1) * 0.1 / 1.5, 1.0)[:, None]
    for scale, w, want in ((0.0, 0.0, full), (0.5, 0.0, np.clip(f * turned + 0.5 * full, -1, 1)),
                           (0.5, 1.0, np.clip(f * (turned + 0.5 * full), -1, 1))):
        q = dataclasses.replace(p, residual_scale=scale, residual_rise=w)
        got = jax.jit(jax.vmap(lambda a, y, i, q=q: ro.applied(a, env.reference_action, y, i, q)))(
            jnp.asarray(full), jnp.asarray(yaw), jnp.asarray(k))
        np.testing.assert_allclose(np.asarray(got), want, atol=1e-12)
    assert np.abs(want).max() == 1.0 and np.ptp(want) > 1.0  # some clipped, the rest spread


@pytest.mark.slow
def test_residual_actions_correct_the_ramp_and_the_last_step_weighs_more(env, batched):
    """With ``residual_scale`` s the applied tendon action is clip(ramp + s x action), the ramp (the
    reference action turned by the drawn yaw, (k + 1) dt / 1.5 s of it at step k) by hand: zero
    actions apply the ramp baseline's; with ``final_weight`` w the reward's closeness term counts
    1 + w times at the last step only; with ``residual_rise`` 1 the corrections rise with the ramp;
    under jit and vmap."""
    res = dataclasses.replace(env.default_params(), yaw_range=math.pi, residual_scale=0.5, residual_rise=0.0,
                              final_weight=4.0)
    keys = jax.random.split(jax.random.PRNGKey(4), 3)  # the scene test's batch: the same programs
    reset, step = batched
    state = reset(keys, res)[1]
    ref, c, s = np.array(env.reference_action), np.cos(np.asarray(state.yaw)), np.sin(np.asarray(state.yaw))
    turned = np.stack([ref[0] * c - ref[1] * s, ref[0] * s + ref[1] * c, ref[2] * c - ref[3] * s,
                       ref[2] * s + ref[3] * c], -1)
    assert np.ptp(np.asarray(state.yaw)) > 0.1
    correction = np.array([[0.9, -0.4, 0.8, 0.1], [0.0, 0.0, 0.0, 0.0], [-1.0, 1.0, -0.6, 0.3]])
    for k in range(30):
        obs, state, reward, done, info = step(keys, state, jnp.asarray(correction), res)
        prior = turned * min((k + 1) * 0.1 / 1.5, 1.0)
        np.testing.assert_allclose(np.asarray(state.last_action), np.clip(prior + 0.5 * correction, -1, 1), atol=1e-12)
        d, depth = np.asarray(info["distance"]), np.asarray(info["depth"])
        shaped = 0.5 * (np.exp(-2 * d) + np.exp(-20 * d)) * (5.0 if k == 29 else 1.0)
        np.testing.assert_allclose(np.asarray(reward), shaped - 0.5 * np.minimum(depth / 0.01, 2), rtol=1e-10)
        if k == 2:  # the ramp baseline's next action, at step 3 of 15
            np.testing.assert_allclose(np.asarray(ro.held_policy(env, ramp_s=1.5)(obs[1])),
                                       np.asarray(state.last_action)[1] * 4 / 3, atol=1e-12)
    assert np.all(np.asarray(done)) and np.all(np.asarray(info["valid"]))
    # residual_rise 1: the corrections rise with the ramp too (the same compiled step: a traced param)
    rising = dataclasses.replace(res, residual_rise=1.0)
    state = reset(keys, rising)[1]
    for k in range(3):
        state = step(keys, state, jnp.asarray(correction), rising)[1]
        np.testing.assert_allclose(np.asarray(state.last_action),
                                   np.clip((k + 1) / 15 * (turned + 0.5 * correction), -1, 1), atol=1e-12)
    for name, bad in (("residual_scale", -1.0), ("final_weight", -1.0), ("residual_rise", -0.1),
                      ("residual_rise", 1.5)):
        with pytest.raises(ValueError, match=name):
            env.reset(keys[0], dataclasses.replace(res, **{name: bad}))


def test_train_variant_registers_the_task_with_its_params_replaced(monkeypatch):
    """``experiments/studies/train_variant.py``: the variant's default params carry the replacements and
    nothing else changes; an unknown field is refused, naming the fields."""
    import importlib.util
    from pathlib import Path

    from gvsjax.tasks import base

    monkeypatch.setattr(base, "_REGISTRY", dict(base._REGISTRY))  # the registration undone after the test
    path = Path(__file__).parents[1] / "experiments" / "studies" / "train_variant.py"
    spec = importlib.util.spec_from_file_location("train_variant", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    name = module.variant("reach_obstacles_2d", {"residual_scale": 1.0, "final_weight": 5.0})
    env, base = make(name), make("reach_obstacles_2d").default_params()
    got = env.default_params()
    assert (got.residual_scale, got.final_weight) == (1.0, 5.0) and env.obs_size == 46
    assert (got.action_rate_weight, got.k, got.target_jitter) == (base.action_rate_weight, base.k, base.target_jitter)
    assert module.parse("0.05,0,0.02") == (0.05, 0.0, 0.02) and module.parse("3") == 3.0
    with pytest.raises(SystemExit, match="final_weight"):
        module.variant("reach_obstacles", {"finalweight": 1.0})


def test_random_layouts_move_each_capsule_and_the_gaps_follow(env, batched, params):
    """``layout_jitter``: each capsule of each episode moves by its own draw within the jitter (before
    the scene's turn), the yaw and target draws unchanged; the rest arm's gaps (each sample's 10 cm
    piece of the straight arm) against distances to the moved, turned capsules by hand; under jit
    and vmap."""
    moved = dataclasses.replace(params, yaw_range=math.pi, layout_jitter=(0.05, 0.02, 0.05))
    keys = jax.random.split(jax.random.PRNGKey(7), 3)
    reset = batched[0]
    state = reset(keys, moved)[1]
    still = reset(keys, dataclasses.replace(moved, layout_jitter=(0.0, 0.0, 0.0)))[1]
    shift = np.asarray(state.shift)
    assert shift.shape == (3, 12, 3) and np.all(np.abs(shift) <= np.array([0.05, 0.02, 0.05]))
    assert np.ptp(shift[:, :, 0]) > 0.05 and np.ptp(shift[0, :, 0]) > 0.03 and not np.any(np.asarray(still.shift))
    np.testing.assert_array_equal(np.asarray(state.yaw), np.asarray(still.yaw))
    np.testing.assert_array_equal(np.asarray(state.target), np.asarray(still.target))
    # each sample's piece of the straight rest arm: 5 cm either way (one way only at the ends), finely sampled
    z = np.linspace(0.0, 1.0, 2001)
    pieces = [np.stack([0 * z, 0 * z, z], -1)[np.abs(z - zc) <= 0.05 + 1e-12] for zc in np.linspace(0.0, 1.0, 11)]
    rod = params.arm.robot.links[0].radius
    for i in range(3):
        c, s = np.cos(float(state.yaw[i])), np.sin(float(state.yaw[i]))
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        a, b = (np.asarray(params.start) + shift[i]) @ R.T, (np.asarray(params.end) + shift[i]) @ R.T
        want = [min(_segment_distance(p, a[j], b[j]).min() - np.asarray(params.radius)[j] for j in range(12))
                for p in pieces]
        np.testing.assert_allclose(np.asarray(state.gap[i]), np.array(want) - rod, atol=1e-6)
    with pytest.raises(ValueError, match="layout_jitter"):
        env.reset(keys[0], dataclasses.replace(params, layout_jitter=(0.05, -0.01, 0.0)))
