"""Domain randomisation (``gvsjax.tasks.randomized``, ``randomize=``): the option's errors before
anything compiles; each factor scales the physics as a robot built with the scaled parameter does
(natural frequencies, damping, payload); per-env models under ``jit(vmap)`` in one trace; the
observed factors; a run records the option, resumes with it and evaluates on the nominal model."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct
from helpers import no_compile, raises_naming

import gvsjax as gv  # noqa: F401  (before JAX starts its backend)
from gvsjax import train
from gvsjax.core.stability import linear_matrices
from gvsjax.ppo import checkpoint as ckpt
from gvsjax.tasks import Environment, auto_reset_step, base, make, register
from gvsjax.tasks.basketball import BALL_WEIGHT
from gvsjax.tasks.randomized import Randomized, nominal, parse, text_of, wrap

NOMINAL = gv.PAPER_ARM


# ----------------------------------------------------------------------------- test tasks


@struct.dataclass
class SwingParams:
    arm: object  # gv.Robot
    duration: float = 0.01  # s
    n_steps: int = struct.field(pytree_node=False, default=4)


class Swing(Environment):
    """A short free swing of the paper's arm from a curvature rate: the tip after ``duration``
    (semi-implicit Euler: the cheapest program to compile; only equality matters here)."""

    name = "swing_test"
    obs_size = 1
    action_size = 1
    episode_length = 1
    randomizable = {**base.ROBOT_MATERIAL, "payload": base.scale_payload}
    traces = 0  # how often ``step`` was traced

    def default_params(self):
        return SwingParams(arm=gv.paper_arm(tip_force=2.0))

    def reset(self, key, params):
        return jnp.zeros(1), jnp.zeros(())

    def step(self, key, state, action, params):
        Swing.traces += 1
        traj = gv.simulate(params.arm, params.duration, n_steps=params.n_steps, save_every=params.n_steps,
                           integrator="euler", qd0=jnp.array([0.0, 2.0, 1.0]), check_stability=False)
        tip = traj.tip[-1, :2]
        info = {"tip_x": tip[0], "tip_y": tip[1], "valid": jnp.ones((), bool), "truncated": jnp.zeros((), bool)}
        return jnp.zeros(1), state, -jnp.sum(tip**2), jnp.ones((), bool), info


@struct.dataclass
class GainParams:
    gain: float = 0.5


@struct.dataclass
class GainState:
    target: jax.Array  # ()


class Gain(Environment):
    """A bandit without a robot: reward exp(-|gain a - target|); it declares its own parameter."""

    name = "gain_test"
    obs_size = 1
    action_size = 1
    episode_length = 1
    ppo_defaults = dict(num_envs=16, num_steps=1, num_minibatches=2, update_epochs=1, shared_hidden=(8,),
                        total_episodes=64)
    randomizable = {"gain": lambda p, f: p.replace(gain=p.gain * f)}

    def default_params(self):
        return GainParams()

    def reset(self, key, params):
        target = jax.random.uniform(key, (), minval=-0.4, maxval=0.4)
        return target[None], GainState(target=target)

    def step(self, key, state, action, params):
        miss = jnp.abs(params.gain * jnp.clip(action[0], -1, 1) - state.target)
        info = {"miss": miss, "valid": jnp.ones((), bool), "truncated": jnp.zeros((), bool)}
        return state.target[None], state, jnp.exp(-miss), jnp.ones((), bool), info


register("gain_test", Gain)


# ----------------------------------------------------------------------------- the option's errors


def test_parse_gives_the_ranges_in_order_and_a_canonical_text():
    env = make("basketball")
    ranges = parse(" E:0.1, damping:0.05,payload:.2 ", env)
    assert ranges == (("E", 0.1), ("damping", 0.05), ("payload", 0.2))
    assert parse(text_of(ranges), env) == ranges
    assert parse("", env) == ()
    assert wrap(env, "") is env


@pytest.mark.parametrize("text, words", [
    ("stiffness:0.1", ["randomize=", "'stiffness'", "'E'", "'damping'", "'density'", "'payload'"]),
    ("E:1.0", ["randomize=", "0 < r < 1"]),
    ("E:1.5", ["randomize=", "0 < r < 1"]),
    ("E:-0.1", ["randomize=", "0 < r < 1"]),
    ("E:0", ["randomize=", "0 < r < 1"]),
    ("E:nan", ["randomize=", "0 < r < 1"]),
    ("E:abc", ["randomize=", "not a number"]),
    ("E=0.1", ["randomize=", "NAME:r"]),
    ("E:0.1,,damping:0.1", ["randomize=", "NAME:r"]),
    ("E", ["randomize=", "NAME:r"]),
    ("E:0.1,E:0.2", ["randomize=", "twice"]),
])
def test_bad_randomize_is_a_clear_error_before_compiling(capsys, text, words):
    with no_compile():
        assert train.main(["task=basketball", f"randomize={text}"]) == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err, (w, err)


def test_names_are_the_tasks_own():
    raises_naming("'payload'", parse, "payload:0.1", make("pickplace"))  # no payload on that arm
    assert parse("gain:0.3", make("gain_test")) == (("gain", 0.3),)
    raises_naming("'gain'", parse, "E:0.1", make("gain_test"))
    raises_naming("randomize_observe", train.parse_args, ["task=basketball", "randomize_observe=true"])
    assert "randomize names ['E', 'damping', 'density', 'payload']" in train.help_text()


def test_a_task_without_a_robot_must_declare_its_parameters():
    raises_naming("Environment.randomizable", base.ROBOT_MATERIAL["E"], GainParams(), 1.1)


# ----------------------------------------------------------------------------- the physics


def _frequencies(robot):
    M, K, _ = linear_matrices(robot, np.zeros(robot.n_dofs))
    return np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))


def _scaled(name, f):
    return Swing.randomizable[name](Swing().default_params(), f).arm


@pytest.mark.parametrize("f", [0.7, 1.25])
def test_each_factor_is_the_robot_built_with_the_scaled_parameter(f):
    built = lambda **kw: gv.paper_arm(tip_force=2.0, **kw)  # noqa: E731
    omega = _frequencies(built())
    # E: the frequencies scale by sqrt(f), as those of an arm built with E f
    assert np.allclose(_frequencies(_scaled("E", f)), np.sqrt(f) * omega, rtol=1e-12)
    assert np.allclose(_frequencies(_scaled("E", f)),
                       _frequencies(built(youngs_modulus=NOMINAL["youngs_modulus"] * f)), rtol=1e-12)
    # density: by 1 / sqrt(f)
    assert np.allclose(_frequencies(_scaled("density", f)), omega / np.sqrt(f), rtol=1e-12)
    # damping: D scales by f, M and K do not move
    _, K0, D0 = linear_matrices(built(), np.zeros(3))
    M1, K1, D1 = linear_matrices(_scaled("damping", f), np.zeros(3))
    _, _, D2 = linear_matrices(built(damping=NOMINAL["damping"] * f), np.zeros(3))
    assert np.allclose(D1, f * D0, rtol=1e-12) and np.allclose(D1, D2, rtol=1e-12) and np.allclose(K1, K0)
    # payload: the tip force
    assert float(_scaled("payload", f).loads[0].magnitude) == pytest.approx(2.0 * f, rel=1e-15)


def _robots(factors):
    """The four parameters' robots built independently, stacked as a batch of params."""
    arms = [gv.paper_arm(youngs_modulus=NOMINAL["youngs_modulus"] * e, damping=NOMINAL["damping"] * d,
                         density=NOMINAL["density"] * r, tip_force=2.0 * p) for e, d, r, p in factors]
    return jax.tree.map(lambda *x: jnp.stack(x), *[SwingParams(arm=a) for a in arms])


def test_per_env_models_under_jit_vmap_in_one_trace():
    env = Randomized(Swing(), parse("E:0.3,damping:0.3,density:0.3,payload:0.3", Swing()))
    params = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(0), 6)
    reset = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    reference = jax.jit(jax.vmap(Swing().step, in_axes=(0, 0, 0, 0)))
    Swing.traces = 0
    for draw in range(3):  # three draws of six models each: one trace of the wrapper's step
        _, state = reset(jax.random.split(jax.random.PRNGKey(draw), 6), params)
        f = np.asarray(state.factors)
        assert f.shape == (6, 4) and np.all(np.abs(f - 1) <= 0.3) and len(np.unique(f[:, 0])) == 6
        _, _, reward, _, info = step(keys, state, jnp.zeros((6, 1)), params)
        for i, name in enumerate(("E", "damping", "density", "payload")):
            assert np.array_equal(info[f"randomize_{name}"], f[:, i])
        _, _, want, _, want_info = reference(keys, state.inner, jnp.zeros((6, 1)), _robots(f))
        assert np.allclose(info["tip_x"], want_info["tip_x"], rtol=0, atol=1e-12)
        assert np.allclose(reward, want, rtol=0, atol=1e-12)
        assert np.ptp(np.asarray(info["tip_x"])) > 1e-4  # the models differ
    assert Swing.traces == 2  # the wrapper's step once, the reference once


def test_auto_reset_redraws_and_observe_appends_the_factors():
    env = Randomized(make("gain_test"), (("gain", 0.5),), observe=True)
    params = env.default_params()
    assert env.obs_size == 2 and env.name == "gain_test" and env.action_size == 1
    assert np.array_equal(env.observation_space().low[-1:], [-1.0])
    obs, state = env.reset(jax.random.PRNGKey(1), params)
    assert obs[-1] == pytest.approx((state.factors[0] - 1) / 0.5)
    step = jax.jit(auto_reset_step(env))
    obs2, state2, _, done, info = step(jax.random.PRNGKey(2), state, jnp.zeros(1), params)
    assert done and info["randomize_gain"] == state.factors[0] and state2.factors[0] != state.factors[0]
    assert obs2[-1] == pytest.approx((state2.factors[0] - 1) / 0.5)
    # nominal: the task's observation with the factors at 1 (zeros)
    task, policy = nominal(env, lambda o: o[:, -1:])
    assert task is env.task and np.array_equal(policy(jnp.ones((3, 1))), np.zeros((3, 1)))
    assert nominal(task, policy)[0] is task


# ----------------------------------------------------------------------------- the command line


def test_a_run_records_randomize_resumes_with_it_and_evaluates_nominal(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["task=gain_test", f"out={out}", "progress=false", "checkpoint_every=0", "eval_targets=32"]
    assert train.main(args + ["randomize=gain: 0.20", "randomize_observe=true"]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["randomize"] == "gain:0.2" and config["randomize_observe"] is True
    rows = (out / "metrics.csv").read_text().splitlines()
    assert "episode_randomize_gain" in rows[0]
    _, env, params, net = ckpt.load_policy(out)
    assert isinstance(env, Randomized) and env.ranges == (("gain", 0.2),) and env.observe
    assert params == GainParams()  # evaluation: the nominal model
    # resume keeps the option (a longer run), a changed one is refused
    assert train.main(args + ["resume=true", "total_episodes=128"]) == 0
    meta = ckpt.load_raw(out)
    assert meta["config"]["randomize"] == "gain:0.2" and meta["config"]["randomize_observe"] is True
    assert meta["step"] == 8
    capsys.readouterr()
    with no_compile():
        assert train.main(args + ["resume=true", "randomize=gain:0.3"]) == 2
    assert "randomize='gain:0.3' differs" in capsys.readouterr().err


def test_gymnasium_takes_the_option():
    import gvsjax.gym as gg

    env = gg.GvsjaxEnv(task="gain_test", randomize="gain:0.3", randomize_observe=True)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (2,) and env.observation_space.shape == (2,) and abs(obs[1]) <= 1
    _, _, terminated, _, info = env.step(np.zeros(1, np.float32))
    assert terminated and abs(info["randomize_gain"] - 1) <= 0.3
    assert gg.GvsjaxEnv(task="gain_test").observation_space.shape == (1,)  # its own compiled functions
    raises_naming("'E'", gg.GvsjaxEnv, task="gain_test", randomize="E:0.1")


@pytest.mark.extended
def test_basketball_throws_on_the_drawn_model_equal_an_arm_built_with_it():
    env = make("basketball")
    wrapped = Randomized(env, parse("E:0.2,damping:0.2,payload:0.2", env))
    params = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(3), 4)
    _, state = jax.vmap(wrapped.reset, in_axes=(0, None))(keys, params)
    action = jnp.array([[-0.5, 0.2], [0.0, 0.0], [0.5, -0.3], [0.9, 0.9]])
    _, _, reward, _, info = jax.jit(jax.vmap(wrapped.step, in_axes=(0, 0, 0, None)))(keys, state, action, params)
    f = np.asarray(state.factors)
    arms = jax.tree.map(lambda *x: jnp.stack(x), *[gv.paper_arm(
        youngs_modulus=NOMINAL["youngs_modulus"] * e, damping=NOMINAL["damping"] * d, tip_force=BALL_WEIGHT * p)
        for e, d, p in f])
    throw = lambda k, s, a, arm: env.step(k, s, a, params.replace(arm=arm))  # noqa: E731
    _, _, want, _, want_info = jax.jit(jax.vmap(throw))(keys, state.inner, action, arms)
    assert np.allclose(info["cost"], want_info["cost"], rtol=0, atol=1e-10)
    assert np.allclose(reward, want, rtol=0, atol=1e-12)
