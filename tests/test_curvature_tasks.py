"""The field's benchmark tasks (gvsjax.tasks.curvature): the rewards, the moving target, the returns and
the orientation distance against independent computations; the control law; follow_target and ik_4d
under jit and vmap for several steps; bad input."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation  # the test extra's independent reference

import gvsjax  # noqa: F401
from gvsjax.core.curvature_arm import SEGMENT_SHARE, segment_lengths
from gvsjax.tasks import make
from gvsjax.tasks.curvature import control, rewards


def test_reach_reward_by_hand():
    d = jnp.array([0.0, 0.049, 0.05, 0.07, 0.1, 0.3])
    want = [2.0, 2.0 - 0.049**2, -0.0025, 0.5 - 0.0049, -0.01, -0.09]
    np.testing.assert_allclose(np.asarray(rewards.reach_reward(d)), want, atol=1e-12)


def test_pose_reward_by_hand():
    cases = [(0.01, 0.02, -1e-4 - 0.5 * 4e-4 + 6.0 - 0.04), (0.01, 0.07, -1e-4 - 0.5 * 0.0049 + 4.5 - 0.14),
             (0.01, 0.5, -1e-4 - 0.125 + 4.0 - 1.0), (0.07, 0.05, -0.0049 - 0.00125 + 1.5 - 0.025),
             (0.07, 0.3, -0.0049 - 0.045 + 1.0 - 0.15), (0.2, 0.0, -0.04)]
    for d, o, want in cases:
        assert float(rewards.pose_reward(jnp.asarray(d), jnp.asarray(o))) == pytest.approx(want, abs=1e-12)


def test_orientation_distance_is_one_minus_the_squared_quaternion_product():
    rng = np.random.default_rng(0)
    for _ in range(20):
        a, b = Rotation.random(random_state=rng), Rotation.random(random_state=rng)
        want = 1.0 - np.dot(a.as_quat(), b.as_quat()) ** 2
        got = rewards.orientation_distance(jnp.asarray(a.as_matrix()), jnp.asarray(b.as_matrix()))
        assert float(got) == pytest.approx(want, abs=1e-12)
    # at rest the benchmark's tip frame is a yaw of pi: o = cos^2(psi / 2) against a target yaw psi
    rest = rewards.benchmark_frame(jnp.asarray(np.array([[0.0, 1, 0], [0, 0, 1], [1, 0, 0]])))
    for psi in (-1.2, 0.0, 0.7):
        o = rewards.orientation_distance(rest, rewards.yaw_frame(jnp.asarray(psi)))
        assert float(o) == pytest.approx(np.cos(psi / 2) ** 2, abs=1e-12)


def test_moving_target_flips_at_the_walls_and_turns_only_inside():
    low, high = jnp.array([-0.6, -0.6, 0.3]), jnp.array([0.6, 0.6, 0.9])
    key = jax.random.PRNGKey(0)
    p, v = jnp.array([0.62, 0.0, 0.5]), jnp.array([0.5, 0.0, 0.0])
    p2, v2 = rewards.move_target(key, p, v, low, high, 0.5, 1.0, 0.1)  # outside: a flip, never a turn
    np.testing.assert_allclose(np.asarray(v2), [-0.5, 0.0, 0.0])
    np.testing.assert_allclose(np.asarray(p2), [0.57, 0.0, 0.5])
    p3, v3 = rewards.move_target(key, jnp.array([0.0, 0.0, 0.5]), v, low, high, 0.5, 1.0, 0.1)  # always turns
    assert float(jnp.linalg.norm(v3)) == pytest.approx(0.5) and not np.allclose(np.asarray(v3), np.asarray(v))
    _, v4 = rewards.move_target(key, jnp.array([0.0, 0.0, 0.5]), v, low, high, 0.5, 0.0, 0.1)  # never turns
    np.testing.assert_allclose(np.asarray(v4), np.asarray(v))


def test_discounted_returns_against_brute_force():
    rng = np.random.default_rng(1)
    r = rng.normal(size=(3, 7))
    out = control.discounted_returns(r, gamma=0.9)
    start = [sum(0.9**t * r[i, t] for t in range(7)) for i in range(3)]
    average = [np.mean([sum(0.9 ** (t - s) * r[i, t] for t in range(s, 7)) for s in range(7)]) for i in range(3)]
    np.testing.assert_allclose(out["start"], start, rtol=1e-12)
    np.testing.assert_allclose(out["average"], average, rtol=1e-12)


def test_control_law_steps_clips_and_spreads_over_the_segments():
    arm = make("follow_target").default_params().arm
    kappa, twist = jnp.zeros((5, 2)), jnp.zeros(5)
    for _ in range(50):
        kappa, twist = control.apply(arm, kappa, twist, jnp.full(10, 1.5))  # clipped to 1: 0.05 per step
    np.testing.assert_allclose(np.asarray(kappa), 2.0)  # 50 x 0.05 = 2.5, clipped to kappa_max
    kappa = jnp.array([[0.1, 0.2], [0.3, 0.4], [0.5, 0.6], [0.7, 0.8], [0.9, 1.0]])
    u = np.asarray(control.rest_values(arm.robot, kappa, twist)).reshape(5, 2)
    share = np.asarray(SEGMENT_SHARE) / segment_lengths()
    np.testing.assert_allclose(u[:, 0], -np.asarray(kappa[:, 0]) * share)  # towards -x: bend_z < 0
    np.testing.assert_allclose(u[:, 1], np.asarray(kappa[:, 1]) * share)


@functools.cache
def batched_step(name):
    """One jit(vmap(step)) per task for the module: every test here then shares its compile."""
    env = make(name)
    return env, jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))


@pytest.mark.parametrize("name", ["follow_target", "ik_4d"])
def test_task_runs_under_jit_and_vmap(name):
    env, step = batched_step(name)
    params = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(0), 3)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    assert obs.shape == (3, env.obs_size)
    actions = jnp.ones((3, env.action_size)).at[1].set(-1.0).at[2].set(0.0)
    for _ in range(3):
        obs, state, reward, done, info = step(keys, state, actions, params)
    assert bool(jnp.all(info["valid"])) and bool(jnp.all(jnp.isfinite(obs))) and not bool(jnp.any(done))
    np.testing.assert_allclose(np.asarray(state.kappa[0]), 0.15)  # three steps of 0.05
    # bending towards -x and -y (direction 1 and 2 both +1) moves the tip that way; no action leaves it up
    tip = np.asarray(state.node_p[:, -1])
    assert tip[0, 0] < -0.005 and tip[0, 1] < -0.005 and tip[1, 0] > 0.005 and tip[1, 1] > 0.005
    assert np.allclose(tip[2, :2], 0.0, atol=1e-9)
    assert env.observation_space().shape == (env.obs_size,)
    with pytest.raises(ValueError, match="action has shape"):
        env.step(keys[0], jax.tree.map(lambda x: x[0], state), jnp.zeros(env.action_size + 1), params)


def test_a_wrong_arm_is_named():
    follow, ik = make("follow_target"), make("ik_4d")
    params = follow.default_params().replace(arm=ik.default_params().arm)  # a twist arm: 15 actions
    with pytest.raises(ValueError, match=r"follow_target\.arm\.robot"):
        follow.reset(jax.random.PRNGKey(0), params)


def test_a_failed_step_scores_minus_ten_ends_the_episode_and_counts_over_its_length():
    """As the benchmark's: a non-finite step gives -10 and ends the episode; the returns divide by the
    episode's own length (2 steps here), not the task's."""
    env, step = batched_step("follow_target")  # the program the jit/vmap test compiled
    params = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(2), 3)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    _, state, r0, done, info = step(keys, state, jnp.zeros((3, 10)), params)
    assert bool(jnp.all(info["valid"])) and not bool(jnp.any(done))
    _, state, r1, done, info = step(keys, state, jnp.zeros((3, 10)).at[1, 4].set(jnp.nan), params)
    assert np.asarray(info["valid"]).tolist() == [True, False, True]
    assert np.asarray(done).tolist() == [False, True, False]
    assert float(r1[1]) == -10.0 and env.failure_reward == -10.0
    assert bool(jnp.all(jnp.isfinite(state.q)))  # the state before the failure is kept
    # recorded as evaluate records it: ``valid`` False from the failed step on, whatever follows
    rewards = np.array([[float(r0[1]), -10.0, 99.0, 99.0]])
    out = control.discounted_returns(rewards, np.array([[True, False, False, False]]))
    np.testing.assert_allclose(out["average"], (float(r0[1]) - 10.0 * 1.99) / 2, rtol=1e-12)
    np.testing.assert_allclose(out["start"], float(r0[1]) - 9.9, rtol=1e-12)


def test_ik_observes_both_orientations_as_quaternions_in_the_published_order():
    """86 values: angles, twists, positions, velocities, the target, the target's quaternion, the tip's
    (their observation's fields in alphabetical order), each (x, y, z, w) with SciPy's sign."""
    env, step = batched_step("ik_4d")
    params = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(3), 3)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    assert env.obs_size == 86 and obs.shape == (3, 86)
    np.testing.assert_allclose(np.asarray(obs[:, 82:]), np.tile([0.0, 0.0, 1.0, 0.0], (3, 1)), atol=1e-12)  # yaw pi
    actions = jnp.ones((3, 15)).at[1].set(-0.7).at[2, 10:].set(1.0)
    for _ in range(3):
        obs, state, _, _, info = step(keys, state, actions, params)
    assert bool(jnp.all(info["valid"]))
    obs = np.asarray(obs)
    np.testing.assert_allclose(obs[:, :10], np.asarray(state.kappa).reshape(3, -1))
    np.testing.assert_allclose(obs[:, 10:15], np.asarray(state.twist))
    np.testing.assert_allclose(obs[:, 75:78], np.asarray(state.target))
    yaw = np.asarray(state.goal)
    want_target = Rotation.from_euler("xyz", np.stack([0 * yaw, 0 * yaw, yaw], 1)).as_quat()
    frames = np.stack([np.asarray(rewards.benchmark_frame(R)) for R in state.tip_R])
    np.testing.assert_allclose(obs[:, 78:82], want_target, atol=1e-12)
    np.testing.assert_allclose(obs[:, 82:86], Rotation.from_matrix(frames).as_quat(), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(obs[:, 78:82], axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(obs[:, 82:86], axis=1), 1.0, rtol=1e-12)
    # the reward's orientation error is the quaternions' 1 - <q_tip, q_target>^2
    o = 1.0 - np.sum(obs[:, 78:82] * obs[:, 82:86], axis=1) ** 2
    np.testing.assert_allclose(np.asarray(info["orientation"]), o, atol=1e-12)


def test_the_quaternion_has_scipys_sign_on_random_rotations():
    R = Rotation.random(500, random_state=4).as_matrix()
    R = np.concatenate([R, np.diag([1.0, -1, -1])[None], np.diag([-1.0, 1, -1])[None], np.eye(3)[None]])
    q = np.asarray(jax.jit(jax.vmap(rewards.quaternion))(jnp.asarray(R)))
    np.testing.assert_allclose(q, Rotation.from_matrix(R).as_quat(), atol=1e-12)


def test_ik_4d_frame_keeps_the_rotation_matrix_observation():
    frame, ik = make("ik_4d_frame"), make("ik_4d")
    params = frame.default_params()
    assert params.orientation_obs == "frame" and frame.obs_size == 89
    obs, state = frame.reset(jax.random.PRNGKey(5), params)
    assert obs.shape == (89,)
    np.testing.assert_allclose(np.asarray(obs[78:80]), [np.cos(float(state.goal)), np.sin(float(state.goal))])
    np.testing.assert_allclose(np.asarray(obs[80:]), np.diag([-1.0, -1.0, 1.0]).reshape(-1), atol=1e-12)
    with pytest.raises(ValueError, match="ik_4d observes orientation_obs='quaternion'.*use ik_4d_frame"):
        ik.reset(jax.random.PRNGKey(5), params)
