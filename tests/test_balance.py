"""The paper's arm on a torque-driven base against closed forms (rigid pendulum, work-energy,
statics), and the balance task: the env under jit/vmap, bad input, its metrics, its figures."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import capture_figures, finite_line, raises_naming

import gvsjax as gv
from gvsjax.tasks import balance as bal
from gvsjax.tasks import make
from gvsjax.tasks.balance.baseline import energy_pd_policy

G, L, R, RHO = 9.81, 1.0, 0.05, 1000.0
MASS = RHO * math.pi * R**2 * L  # 7.85 kg


@pytest.fixture(scope="module")
def env():
    return make("balance")


@jax.jit
def _mass_and_stiffness(robot, q):
    zero = jnp.zeros(robot.n_dofs)
    potential = lambda x: (lambda e: e["elastic"] + e["gravity"])(gv.energy(robot, x, zero))  # noqa: E731
    return gv.mass_and_forces(robot, q, zero)[0], jax.hessian(potential)(q)


def linear_frequencies(robot, q):
    """Small-oscillation frequencies (rad/s) about the equilibrium q: eig(M^-1 (K_elastic + K_gravity)),
    the stiffness the Hessian of the potential energy (elastic + gravity) from gv.energy."""
    M, K = map(np.asarray, _mass_and_stiffness(robot, q))
    M = M + np.tril(M, -1).T  # its lower triangle
    return np.sort(np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real))


def test_torque_base_is_free_and_driven():
    robot = gv.paper_arm(base="torque")
    assert robot.actuated == (0,) and robot.prescribed == () and robot.free == (0, 1, 2)
    assert gv.paper_arm().prescribed == (0,)
    raises_naming("base", gv.paper_arm, base="free")


def test_a_stiff_arm_swings_as_the_rigid_pendulum():
    """A stiff rod hanging from a free pivot: omega^2 = m g (L/2) / J, J = m (L^2 / 3 + r^2 / 4) its
    moment of inertia about the pivot (the r^2 / 4 of the sections' own rotation lowers omega by 0.09%)."""
    w = linear_frequencies(gv.paper_arm(base="torque", youngs_modulus=1e10), jnp.zeros(3))
    np.testing.assert_allclose(w[0], math.sqrt(G * L / 2 / (L**2 / 3 + R**2 / 4)), rtol=1e-6)


@pytest.mark.extended  # a 1650-step simulation; the stiff arm's closed form covers it in the default run
def test_the_soft_arm_swings_at_its_linear_frequency():
    """The default (soft) arm, 0.05 rad from hanging, torque off, no damping: the simulated period
    matches its linear analysis (slower than a rigid rod's 1.638 s, the arm bending as it swings)."""
    robot = gv.paper_arm(base="torque", damping=0.0)
    w = linear_frequencies(robot, jnp.zeros(3))
    tr = gv.simulate(robot, 3.3, n_steps=1650, q0=jnp.array([0.05, 0.0, 0.0]), joint_force=0.0,
                     integrator="ars443", check_stability=False)
    t, theta = np.asarray(tr.t), np.asarray(tr.q[:, 0])
    # upward zero crossings, linearly interpolated
    i = np.flatnonzero((theta[:-1] < 0) & (theta[1:] >= 0))
    crossings = t[i] - theta[i] * (t[i + 1] - t[i]) / (theta[i + 1] - theta[i])
    period = np.diff(crossings)[0]
    assert 2 * math.pi / math.sqrt(1.5 * G / L) < period
    np.testing.assert_allclose(period, 2 * math.pi / w[0], rtol=3e-3)


def test_work_of_the_base_torque_equals_the_energy_gained():
    """Undamped, a constant base torque tau: E(t) - E(0) = tau (theta(t) - theta(0))."""
    robot = gv.paper_arm(base="torque", damping=0.0)
    tau, q0 = 15.0, jnp.array([0.3, 0.0, 0.0])
    tr = gv.simulate(robot, 1.0, n_steps=1000, q0=q0, joint_force=tau, integrator="rk4", save_every=250)
    parts = jax.jit(jax.vmap(lambda q, qd: gv.energy(robot, q, qd)))(tr.q, tr.qd)
    energy = np.asarray(parts["kinetic"] + parts["elastic"] + parts["gravity"])
    work = tau * (np.asarray(tr.q[:, 0]) - 0.3)
    assert work.max() > 5.0  # the torque did real work
    np.testing.assert_allclose(energy - energy[0], work, atol=1e-6 * MASS * G * L)


def test_a_stiff_arm_is_held_by_the_static_torque():
    """The torque limit's analysis: m g (L/2) sin(theta) holds a stiff arm at theta (here 60 degrees)."""
    robot = gv.paper_arm(base="torque", youngs_modulus=1e10)
    theta = math.radians(60)
    tau = MASS * G * L / 2 * math.sin(theta)
    tr = gv.simulate(robot, 1.0, n_steps=100, q0=jnp.array([theta, 0.0, 0.0]), joint_force=tau,
                     integrator="ars443", check_stability=False)
    assert np.max(np.abs(np.asarray(tr.q[:, 0]) - theta)) < 1e-3  # the arm's small sag: 1.6e-4 rad
    # 2% more or less and the arm turns away
    for k, sign in ((1.02, 1), (0.98, -1)):
        tr = gv.simulate(robot, 1.0, n_steps=100, q0=jnp.array([theta, 0.0, 0.0]), joint_force=k * tau,
                         integrator="ars443", check_stability=False)
        assert sign * (float(tr.q[-1, 0]) - theta) > 1e-3


def test_upright_summary_by_hand():
    dt, T = 0.05, 200
    tilt = np.full((3, T), math.radians(90.0))
    tilt[0, 40:] = math.radians(2.0)  # up from step 40 on: time 2.05 s
    tilt[0, 100] = math.radians(4.0)
    tilt[1, 40:150] = math.radians(1.0)  # up, then lost
    tilt[2, 170:] = math.radians(1.0)  # up for the last 1.5 s only: not a success
    tip = np.zeros((3, T, 3))
    tip[0, 40:, 0] = 0.01
    s = bal.upright_summary(tilt, np.ones((3, T), bool), tip, dt, 5.0)
    assert s["success"].tolist() == [True, False, False]
    assert s["ever_upright"].tolist() == [True, True, True]
    np.testing.assert_allclose(s["time_to_upright_s"][[0, 2]], [2.05, 8.55])
    assert np.isnan(s["time_to_upright_s"][1])
    np.testing.assert_allclose(s["wobble_max_deg"][0], 4.0)
    np.testing.assert_allclose(s["wobble_rms_deg"][0], math.sqrt((159 * 4 + 16) / 160))
    np.testing.assert_allclose(s["tip_sway_rms_mm"][0], 10.0)
    np.testing.assert_allclose(s["last_max_deg"], [2.0, 90.0, 90.0])
    np.testing.assert_allclose(s["last_rms_deg"][0], 2.0)


def test_reward_by_hand():
    """Values of the reward at tilts and speeds worked out by hand (see ``bal.reward``'s formula)."""
    P = bal.BalanceParams()
    b, cone = P.upright_bonus, math.radians(P.upright_deg)

    def r(tilt_deg, speed=0.0, a=0.0):
        t = math.radians(tilt_deg)
        tip = jnp.array([math.sin(t), math.cos(t), 0.0])  # 1 m from the base, tilted by t from straight up
        return float(bal.reward(P, tip, jnp.array([speed, 0.0, 0.0]), jnp.asarray(a)))

    assert r(0.0) == pytest.approx(1.0, abs=1e-12)
    assert r(180.0) == pytest.approx(0.0, abs=1e-12)  # hanging still earns nothing
    assert r(P.upright_deg) == pytest.approx((1 - b) * (1 - cone / math.pi) + b * math.exp(-1.0), rel=1e-9)
    assert r(90.0) == pytest.approx((1 - b) * 0.5, rel=1e-9)  # the bonus is gone far from upright
    assert r(0.0, speed=P.speed_scale) == pytest.approx(0.5, rel=1e-9)
    assert r(0.0, a=1.0) == pytest.approx(1.0 - P.action_cost, rel=1e-9)
    # sharp near upright, where 1 - tilt / pi alone changes by 0.3% between 0.5 and 1 degree
    assert r(0.5) - r(1.0) > 0.01
    assert all(0.0 <= r(t, 3.0 * f, f) <= 1.0 for t in range(0, 181, 15) for f in (0.0, 0.5, 1.0))


def test_env_under_jit_and_vmap(env):
    P = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(1), 3)
    obs, s = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, P)
    assert obs.shape == (3, env.obs_size) and np.all(np.asarray(obs[:, -1]) == 1.0)
    assert np.all(np.abs(np.asarray(s.q[:, 0])) <= P.start_angle)
    assert np.all(np.degrees(np.asarray(bal.tilt(s.tip))) > 180 - np.degrees(P.start_angle) - 1e-9)
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    actions = jnp.array([[1.0], [-2.0], [jnp.nan]])
    for t in range(3):
        obs, s2, reward, done, info = step(jax.random.split(jax.random.PRNGKey(t), 3), s, actions, P)
        s = s2
    valid = np.asarray(info["valid"])
    assert valid.tolist() == [True, True, False]  # a NaN action is flagged, the batch runs on
    r = np.asarray(reward)
    expected = [float(bal.reward(P, s.tip[i], s.tip_velocity[i], s.action[i])) for i in range(2)]
    np.testing.assert_allclose(r[:2], expected, rtol=1e-12)
    assert np.asarray(s.action)[1] == -1.0 and r[2] == 0.0  # clipped; invalid step: no reward
    assert np.all((r[:2] >= 0) & (r[:2] <= 1))
    assert float(s.q[0, 0]) > float(s.q[1, 0])  # +torque turns the base towards +theta
    np.testing.assert_allclose(np.asarray(obs[:2, -1]), 1 - 3 / env.episode_length)
    assert np.asarray(done).tolist() == [False, False, True]  # an invalid step ends its episode
    assert env.observation_space().shape == (env.obs_size,)


def test_bad_input_is_refused_before_compiling(env):
    P = env.default_params()
    key = jax.random.PRNGKey(0)
    raises_naming("paper_arm(base='torque')", env.reset, key, P.replace(arm=gv.paper_arm()))
    raises_naming("n_modes=2", env.reset, key, P.replace(arm=gv.paper_arm(base="torque", n_modes=3)))
    raises_naming("torque_max", env.reset, key, P.replace(torque_max=0.0))
    raises_naming("start_rate", env.reset, key, P.replace(start_rate=-1.0))
    raises_naming("upright_bonus", env.reset, key, P.replace(upright_bonus=1.5))
    raises_naming("episode_steps", env.reset, key, P.replace(episode_steps=100))
    _, s = env.reset(key, P)
    raises_naming("expected (1,)", env.step, key, s, jnp.zeros(2), P)


def test_the_baseline_swings_up_and_balances(env):
    """The hand-designed controller (energy pumping, then a PD catch on the tip) succeeds in every
    episode: the task is feasible within the torque limit, and evaluate's metrics see it."""
    P = env.default_params()
    result = env.evaluate(P, energy_pd_policy(P), 8, seed=3)
    m = result.metrics
    assert m["success_rate"] == 1.0 and m["valid_fraction"] == 1.0
    assert 1.5 < m["time_to_upright_s"]["median"] < 4.0  # a swing-up, not a lift
    assert m["wobble_max_deg"]["max"] < 5.0
    assert "success 100.0%" in env.summary(m)
    assert np.abs(result.extra["action"]).max() == 1.0  # the pump saturates the torque


def test_evaluation_figures_draw_the_curves(tmp_path, monkeypatch):
    from gvsjax.tasks.balance.figures import evaluation_figures

    rng = np.random.default_rng(0)
    tilt = np.radians(rng.uniform(0.5, 3.0, (32, 200)))
    tilt[:, :40] = np.radians(np.linspace(175, 10, 40))
    tilt[:2, 150:] = 1.5  # two failures
    success = np.ones(32, bool)
    success[:2] = False
    extra = {"tilt": tilt, "action": rng.uniform(-1, 1, (8, 200)), "success": success,
             "time_to_upright": np.where(success, 2.05, np.nan), "dt": 0.05, "torque_max": 20.0,
             "upright_deg": 5.0}
    figs = capture_figures(monkeypatch)
    paths = evaluation_figures(extra, tmp_path)
    assert [p.name for p in paths] == ["balance_tilt.png", "balance_torque.png", "time_to_upright.png"]
    median = finite_line(figs["balance_tilt.png"], "median", 200)
    np.testing.assert_allclose(median["y"], np.median(np.degrees(tilt), 0))
    finite_line(figs["balance_tilt.png"], "failed episode 0", 200)
    for i in range(4):
        line = finite_line(figs["balance_torque.png"], f"episode {i}", 200)
        np.testing.assert_allclose(line["y"], 20.0 * extra["action"][i])
    bars = [ln for ln in figs["time_to_upright.png"] if ln["label"] == "bars"][0]
    assert abs(bars["y"].sum() - 100 * 30 / 32) < 1e-9


def test_render_and_gif_draw_the_arm(env, tmp_path):
    P = env.default_params()
    _, s = env.reset(jax.random.PRNGKey(0), P)
    image = env.render(P, s, None)
    assert image.ndim == 3 and image.shape[2] == 3 and image.std() > 0
    from gvsjax.tasks.balance.figures import episode_gif

    q = np.zeros((3, 3))
    q[:, 0] = [0.0, 1.5, 3.1]
    path = episode_gif(tmp_path / "a.gif", P.arm, q, np.array([1.0, 0.1]), np.array([20.0, -5.0]), 20.0, 0.05,
                       5.0, fps=10, dpi=40)
    assert path.stat().st_size > 1000
