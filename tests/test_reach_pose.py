"""reach_pose: the tip frame and the target table against closed forms and the dynamics, the
env under jit/vmap, bad input, the evaluation's statistics and figures."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import capture_figures, finite_line

import gvsjax as gv
from gvsjax.tasks import arm3d, make
from gvsjax.tasks import reach_pose as rp


@pytest.fixture(scope="module")
def env():
    return make("reach_pose")


@pytest.fixture(scope="module")
def small():
    """A held-out-style table of 6 poses (its own seed), cheap to build."""
    return rp.make_params(6, 7)


def test_angle_is_accurate_near_zero_and_pi():
    a = jnp.array([0.0, 0.0, 1.0])
    for theta in (1e-9, 0.3, 2.0, math.pi - 1e-9):
        b = jnp.array([math.sin(theta), 0.0, math.cos(theta)])
        np.testing.assert_allclose(float(rp.angle(a, b)), theta, rtol=1e-12)


@pytest.mark.slow
def test_held_actions_settle_on_the_table_poses_under_jit_and_vmap(env, small):
    """The table's poses are static equilibria (Newton on the forces); the env, stepping the
    dynamics with each pose's action held, must come to rest exactly there. Also: jit(vmap) of
    reset/step, the reward's formula, a NaN action flagged while the batch runs on."""
    P = small
    n = P.position.shape[0]
    state = jax.vmap(rp.start, in_axes=(0, None))(jnp.arange(n), P)
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    keys = jax.random.split(jax.random.PRNGKey(0), n)
    for t in range(60):  # 6 s: the slowest pose relaxes within ~1 mm by 5 s
        action = P.action.at[0].set(jnp.nan) if t == 0 else P.action
        obs, state, reward, done, info = step(keys, state, action, P)
        if t == 0:
            assert np.asarray(info["valid"]).tolist() == [False] + [True] * (n - 1)
            assert float(reward[0]) == 0.0
        if t == env.episode_length - 1:
            assert np.all(np.asarray(done))
    d, a = np.asarray(info["distance"][1:]), np.asarray(info["angle_deg"][1:])
    assert d.max() < 2e-3 and a.max() < 0.2, (d, a)
    cost = P.k_position * d + P.k_angle * np.radians(a)
    np.testing.assert_allclose(np.asarray(reward[1:]), (np.exp(-cost) + np.exp(-P.precision * cost)) / 2, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(np.asarray(state.tip_axis), axis=-1), 1.0, atol=1e-12)
    assert obs.shape == (n, env.obs_size) and np.all(np.isfinite(np.asarray(obs)))
    obs0, s0 = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, P)
    assert np.all(np.asarray(obs0[:, -1]) == 1.0) and np.all(np.asarray(s0.index) < n)
    np.testing.assert_allclose(np.asarray(s0.target), np.asarray(P.position[s0.index]))


def test_table_poses_are_unit_directions_within_reach(small):
    big = small
    pos, axis = np.asarray(big.position), np.asarray(big.axis)
    np.testing.assert_allclose(np.linalg.norm(axis, axis=-1), 1.0, atol=1e-12)
    assert np.all(np.linalg.norm(pos, axis=-1) <= 1.0 + 1e-9)  # never beyond the arm's length
    with pytest.raises(ValueError, match="n=0"):
        rp.reachable_poses(big.arm, 0, 0)


def test_bad_parameters_are_refused_before_compiling(env, small):
    with pytest.raises(ValueError, match="unknown reach_pose parameter"):
        rp.make_params(4, 0, k_pos=1.0)
    with pytest.raises(ValueError, match="no target table"):
        env.reset(jax.random.PRNGKey(0), rp.ReachPoseParams())
    with pytest.raises(ValueError, match="two tendon groups"):
        env.reset(jax.random.PRNGKey(0), small.replace(arm=small.arm.replace(robot=gv.soft_arm(tendon_ends=(1.0,)))))
    with pytest.raises(ValueError, match=r"n_episodes=7 is invalid .* 1\.\.6"):
        env.evaluate(small, lambda o: jnp.zeros(o.shape[:-1] + (4,)), 7, 0)
    _, s = env.reset(jax.random.PRNGKey(0), small)
    with pytest.raises(ValueError, match=r"expected \(4,\)"):
        env.step(jax.random.PRNGKey(0), s, jnp.zeros(3), small)
    with pytest.raises(ValueError, match="train_targets"):
        env.train_params("hard")


def test_final_summary_counts_successes_and_divergence():
    out = {"distance": np.array([[0.5, 0.01], [0.5, 0.04], [0.5, 0.01], [0.5, 0.01]]),
           "angle_deg": np.array([[50, 4.0], [50, 9.0], [50, 12.0], [50, 1.0]]),
           "valid": np.array([[True, True], [True, True], [True, True], [True, False]])}
    m = rp.final_summary(out)
    assert m["within_5cm_10deg"] == 0.5 and m["within_2cm_5deg"] == 0.25  # the diverged one fails
    assert m["distance_mean_m"] == math.inf and m["distance_median_m"] == pytest.approx(0.025)


def test_evaluation_figures_draw_the_curves(tmp_path, monkeypatch):
    from gvsjax.tasks.reach_pose.figures import evaluation_figures

    rng = np.random.default_rng(0)
    n, T = 6, 20
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=-1)[:, None]
    small = rp.ReachPoseParams(position=rng.uniform(-0.5, 0.5, (n, 3)), axis=axis, action=rng.uniform(-1, 1, (n, 4)))
    decay = np.exp(-np.arange(1, T + 1) / 5.0)

    def run(scale):
        return {"distance": scale * rng.uniform(0.5, 1, (n, T)) * decay,
                "angle_deg": 30 * scale * np.tile(decay, (n, 1)), "valid": np.ones((n, T), bool),
                "q": np.zeros((n, T + 1, small.arm.robot.n_dofs))}

    pol, held = run(0.5), run(1.0)
    figs = capture_figures(monkeypatch)
    paths = evaluation_figures(small, {"policy": pol, "held_action": held, "dt": 0.1}, tmp_path)
    assert [p.name for p in paths] == ["reach_errors.png", "reach_final_errors.png", "reach_poses.png"]
    median = finite_line(figs["reach_errors.png"], "policy: position, median", T)
    np.testing.assert_allclose(median["y"], 100 * np.median(pol["distance"], 0))
    angle = finite_line(figs["reach_errors.png"], "policy: angle, median", T)
    assert angle["axes"] == 1 and median["axes"] == 0
    np.testing.assert_allclose(angle["y"], np.median(pol["angle_deg"], 0))
    finite_line(figs["reach_errors.png"], "target's own action, held: position, median", T)
    finite_line(figs["reach_errors.png"], "target's own action, held: angle, median", T)
    dots = finite_line(figs["reach_final_errors.png"], "policy", n)
    np.testing.assert_allclose(dots["x"], 100 * pol["distance"][:, -1])
    finite_line(figs["reach_final_errors.png"], "5 cm & 10 deg", 3)
    for i in range(4):
        arm = finite_line(figs["reach_poses.png"], f"episode {i + 1}", 3)
        np.testing.assert_allclose(arm["y"], 0.0, atol=1e-12)  # q = 0: the straight upright arm


def test_arm_actions_are_shared_with_track3d(env):
    """Both 3D tasks act on the same arm the same way (one implementation in arm3d)."""
    assert env.action_size == make("track3d").action_size == arm3d.n_actions(arm3d.ArmParams())
