"""gvsjax.mpc: the gradient MPC's optimiser against closed-form optima on a toy integrator, its
memory through ``evaluate`` (a ``Controller`` wherever a ``Policy`` goes), the CLI's checks, and
on the balance arm (extended tier) a plan that beats holding still."""

import gvsjax  # noqa: F401, I001  (first: it configures JAX)

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct

from gvsjax import evaluate, mpc
from gvsjax.tasks import Environment, base, make, register

GAIN = 0.5  # the integrator's displacement per unit action and step


@struct.dataclass
class PointState:
    x: jax.Array  # (2,)
    goal: jax.Array  # (2,)
    step: jax.Array


class Integrator(Environment):
    """x' = x + GAIN a, reward -|x' - goal|^2: one step's optimum is clip((goal - x) / GAIN, -1, 1)."""

    name = "integrator"
    obs_size = 4
    action_size = 2
    episode_length = 6

    def default_params(self):
        return {"gain": jnp.asarray(GAIN)}

    def reset(self, key, params):
        x, goal = jax.random.uniform(key, (2, 2), minval=-2.0, maxval=2.0)
        state = PointState(x=x, goal=goal, step=jnp.zeros((), jnp.int32))
        return jnp.concatenate([x, goal]), state

    def step(self, key, state, action, params):
        x = state.x + params["gain"] * jnp.clip(action, -1.0, 1.0)
        new = PointState(x=x, goal=state.goal, step=state.step + 1)
        reward = -jnp.sum((x - state.goal) ** 2)
        done = new.step >= self.episode_length
        return jnp.concatenate([x, state.goal]), new, reward, done, {"valid": jnp.ones((), bool)}


def test_config_names_the_parameter_and_its_range():
    for bad, match in ((dict(horizon=0), r"horizon=0.*\[1, 1000\]"), (dict(iterations=2.5), "iterations=2.5"),
                       (dict(learning_rate=-1.0), r"learning_rate=-1.0.*\(0, 10\]"),
                       (dict(discount=1.5), "discount=1.5"), (dict(sim_dtype="half"), "sim_dtype='half'"),
                       (dict(gradient="adjoint"), "gradient='adjoint'.*'reverse' or 'forward'"),
                       (dict(planner="cem"), "planner='cem'.*'adam' or 'mppi'"),
                       (dict(samples=1), r"samples=1.*\[2, 100000\]"), (dict(noise=0.0), r"noise=0.0.*\(0, 2\]"),
                       (dict(temperature=-1), "temperature=-1")):
        with pytest.raises(ValueError, match=match):
            mpc.MPCConfig(**bad)
    assert mpc.MPCConfig(horizon=4, iterations=3).passes_per_step == 24
    assert mpc.MPCConfig(horizon=4, iterations=3, planner="mppi", samples=10).passes_per_step == 120


@pytest.mark.parametrize("gradient", ["reverse", "forward"])
def test_one_step_plan_is_the_closed_form_optimum_under_jit_and_vmap(gradient):
    env = Integrator()
    params = env.default_params()
    config = mpc.MPCConfig(horizon=1, iterations=300, learning_rate=0.05, gradient=gradient)
    controller = mpc.MPC(env, params, config)
    keys = jax.random.split(jax.random.PRNGKey(3), 64)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    action, _ = jax.jit(controller.act)(controller.init(obs, state), obs, state, 0)
    exact = np.clip((np.asarray(state.goal) - np.asarray(state.x)) / GAIN, -1.0, 1.0)
    saturated = np.abs((np.asarray(state.goal) - np.asarray(state.x)) / GAIN) > 1.0
    assert saturated.any() and (~saturated).any()  # both the projection and the interior optimum are checked
    np.testing.assert_allclose(np.asarray(action), exact, atol=2e-3)


def test_sampled_one_step_plan_is_near_the_closed_form_optimum_under_jit_and_vmap():
    """MPPI, no derivative: the best of its samples and their weighted mean close in on the optimum."""
    env = Integrator()
    params = env.default_params()
    config = mpc.MPCConfig(horizon=1, iterations=30, planner="mppi", samples=256, noise=0.3)
    controller = mpc.MPC(env, params, config)
    keys = jax.random.split(jax.random.PRNGKey(3), 64)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    action, _ = jax.jit(controller.act)(controller.init(obs, state), obs, state, 0)
    exact = np.clip((np.asarray(state.goal) - np.asarray(state.x)) / GAIN, -1.0, 1.0)
    np.testing.assert_allclose(np.asarray(action), exact, atol=2e-2)
    # a few samples and iterations leave it far off: the tolerance above is met by the search, not by luck
    rough = mpc.MPC(env, params, dataclasses.replace(config, iterations=1, samples=4))
    coarse, _ = jax.jit(rough.act)(rough.init(obs, state), obs, state, 0)
    assert np.max(np.abs(np.asarray(coarse) - exact)) > 0.2


@pytest.mark.parametrize("planner", ["adam", "mppi"])
def test_the_plan_is_warm_started_and_the_memory_runs_through_evaluate(planner):
    env = Integrator()
    params = env.default_params()
    controller = mpc.MPC(env, params, mpc.MPCConfig(horizon=3, iterations=100, learning_rate=0.1, planner=planner))
    keys = jax.random.split(jax.random.PRNGKey(4), 8)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    action, plan = controller.act(controller.init(obs, state), obs, state, 0)
    assert plan.shape == (8, 3, 2)
    # the goal is reached within three steps of at most GAIN each where it is that close; then held
    result = env.evaluate(params, controller, 32, seed=5)
    held = env.evaluate(params, lambda o: jnp.zeros((o.shape[0], 2)), 32, seed=5)
    assert result.metrics["valid_fraction"] == 1.0
    assert result.metrics["mean_return"] > 0.2 * held.metrics["mean_return"]  # returns are <= 0


def test_cli_checks_controller_keys_before_compiling(capsys, monkeypatch):
    monkeypatch.setattr(base, "_REGISTRY", dict(base._REGISTRY))
    register("integrator", Integrator)
    cases = ((["controller=pid", "task=integrator"], "controller='pid' is invalid"),
             (["controller=mpc"], "controller=mpc needs task=NAME"),
             (["controller=mpc", "task=integrator", "checkpoint=runs/x"], "either checkpoint= .* or controller=mpc"),
             (["controller=mpc", "task=integrator", "horizon=0"], r"horizon=0 is invalid.*\[1, 1000\]"),
             (["controller=mpc", "task=chess"], "task='chess' is unknown"),
             (["controller=mpc", "task=basketball"], "task='basketball' evaluates policies only"),
             (["checkpoint=runs/x", "horizon=5"], r"\['horizon'\] set the controller: add controller=mpc"))
    for argv, match in cases:
        assert evaluate.main(argv) == 2
        assert __import__("re").search(match, capsys.readouterr().err)


def test_open_loop_tasks_refuse_a_controller():
    env = make("basketball")
    params = env.default_params()
    with pytest.raises(ValueError, match="task='basketball' evaluates policies .* only"):
        env.evaluate(params, mpc.MPC(env, params), 2, 0)


def test_cli_evaluates_the_controller(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(base, "_REGISTRY", dict(base._REGISTRY))
    register("integrator", Integrator)
    argv = ["controller=mpc", "task=integrator", "horizon=2", "iterations=20", "n_targets=4", f"out={tmp_path}"]
    assert evaluate.main(argv) == 0
    import json

    result = json.loads((tmp_path / "eval.json").read_text())
    assert result["controller"]["horizon"] == 2 and result["n_episodes"] == 4 and result["wall_s"] > 0
    assert result["who"] == "MPC"  # the summaries and figures name the controller
    # the batch's wall time splits into compiling (this program is new: it compiles) and running
    assert 0.0 < result["compile_s"] < result["wall_s"]
    steps = 4 * Integrator.episode_length
    assert result["run_ms_per_control_step"] == pytest.approx(1e3 * (result["wall_s"] - result["compile_s"]) / steps)
    assert "ms per control step" in capsys.readouterr().out


def test_compile_clock_counts_a_new_program_and_not_a_cached_one():
    from gvsjax.utils.compile_clock import compile_seconds

    f = jax.jit(lambda x: jnp.sin(x) * 3.0 + jnp.cumsum(x))
    x = jnp.arange(5.0)
    with compile_seconds() as first:
        f(x).block_until_ready()
    with compile_seconds() as again:
        f(x).block_until_ready()
    assert first[0] > 0.0 and again[0] == 0.0


@pytest.mark.extended
def test_mpc_on_the_balance_arm_beats_holding_still():
    # the balance arm (3 coordinates): its derivative compiles in about a minute (docs/mpc.md)
    env = make("balance")
    params = env.default_params()
    controller = mpc.MPC(env, params, mpc.MPCConfig(horizon=5, iterations=5, learning_rate=0.2, gradient="forward"))
    keys = jax.random.split(jax.random.PRNGKey(11), 2)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)

    @jax.jit
    def run(state, obs):
        def one(carry, t):
            obs, s, plan, hold = carry
            a, plan = controller.act(plan, obs, s, t)
            obs, s, r, _, _ = jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, s, a, params)
            _, hold, r0, _, _ = jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, hold, 0.0 * a, params)
            return (obs, s, plan, hold), (r, r0)

        init = (obs, state, controller.init(obs, state), state)
        return jax.lax.scan(one, init, jnp.arange(20))[1]

    r, r0 = run(state, obs)
    assert np.all(np.isfinite(r)) and float(jnp.sum(r)) > float(jnp.sum(r0)) + 0.1
