"""The basketball task (gvsjax.tasks.basketball): action mapping, flight geometry, release
states, cost, reward, non-finite actions, targets, and the figures' arm and ball drawings."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import capture_figures, finite_line, no_compile

import gvsjax  # noqa: F401  (sets the XLA flag and x64 before JAX starts)
from gvsjax.tasks import basketball as bb
from gvsjax.tasks import make

G = 9.81


class _Jitted:
    """The env with jitted step (eager simulation would compile at every call)."""

    def __init__(self, env):
        self.env, self.step, self.reset = env, jax.jit(env.step), env.reset


@pytest.fixture(scope="module")
def env_and_params():
    env = make("basketball")
    return _Jitted(env), env.default_params()


_release = jax.jit(bb.release_state)


def test_action_mapping_hand_values(env_and_params):
    _, P = env_and_params
    a = jnp.array([[-1.0, -1.0], [1.0, 1.0], [0.0, 0.0], [3.0, -7.0], [0.2, -0.6]])
    T, delta = bb.action_to_physical(a, P)
    np.testing.assert_allclose(T, [0.5, 3.0, 1.75, 3.0, 0.5 + 0.6 * 2.5], rtol=1e-12)
    np.testing.assert_allclose(delta, [0.85, 1.0, 0.925, 0.85, 0.85 + 0.2 * 0.15], rtol=1e-12)
    back = bb.physical_to_action(T, delta, P)
    np.testing.assert_allclose(back, np.clip(a, -1, 1), atol=1e-12)


def test_closest_approach_hand_cases():
    p0, v0, end = jnp.array([0.0, 0.0]), jnp.array([1.0, 0.0]), 10.0
    # a point on the path (tau = 0.5): cost 0
    on = bb.flight_point(p0, v0, 0.5, G)
    d, tau = bb.closest_approach(p0, v0, on, G, end)
    assert float(d) < 1e-12 and abs(float(tau) - 0.5) < 1e-9
    # behind the release point: the path's start is closest
    d, tau = bb.closest_approach(p0, v0, jnp.array([-1.0, 0.0]), G, end)
    assert abs(float(d) - 1.0) < 1e-12 and float(tau) == 0.0
    # straight up, no gravity: distance from (1, 1) to the ray along +x is 1
    d, _ = bb.closest_approach(p0, v0, jnp.array([1.0, 1.0]), 0.0 * G + 1e-9, end)
    assert abs(float(d) - 1.0) < 1e-6
    # past the floor end: the landing point is closest
    end_floor = bb.floor_time(p0, v0, G, -1.0)
    assert abs(float(end_floor) - math.sqrt(2.0 / G)) < 1e-12
    land = bb.flight_point(p0, v0, end_floor, G)
    d, tau = bb.closest_approach(p0, v0, land + jnp.array([0.0, -0.5]), G, end_floor)
    assert abs(float(d) - 0.5) < 1e-3 and abs(float(tau) - float(end_floor)) < 1e-12


def test_closest_approach_matches_dense_sampling():
    rng = np.random.default_rng(0)
    n = 100
    p0 = rng.uniform(-1, 1, (n, 2))
    v0 = rng.uniform(-14, 14, (n, 2))
    target = rng.uniform([-8, -2], [2, 5], (n, 2))
    end = np.asarray(bb.floor_time(jnp.asarray(p0), jnp.asarray(v0), G, -1.95))
    d, _ = jax.vmap(bb.closest_approach, in_axes=(0, 0, 0, None, 0))(
        jnp.asarray(p0), jnp.asarray(v0), jnp.asarray(target), G, jnp.asarray(end))
    tau = np.linspace(0, 1, 50001)[None, :] * end[:, None]
    pts = p0[:, None] + v0[:, None] * tau[..., None] + 0.5 * np.array([0, -G]) * tau[..., None] ** 2
    dense = np.min(np.linalg.norm(pts - target[:, None], axis=-1), axis=1)
    # exact <= sampled, and sampling on a fine grid comes within its resolution
    assert np.all(np.asarray(d) <= dense + 1e-9)
    np.testing.assert_allclose(np.asarray(d), dense, atol=1e-3)


@pytest.mark.parametrize("integration, tol_p, tol_v", [
    (dict(integrator="rk4", n_steps=300), 2e-5, 2e-4),  # converged: the reference's own digits
    ({}, 1e-3, 5e-3),  # the task's default (40 ars443 steps): its documented 1 mm / 5 mm/s
])
def test_release_matches_reference(env_and_params, integration, tol_p, tol_v):
    _, P = env_and_params
    P = P.replace(**integration)
    for T, tip, vel in [(0.5, (0.440682, 0.815432), (-13.68403, 7.85183)),
                        (3.0, (-0.495256, 0.868742), (-3.82237, -2.17637))]:
        p0, v0 = _release(P, T, 1.0)
        np.testing.assert_allclose(p0, tip, atol=tol_p)
        np.testing.assert_allclose(v0, vel, atol=tol_v)


def test_step_cost_reward_and_exact_hit(env_and_params):
    env, P = env_and_params
    action = jnp.array([0.3, -0.2])
    T, delta = bb.action_to_physical(action, P)
    p0, v0 = _release(P, float(T), float(delta))  # Python numbers, as the other tests': one program
    target = bb.flight_point(p0, v0, 0.4, G)  # on this throw's own path
    state = bb.BasketballState(target=target, source_action=action, step=jnp.zeros((), jnp.int32))  # as reset's
    obs, state2, reward, done, info = env.step(jax.random.PRNGKey(0), state, action, P)
    assert float(info["cost"]) < 1e-9 and abs(float(reward) - 1.0) < 1e-8
    assert bool(done) and bool(info["valid"]) and not bool(info["truncated"])
    np.testing.assert_allclose(obs, bb.normalise(target, P))
    # 10 cm off the path, normal to it: cost 0.1, reward exp(-0.22) ~ 0.8
    vel = v0 + jnp.array([0.0, -G]) * 0.4
    normal = jnp.array([-vel[1], vel[0]]) / jnp.linalg.norm(vel)
    off = state.replace(target=target + 0.1 * normal)
    _, _, reward, _, info = env.step(jax.random.PRNGKey(0), off, action, P)
    assert abs(float(info["cost"]) - 0.1) < 1e-6
    assert abs(float(reward) - math.exp(-0.22)) < 1e-6 and abs(float(reward) - 0.8) < 3e-3


def test_nonfinite_action_is_thrown_as_the_centre_and_flagged(env_and_params):
    env, P = env_and_params
    key = jax.random.PRNGKey(0)
    _, state = env.reset(jax.random.PRNGKey(1), P)
    with no_compile(), pytest.raises(ValueError, match="action has shape"):  # known while tracing
        jax.eval_shape(lambda a: env.env.step(key, state, a, P), jax.ShapeDtypeStruct((3,), jnp.float64))
    _, _, reward, done, info = env.step(key, state, jnp.array([jnp.nan, 0.0]), P)
    assert not bool(info["valid"]) and float(reward) == 0.0 and bool(done)
    _, _, reward, _, centre = env.step(key, state, jnp.zeros(2), P)
    assert bool(centre["valid"]) and float(reward) > 0.0
    assert (float(info["T"]), float(info["delta"])) == (float(centre["T"]), float(centre["delta"]))


def test_targets_reachable_inside_window_and_spread(env_and_params):
    env, P = env_and_params
    keys = jax.random.split(jax.random.PRNGKey(2), 512)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, P)
    assert np.all(np.abs(np.asarray(obs)) <= 1.0)
    x0, x1, y0, y1 = P.window
    t = np.asarray(state.target)
    assert np.all((t[:, 0] >= x0) & (t[:, 0] <= x1) & (t[:, 1] >= y0) & (t[:, 1] <= y1))
    # action-uniform: the far half of the court still gets its share of targets
    assert np.mean(t[:, 0] < -4.0) > 0.05
    # the recorded grid action throws through its target (first 64, to stay fast; one at a time
    # through the jitted step the other tests compile)
    for i in range(64):
        one = jax.tree.map(lambda x, i=i: x[i], state)
        assert float(env.step(keys[i], one, one.source_action, P)[4]["cost"]) < 1e-6, i


def test_registry():
    from gvsjax.tasks import registered
    assert "basketball" in registered()
    assert make("basketball").obs_size == 2


@pytest.mark.extended
@pytest.mark.parametrize("mode, far_range", [("area", (0.4, 0.65)), ("mixed", (0.22, 0.45))])
def test_area_and_mixed_sampling_are_reachable_and_spread(mode, far_range):
    P = bb.make_params(target_sampling=mode, n_grid_T=32, n_grid_delta=8)
    keys = jax.random.split(jax.random.PRNGKey(3), 512)
    t, source = jax.vmap(bb.sample_target, in_axes=(0, None))(keys, P)
    # x < -4 m holds ~13% of action-uniform targets, ~51% of area-uniform ones, the mean if mixed
    lo, hi = far_range
    assert lo < np.mean(np.asarray(t)[:, 0] < -4.0) < hi
    cost, _ = jax.jit(jax.vmap(bb.throw_cost, in_axes=(None, 0, 0)))(P, source[:32], t[:32])
    assert float(jnp.max(cost)) < 1e-6


def test_unknown_sampling_mode_is_a_clear_error():
    with pytest.raises(ValueError, match="target_sampling='grid' is invalid"):
        bb.make_params(target_sampling="grid")


def test_reset_without_target_tables_says_how_to_build_them():
    env = make("basketball")
    bare = bb.BasketballParams(arm=gvsjax.paper_arm(tip_force=bb.BALL_WEIGHT))  # step works, reset needs tables
    with pytest.raises(ValueError, match="no target tables.*make_params"):
        env.reset(jax.random.PRNGKey(0), bare)


def test_default_integration_within_1mm_of_converged(env_and_params):
    """The task's default (40 ars443 steps) releases within 1 mm, and within 5 mm/s,
    of a converged RK4 run (3000 steps) over the whole action box."""
    _, P = env_and_params
    T, delta = (x.ravel() for x in np.meshgrid(np.linspace(0.5, 3.0, 6), [0.85, 0.925, 1.0]))
    ref = P.replace(integrator="rk4", n_steps=3000)
    p, v = jax.jit(jax.vmap(lambda a, b: bb.release_state(P, a, b)))(T, delta)
    p_ref, v_ref = jax.jit(jax.vmap(lambda a, b: bb.release_state(ref, a, b)))(T, delta)
    assert np.max(np.linalg.norm(p - p_ref, axis=1)) < 1e-3
    assert np.max(np.linalg.norm(v - v_ref, axis=1)) < 5e-3


def test_release_drawing_is_the_envs_throw(env_and_params):
    """The figures' arm and ball: finite, the arm's base at the origin and its 1 m backbone
    ending where the ball starts, at the env's own release point; the flight ends on the floor."""
    _, P = env_and_params
    arm, ball = bb.figures.release_drawing(P, 2.0, 0.9)
    assert arm.ndim == 2 and arm.shape[1] == 3 and arm.shape[0] > 2 and ball.shape == (200, 2)
    assert np.all(np.isfinite(arm)) and np.all(np.isfinite(ball))
    np.testing.assert_allclose(arm[0], 0.0, atol=1e-12)
    length = np.sum(np.linalg.norm(np.diff(arm, axis=0), axis=1))
    assert 0.98 < length <= 1.0 + 1e-9  # the polyline of an inextensible 1 m arm
    p0, _ = _release(P, 2.0, 0.9)
    np.testing.assert_allclose(arm[-1, :2], p0, atol=1e-12)
    np.testing.assert_allclose(ball[0], p0, atol=1e-12)
    assert abs(ball[-1, 1] - P.y_floor) < 1e-9 and np.all(ball[:, 1] >= P.y_floor - 1e-9)


def test_throw_and_shapes_figures_plot_the_arm_and_the_ball(env_and_params, tmp_path, monkeypatch):
    _, P = env_and_params
    captured = capture_figures(monkeypatch)
    arm, ball = bb.figures.release_drawing(P, 2.0, 0.9)
    bb.figures.throw_figure(P, np.array([-5.0, 1.0]), 2.0, 0.9, tmp_path / "throw.png", miss_m=0.01)
    lines = captured["throw.png"]
    drawn = finite_line(lines, "arm at release")
    np.testing.assert_allclose(np.stack([drawn["x"], drawn["y"]], 1), arm[:, :2])
    drawn = finite_line(lines, "ball", min_points=200)
    np.testing.assert_allclose(np.stack([drawn["x"], drawn["y"]], 1), ball)
    finite_line(lines, "target", min_points=1)

    deltas = (0.85, 0.9, 0.95, 1.0)
    bb.figures.shapes(P, tmp_path / "shapes.png", T=2.0, deltas=deltas)
    lines = captured["shapes.png"]
    balls = [finite_line(lines, f"delta = {d:.2f}", min_points=200) for d in deltas]
    arms = [ln for ln in lines if ln["x"].size > 2 and not ln["label"].startswith("delta")]
    assert len(arms) == len(deltas)
    for a, b in zip(arms, balls):
        assert np.all(np.isfinite(a["x"])) and np.all(np.isfinite(a["y"]))
        assert abs(a["x"][0]) < 1e-12 and abs(a["y"][0]) < 1e-12  # the base
        assert abs(a["x"][-1] - b["x"][0]) < 1e-12 and abs(a["y"][-1] - b["y"][0]) < 1e-12  # ball leaves the tip
        assert abs(b["y"][-1] - P.y_floor) < 1e-9
