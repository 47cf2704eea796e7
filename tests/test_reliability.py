"""Reliability: bad input, non-finite actions and states, non-finite losses,
killed and resumed runs, determinism (issue 6).

The generated bad inputs must fail *before* anything is traced or compiled:
``no_compile`` counts XLA compilations around them (jax.monitoring) and must
see none. The subprocess tests share one killed/resumed run (module fixture).
"""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import csv
import importlib
import json
import math
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gvsjax import checkpoint, train
from gvsjax.integrators import INTEGRATORS
from gvsjax.ppo import FIELD_DOCS
from gvsjax.tasks import base
from gvsjax.tasks import pickplace as pp

FAST = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])

_COMPILES = [0]


def _on_event(event, duration, **kwargs):
    if event == "/jax/core/compile/backend_compile_duration":
        _COMPILES[0] += 1


jax.monitoring.register_event_duration_secs_listener(_on_event)


@contextmanager
def no_compile():
    """Fail if XLA compiles anything inside the block."""
    before = _COMPILES[0]
    yield
    assert _COMPILES[0] == before, f"{_COMPILES[0] - before} compilation(s) before the error"


def raises_naming(name, fn, /, *args, exc=ValueError, **kwargs):
    """``fn(*args, **kwargs)`` raises ``exc`` whose message contains ``name``; no compilation.
    (For arbitrary keyword names, e.g. generated ones, pass a closure: a key "exc" would land here.)"""
    with no_compile(), pytest.raises(exc) as info:
        fn(*args, **kwargs)
    assert name in str(info.value), f"{name!r} not in {str(info.value)!r}"
    return str(info.value)


# ----------------------------------------------------------------------------- value strategies

nan_inf = st.sampled_from([math.nan, math.inf, -math.inf])
not_a_number = st.one_of(st.text(max_size=5), st.none(), st.booleans(), st.just([]),
                         st.just({"a": 1}), st.just(object()))
not_positive = st.one_of(st.floats(max_value=0.0, allow_nan=False), st.integers(max_value=0), nan_inf,
                         not_a_number)
negative = st.one_of(st.floats(max_value=-1e-12, allow_nan=False), st.integers(max_value=-1),
                     st.just(math.nan), st.just(math.inf), not_a_number)
not_finite = st.one_of(nan_inf, not_a_number)
bad_count = st.one_of(st.integers(max_value=0), st.floats(allow_nan=True), st.booleans(),
                      st.text(max_size=3), st.none())

ARM_BAD = {
    **{k: not_positive for k in ("length", "radius", "youngs_modulus", "density")},
    **{k: negative for k in ("damping", "gravity", "tip_mass")},
    "tip_force": not_finite,
    "n_modes": bad_count,
    "n_gauss": bad_count,
    "basis": st.one_of(st.text(max_size=8).filter(lambda s: s not in ("monomial", "legendre")),
                       st.integers(), st.none()),
    "poisson": st.one_of(st.floats(min_value=0.5, exclude_min=True, allow_nan=False),
                         st.floats(max_value=-1.0, allow_nan=False), st.just(math.nan), not_a_number),
    "tendon_offset": st.one_of(st.floats(min_value=0.0501, allow_nan=False, allow_infinity=False),
                               st.floats(max_value=-0.0501, allow_nan=False, allow_infinity=False),
                               nan_inf, not_a_number.filter(lambda v: v is not None)),
}


@FAST
@given(data=st.data(), name=st.sampled_from(sorted(ARM_BAD)))
def test_paper_arm_overrides_invalid(data, name):
    value = data.draw(ARM_BAD[name], label=name)
    raises_naming(name, gv.paper_arm, **{name: value})


@FAST
@given(key=st.text("abcdefghijklmnopqrstuvwxyz_", min_size=1, max_size=12).filter(
    lambda k: k not in gv.PAPER_ARM))
def test_paper_arm_unknown_override_lists_the_valid_keys(key):
    # a closure, so that generated keys such as "fn" or "exc" reach paper_arm, not the helper
    message = raises_naming(key, lambda: gv.paper_arm(**{key: 1.0}))
    assert "youngs_modulus" in message


ROD_BAD = {
    **{k: not_positive for k in ("length", "radius", "youngs_modulus", "density")},
    **{k: negative for k in ("damping", "gravity")},
    "order": st.one_of(st.integers(max_value=-1), st.floats(), st.booleans(),
                       st.lists(st.integers(-1, 3), max_size=5),  # not six entries
                       st.just((-1,) * 6), st.just((0, 1, 2, 3, 4, -2))),
    "n_gauss": st.one_of(st.integers(max_value=1), st.floats(), st.booleans(), st.none()),
    "basis": st.text(max_size=8).filter(lambda s: s not in ("monomial", "legendre")),
}


@FAST
@given(data=st.data(), name=st.sampled_from(sorted(ROD_BAD)))
def test_rod_3d_invalid(data, name):
    value = data.draw(ROD_BAD[name], label=name)
    raises_naming(name, gv.rod_3d, **{name: value})


ARM = gv.paper_arm()  # q = (theta, q1, q2)
TENDON_ARM = gv.paper_arm(tendon_offset=0.025)

# Each entry: strategy of (simulate kwargs) that is invalid because of the named argument.
SIM_BAD = {
    "duration": st.builds(lambda d: dict(duration=d, dt=1e-3), not_positive),
    "dt": st.builds(lambda d: dict(duration=1.0, dt=d), st.one_of(
        not_positive.filter(lambda v: v is not None),  # dt=None is "give n_steps"
        st.floats(min_value=1e-4, max_value=0.5).filter(lambda d: abs(round(1 / d) * d - 1) > 1e-6))),
    "n_steps": st.builds(lambda k: dict(duration=1.0, n_steps=k), bad_count.filter(lambda v: v is not None)),
    "integrator": st.builds(lambda i: dict(duration=1.0, dt=1e-3, integrator=i),
                            st.one_of(st.text(max_size=6).filter(lambda s: s not in INTEGRATORS),
                                      st.integers(), st.just(["rk4"]), st.none())),
    "save_every": st.builds(lambda k: dict(duration=1.0, dt=1e-3, save_every=k), st.one_of(
        st.integers(max_value=0), st.integers(1, 999).filter(lambda k: 1000 % k), st.booleans(),
        st.floats(), st.none())),
    "q0": st.builds(lambda q: dict(duration=1.0, dt=1e-3, q0=q), st.one_of(
        st.integers(0, 6).filter(lambda n: n != 3).map(np.zeros),
        st.just(np.zeros((3, 1))), st.just([0.0, math.nan, 0.0]), st.just([0.0, 0.0, math.inf]),
        st.just("abc"), st.just([[0.0], [1.0, 2.0]]))),
    "qd0": st.builds(lambda q: dict(duration=1.0, dt=1e-3, qd0=q), st.one_of(
        st.integers(0, 6).filter(lambda n: n != 3).map(np.ones), st.just([math.nan] * 3))),
    "base_angle": st.builds(lambda b: dict(duration=1.0, dt=1e-3, base_angle=b), st.one_of(
        st.floats(), st.text(max_size=3),
        st.integers(2, 4).map(lambda k: (lambda t: jnp.ones(k) * t)))),  # callable, wrong output shape
}


@FAST
@given(data=st.data(), name=st.sampled_from(sorted(SIM_BAD)))
def test_simulate_arguments_invalid(data, name):
    kwargs = data.draw(SIM_BAD[name], label=name)
    raises_naming(name, gv.simulate, ARM, **kwargs)


@FAST
@given(force=st.one_of(
    st.floats(max_value=-1e-9), nan_inf, st.text(max_size=3), st.just([]),
    st.integers(2, 5).map(np.ones),  # one tendon: a (k,) array is the wrong shape
    st.integers(2, 3).map(lambda k: (lambda t: jnp.ones(k)))))
def test_simulate_tendon_force_invalid(force):
    raises_naming("tendon_force", gv.simulate, TENDON_ARM, 1.0, 1e-3, tendon_force=force)


@settings(max_examples=10, deadline=None)
@given(dt=st.sampled_from([0.02, 0.025, 0.05, 0.1, 0.125, 0.2, 0.25, 0.5]))
def test_simulate_step_beyond_stability_is_rejected_before_the_program_compiles(dt):
    # the estimate itself runs a few eager JAX ops (tiny compilations), the simulation never
    sim = importlib.import_module("gvsjax.simulate")  # the module (gvsjax.simulate is the function)
    programs = sim._run._cache_size()
    with pytest.raises(ValueError, match=r"dt=.*stability limit"):
        gv.simulate(ARM, 1.0, dt)
    assert sim._run._cache_size() == programs


def test_simulate_tendon_force_needs_a_tendon():
    raises_naming("tendon_force", gv.simulate, ARM, 1.0, 1e-3, tendon_force=1.0)


# ----------------------------------------------------------------------------- env actions

PICK_PARAMS = pp.PickPlaceParams(arm=TENDON_ARM)  # no target tables: step does not read them


def _pick_state():
    return pp._reset_state(jnp.asarray([[0.5, -0.8], [-0.5, -0.8]]))


@FAST
@given(shape=st.lists(st.integers(0, 3), max_size=3).map(tuple).filter(lambda s: s != (2,)))
def test_env_action_of_wrong_shape_is_rejected_while_tracing(shape):
    env = pp.PickPlace()
    step = lambda a: env.step(jax.random.PRNGKey(0), _pick_state(), a, PICK_PARAMS)  # noqa: E731
    with no_compile(), pytest.raises(ValueError, match=r"action has shape .* expected \(2,\)"):
        jax.eval_shape(step, jax.ShapeDtypeStruct(shape, jnp.float64))


def test_sanitize_action_policy():
    a, ok = base.sanitize_action(jnp.array([0.3, -0.2]), 2)
    assert bool(ok) and np.array_equal(a, [0.3, -0.2])
    for bad in ([math.nan, 0.5], [0.1, math.inf], [-math.inf, math.nan]):
        a, ok = base.sanitize_action(jnp.array(bad), 2)
        assert not bool(ok) and np.array_equal(a, [0.0, 0.0])
    a, ok = base.sanitize_action(jnp.array([1, -1]), 2)  # ints are cast, not rejected
    assert bool(ok) and jnp.issubdtype(a.dtype, jnp.floating)
    assert bool(base.bounded(jnp.array([1.0, -2.0]), 2.0))
    for x in ([2.5, 0.0], [math.nan, 0.0], [math.inf, 0.0]):
        assert not bool(base.bounded(jnp.array(x), 2.0))


# ----------------------------------------------------------------------------- command line

INT_FIELDS = [k for k in FIELD_DOCS if isinstance(getattr(train.PPOConfig(), k), int)
              and not isinstance(getattr(train.PPOConfig(), k), bool)]
FLOAT_FIELDS = [k for k in FIELD_DOCS if isinstance(getattr(train.PPOConfig(), k), float)]
BOOL_FIELDS = [k for k in FIELD_DOCS if isinstance(getattr(train.PPOConfig(), k), bool)]
CHOICE_FIELDS = {"network": ("shared", "separate"), "activation": ("relu", "tanh"),
                 "std_mode": ("learned", "network")}
SIZES_FIELDS = ["shared_hidden", "actor_hidden", "critic_hidden"]
junk = st.text(alphabet="xyz!@#% ", min_size=1, max_size=6)


def _bad_ppo(name):
    if name == "seed":  # jax.random.PRNGKey overflows at 2**63
        return st.one_of(junk, st.sampled_from(["1.5", "nan", "-1", "1e30", str(2**63), str(2**64)]))
    if name in INT_FIELDS:
        return st.one_of(junk, st.sampled_from(["1.5", "nan", "inf", "-1", "1e400"]))
    if name in FLOAT_FIELDS:  # every float field rejects NaN and -inf
        return st.one_of(junk, st.sampled_from(["nan", "-inf", "--1", "1,2"]))
    if name in BOOL_FIELDS:
        return st.one_of(junk, st.sampled_from(["2", "maybe", ""]))
    if name in CHOICE_FIELDS:
        return st.text(max_size=8).filter(lambda s: s.strip() not in CHOICE_FIELDS[name])
    return st.one_of(junk, st.sampled_from(["", "0", "-4,8", "8,0", "1.5,2", "()"]))


RUN_BAD = {
    "checkpoint_every": st.sampled_from(["nan", "-1", "x", ""]),
    "eval_targets": st.sampled_from(["-1", "1.5", "x"]),
    "eval_seed": st.sampled_from(["-2", "1.5", "x"]),
    "updates_per_call": st.sampled_from(["-3", "x"]),
    "resume": st.sampled_from(["maybe", "2", ""]),
    "progress": st.sampled_from(["maybe", "2", ""]),
    "task": junk,
    "preset": junk,
}


@FAST
@given(data=st.data(), name=st.sampled_from(sorted(FIELD_DOCS)))
def test_cli_invalid_ppo_value_names_the_key(data, name):
    text = data.draw(_bad_ppo(name), label=name)

    def parse_and_build():
        run, overrides = train.parse_args(["task=basketball", f"{name}={text}"])
        train.build_config(run["task"], run["preset"], overrides)

    raises_naming(name, parse_and_build)


@FAST
@given(data=st.data(), name=st.sampled_from(sorted(RUN_BAD)))
def test_cli_invalid_run_option_names_the_key(data, name):
    text = data.draw(RUN_BAD[name], label=name)
    raises_naming(name, train.parse_args, [f"{name}={text}"])


@FAST
@given(word=st.text(max_size=12))
def test_cli_word_without_equals_or_unknown_key(word):
    key = word.partition("=")[0].strip()
    if "=" in word and (key in train.RUN_DOCS or key in FIELD_DOCS):
        return  # a known key: covered above
    message = raises_naming("", train.parse_args, [word])
    assert "key=value" in message or "unknown key" in message


def test_cli_resume_needs_out_and_main_exits_2(capsys):
    raises_naming("out", train.parse_args, ["resume=true"])
    assert train.main(["resume=true"]) == 2
    assert "out=" in capsys.readouterr().err


# ----------------------------------------------------------------------------- config files


@FAST
@given(data=st.data(), name=st.sampled_from(sorted(FIELD_DOCS)))
def test_saved_config_with_a_garbled_value_names_the_key(data, name):
    value = data.draw(st.one_of(st.text(max_size=4), st.none(), st.just([[1]]), st.just({"x": 1}))
                      .filter(lambda v: not (isinstance(v, str) and name in CHOICE_FIELDS
                                             and v in CHOICE_FIELDS[name])))
    config = {**train.dataclasses.asdict(train.PPOConfig()), name: value}
    message = raises_naming(name, train.config_from_json, config, "the config saved in X")
    assert "saved in X" in message


def test_saved_config_unknown_key_or_not_an_object():
    raises_naming("bogus", train.config_from_json, {"bogus": 1})
    raises_naming("JSON object", train.config_from_json, [1, 2])
    assert train.config_from_json({"task": "basketball", "preset": "paper"}) == train.PPOConfig()


# ----------------------------------------------------------------------------- checkpoint files


@pytest.fixture(scope="module")
def good_checkpoint(tmp_path_factory):
    path = tmp_path_factory.mktemp("ckpt") / "checkpoint.ckpt"
    state = {"w": jnp.arange(6.0).reshape(2, 3), "n": jnp.asarray(7, jnp.int32)}
    checkpoint.save(path, state, {"num_envs": 4}, "basketball", 7)
    return path, path.read_bytes(), state


def test_checkpoint_missing_or_a_directory(tmp_path):
    raises_naming("does not exist", checkpoint.load_raw, tmp_path / "nope.ckpt",
                  exc=checkpoint.CheckpointError)
    raises_naming("is a directory", checkpoint.load_raw, tmp_path, exc=checkpoint.CheckpointError)


@settings(max_examples=50, deadline=None)
@given(data=st.data())
def test_checkpoint_truncated_or_flipped_bytes_are_detected(good_checkpoint, tmp_path_factory, data):
    path, blob, _ = good_checkpoint
    if data.draw(st.booleans(), label="truncate"):
        cut = data.draw(st.integers(0, len(blob) - 1), label="length")
        bad = blob[:cut]
    else:
        at = data.draw(st.integers(0, len(blob) - 1), label="position")
        flip = data.draw(st.integers(1, 255), label="xor")
        bad = blob[:at] + bytes([blob[at] ^ flip]) + blob[at + 1:]
    target = tmp_path_factory.mktemp("bad") / "checkpoint.ckpt"
    target.write_bytes(bad)
    message = raises_naming(str(target), checkpoint.load_raw, target, exc=checkpoint.CheckpointError)
    assert any(w in message for w in ("truncated", "corrupted", "malformed"))


def test_checkpoint_of_another_shape_is_refused(good_checkpoint):
    path, _, state = good_checkpoint
    loaded, meta = checkpoint.load(path, jax.tree.map(jnp.zeros_like, state))
    assert meta["step"] == 7 and np.array_equal(loaded["w"], state["w"])
    raises_naming("shape", checkpoint.load, path, {"w": jnp.zeros((3, 3)), "n": jnp.zeros((), jnp.int32)},
                  exc=checkpoint.CheckpointError)
    raises_naming("does not match", checkpoint.load, path, {"v": jnp.zeros(2)}, exc=checkpoint.CheckpointError)


# ----------------------------------------------------------------------------- non-finite actions, divergence


def _pick_step(params):
    env = pp.PickPlace()
    return jax.jit(jax.vmap(lambda s, a: env.step(jax.random.PRNGKey(0), s, a, params), in_axes=(None, 0)))


def test_pickplace_non_finite_action_is_replaced_by_the_centre_and_flagged():
    actions = jnp.array([[math.nan, 0.5], [0.2, math.inf], [-math.inf, math.nan], [0.3, -0.4]])
    obs, state, reward, done, info = _pick_step(PICK_PARAMS)(_pick_state(), actions)
    assert info["valid"].tolist() == [False, False, False, True]
    assert done[:3].all() and np.array_equal(reward[:3], [0.0, 0.0, 0.0]) and reward[3] > 0
    # the simulated action was the centre of the box: theta_F = 0, tension = 15 N
    np.testing.assert_array_equal(info["theta_final"][:3], 0.0)
    np.testing.assert_array_equal(info["tension"][:3], PICK_PARAMS.tension_max / 2)
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(state.q))


def test_pickplace_blow_up_is_flagged_even_while_finite():
    # 300 RK4 steps per 5 s step: dt = 16.7 ms, above the 13.9 ms stability limit; the
    # integration grows without reaching inf, so only the magnitude bound can catch it
    params = pp.PickPlaceParams(arm=TENDON_ARM, n_steps=300, integrator="rk4")
    action = jnp.array([[1.0 / math.pi, -1.0 / 3.0]])  # theta_F = 1 rad, 10 N

    @jax.jit
    def run(state, action):
        out = jax.vmap(lambda a: pp.PickPlace().step(jax.random.PRNGKey(0), state, a, params))(action)
        theta, tension = pp.action_to_physical(action[0], params)
        return out, pp.run_step(params, state.q, state.qd, state.tension, theta, tension)

    (_, _, reward, done, info), traj = run(_pick_state(), action)
    q, qd = np.asarray(traj.q[-1]), np.asarray(traj.qd[-1])
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(qd))
    assert np.max(np.abs(qd)) > pp.PickPlace.qd_bound  # blown up (a sane step stays below 3)
    assert not bool(info["valid"][0]) and bool(done[0]) and float(reward[0]) == 0.0


def test_basketball_non_finite_action_policy():
    from gvsjax.tasks import basketball as bb

    params = bb.BasketballParams(arm=gv.paper_arm(tip_force=bb.BALL_WEIGHT))  # no target tables
    state = bb.BasketballState(target=jnp.array([-5.0, 1.0]), source_action=jnp.zeros(2),
                               step=jnp.zeros((), jnp.int32))
    env = bb.Basketball()
    with no_compile(), pytest.raises(ValueError, match="action has shape"):
        jax.eval_shape(lambda a: env.step(jax.random.PRNGKey(0), state, a, params),
                       jax.ShapeDtypeStruct((3,), jnp.float64))
    step = jax.jit(jax.vmap(lambda a: env.step(jax.random.PRNGKey(0), state, a, params)))
    _, _, reward, done, info = step(jnp.array([[math.nan, 0.0], [0.0, 0.0]]))
    assert info["valid"].tolist() == [False, True] and done.all() and float(reward[0]) == 0.0
    assert float(info["T"][0]) == float(info["T"][1])  # the NaN action was thrown as the centre


# ----------------------------------------------------------------------------- physical fuzz

# Swept ranges (SI): a 30 cm - 2 m rod, 1-10 cm radius, rubber to stiff polymer, light to heavy.
PHYS = {"length": (0.3, 2.0), "radius": (0.01, 0.1), "youngs_modulus": (1e5, 1e8),
        "density": (300.0, 3000.0), "damping": (0.0, 1e6), "tip_force": (-20.0, 20.0),
        "tip_mass": (0.0, 1.0), "gravity": (0.0, 20.0)}
FUZZ_STEPS = 200


@jax.jit
def _fuzz(p, action, duration):
    """Finite-state and straight-configuration checks for one parameter set (all traced: one compile)."""
    arm = gv.paper_arm(tendon_offset=0.5 * p["radius"], **p)
    theta_f, tension = jnp.pi * action[0], 10.0 * (action[1] + 1.0)
    traj = gv.simulate(arm, duration, n_steps=FUZZ_STEPS, save_every=FUZZ_STEPS // 4,
                       base_angle=lambda t: theta_f * (t / duration) ** 2, tendon_force=tension,
                       check_stability=False)
    zero = jnp.zeros(arm.n_dofs)
    d_tip = jax.jacfwd(lambda q: gv.tip_state(arm, q, zero)[0])(zero)
    d_energy = jax.grad(lambda q: sum(gv.energy(arm, q, zero).values()))(zero)
    d_params = jax.grad(lambda p: gv.tip_state(gv.paper_arm(**p), zero, zero)[0][1]
                        + sum(gv.energy(gv.paper_arm(**p), zero, zero).values()))(p)
    return traj, d_tip, d_energy, d_params


@settings(max_examples=20, deadline=None)
@given(p=st.fixed_dictionaries({k: st.floats(*r) for k, r in PHYS.items()}),
       action=st.tuples(st.floats(-1, 1), st.floats(-1, 1)))
def test_physical_parameter_fuzz_finite_states_and_gradients(p, action):
    arm = gv.paper_arm(tendon_offset=0.5 * p["radius"], **p)  # concrete: validated, in range
    limit = gv.stable_step_estimate(arm, "rk4", np.zeros(arm.n_dofs))
    duration = min(1.0, 0.5 * limit * FUZZ_STEPS)  # half the RK4 limit: stability is not what we test
    traj, d_tip, d_energy, d_params = _fuzz({k: jnp.float64(v) for k, v in p.items()}, jnp.array(action),
                                            jnp.float64(duration))
    for name, x in [("q", traj.q), ("qd", traj.qd), ("tip", traj.tip), ("joint_torque", traj.joint_torque),
                    ("d tip / d q at q = 0", d_tip), ("d energy / d q at q = 0", d_energy),
                    *[(f"d (tip_y + energy) / d {k}", v) for k, v in d_params.items()]]:
        assert np.all(np.isfinite(np.asarray(x))), f"{name} not finite for {p}, action {action}"
    # the tip stays on the rod: no stretch in this model, so |tip| <= length
    assert np.max(np.linalg.norm(np.asarray(traj.tip), axis=-1)) <= p["length"] * (1 + 1e-9)


# ----------------------------------------------------------------------------- non-finite training


@pytest.fixture
def bandit_tasks(monkeypatch):
    """Registers the test bandit ("bandit") and one whose reward is NaN on 1% of valid steps."""
    from bandit_env import BanditEnv

    class NanBandit(BanditEnv):
        name = "nanbandit"

        def step(self, key, state, action, params):
            obs, new, reward, done, info = super().step(key, state, action, params)
            return obs, new, jnp.where(state.target[0] > 0.98, jnp.nan, reward), done, info

    monkeypatch.setitem(base._REGISTRY, "bandit", BanditEnv)
    monkeypatch.setitem(base._REGISTRY, "nanbandit", NanBandit)


BANDIT = ["num_envs=16", "num_minibatches=2", "update_epochs=1", "total_episodes=960",
          "progress=false", "eval_targets=0", "updates_per_call=1", "checkpoint_every=1e9"]


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_nan_loss_stops_training_and_keeps_the_last_good_checkpoint(bandit_tasks, tmp_path, capsys):
    out = tmp_path / "nan"
    assert train.main(["task=nanbandit", f"out={out}"] + BANDIT) == 3
    err = capsys.readouterr().err
    assert "training stopped: metric" in err and "=nan at update" in err and str(out / "checkpoint.ckpt") in err
    bad_update = int(err.split("=nan at update ")[1].split(".")[0].split()[0])
    assert 0 < bad_update < 60  # NaN rewards on ~1% of steps: it fails early, not at update 0
    rows = _rows(out / "metrics.csv")
    assert [int(r["update"]) for r in rows] == list(range(bad_update + 1))
    assert math.isnan(float(rows[-1]["loss"])) and all(math.isfinite(float(r["loss"])) for r in rows[:-1])
    meta = checkpoint.load_raw(out / "checkpoint.ckpt")
    assert meta["step"] == bad_update  # the state before the failing update, saved on the way out
    assert not (out / "timing.json").exists()
    config = train.config_from_json(meta["config"])
    from bandit_env import BanditEnv

    from gvsjax.ppo import init

    template = init(config, BanditEnv(), BanditEnv().default_params(), jax.random.PRNGKey(0))
    state = checkpoint.restore_state(template, meta["train_state"])
    assert all(np.all(np.isfinite(x)) for x in jax.tree.leaves(state.params))


def test_non_finite_weights_stop_training(bandit_tasks, tmp_path, capsys, monkeypatch):
    real = train._update_fn
    calls = []

    def poisoned(*args, **kwargs):
        step = real(*args, **kwargs)

        def run(state):
            state, metrics = step(state)
            calls.append(1)
            if len(calls) == 3:  # metrics stay finite, one weight does not
                state = state.replace(params=jax.tree.map(lambda x: x.at[(0,) * x.ndim].set(jnp.inf),
                                                          state.params))
            return state, metrics

        return run

    monkeypatch.setattr(train, "_update_fn", poisoned)
    out = tmp_path / "inf"
    assert train.main(["task=bandit", f"out={out}", "checkpoint_every=0"] + BANDIT[:-1]) == 3
    err = capsys.readouterr().err
    assert "params" in err and "non-finite by update 2" in err
    assert checkpoint.load_raw(out / "checkpoint.ckpt")["step"] == 2  # saved after call 2, kept


# ----------------------------------------------------------------------------- killed, resumed, repeated runs

ROOT = Path(__file__).resolve().parents[1]
N_UPDATES = 150  # 16 throws each, a checkpoint after every one; b is killed past the middle
SUB = ["task=basketball", "num_envs=16", "num_minibatches=2", "update_epochs=1",
       f"total_episodes={16 * N_UPDATES}", "progress=false", "eval_targets=0", "updates_per_call=1",
       "checkpoint_every=0", "seed=5"]


def _start(out, *extra):
    return subprocess.Popen([sys.executable, "-m", "gvsjax.train", *SUB, f"out={out}", *extra], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish(proc, timeout=900):
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out + err


def _saved_step(path):
    try:
        return checkpoint.load_raw(path)["step"]
    except checkpoint.CheckpointError:  # not written yet
        return -1


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two trainings of one config started together: a runs through; b is SIGKILLed once its
    checkpoint is past the middle (config.json then garbled) and resumed to the end."""
    root = tmp_path_factory.mktemp("runs")
    procs = {name: _start(root / name) for name in "ab"}
    ckpt = root / "b" / "checkpoint.ckpt"
    deadline = time.monotonic() + 900
    while _saved_step(ckpt) < N_UPDATES // 2:
        if procs["b"].poll() is not None:
            pytest.fail(f"run b ended before the kill: {_finish(procs['b'])}")
        assert time.monotonic() < deadline, "run b did not reach the middle in 900 s"
        time.sleep(0.01)
    running = procs["b"].poll() is None
    os.kill(procs["b"].pid, signal.SIGKILL)
    killed = _finish(procs["b"])
    info = {"running_at_kill": running, "killed_rc": killed[0],
            "killed_step": checkpoint.load_raw(ckpt)["step"],
            "rows_at_kill": _complete_rows(root / "b" / "metrics.csv")}
    (root / "b" / "config.json").write_text('{"num_envs": 1, garbled')  # resume must not read it
    procs["b"] = _start(root / "b", "resume=true")
    info["done"] = {name: _finish(p) for name, p in procs.items()}
    return root, info


def _complete_rows(path):
    """Rows of a CSV a kill may have cut inside its last line (that line is left out)."""
    text = path.read_text()
    return list(csv.DictReader(text[: text.rfind("\n") + 1].splitlines()))


def _comparable(rows):
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in rows]


def test_killed_run_resumes_and_completes(runs):
    root, info = runs
    for name, (rc, text) in info["done"].items():
        assert rc == 0, f"run {name}: exit {rc}\n{text}"
    assert info["running_at_kill"] and info["killed_rc"] == -signal.SIGKILL
    assert N_UPDATES // 2 <= info["killed_step"] < N_UPDATES  # killed mid-run
    b = root / "b"
    assert checkpoint.load_raw(b / "checkpoint.ckpt")["step"] == N_UPDATES
    updates = [int(r["update"]) for r in _rows(b / "metrics.csv")]
    assert updates == list(range(N_UPDATES))  # every update once: rows past the checkpoint were dropped
    assert json.loads((b / "config.json").read_text())["num_envs"] == 16  # rewritten from the checkpoint
    assert not list(b.glob(".*.tmp"))
    assert json.loads((b / "timing.json").read_text())["updates"] == N_UPDATES


def test_resumed_run_is_bit_identical_to_an_uninterrupted_one(runs):
    root, _ = runs
    a, b = root / "a", root / "b"
    assert _comparable(_rows(b / "metrics.csv")) == _comparable(_rows(a / "metrics.csv"))
    assert (checkpoint.load_raw(b / "checkpoint.ckpt")["train_state"]
            == checkpoint.load_raw(a / "checkpoint.ckpt")["train_state"])  # weights, Adam, key, envs


def test_same_config_and_seed_give_bit_identical_runs(runs):
    # b's rows up to the kill (over half the run) came from another process than a's
    root, info = runs
    before = _comparable(info["rows_at_kill"])
    rows = _comparable(_rows(root / "a" / "metrics.csv"))
    assert len(before) >= N_UPDATES // 2 and len(rows) == N_UPDATES
    assert before == rows[: len(before)]


@pytest.mark.parametrize("damage", ["truncate", "flip"])
def test_resume_from_a_damaged_checkpoint_is_a_clear_error(runs, tmp_path, capsys, damage):
    import shutil

    root, _ = runs
    run = tmp_path / "b"
    shutil.copytree(root / "b", run)
    blob = (run / "checkpoint.ckpt").read_bytes()
    if damage == "truncate":
        blob = blob[: len(blob) * 2 // 3]
    else:
        blob = blob[:-100] + bytes([blob[-100] ^ 0x5A]) + blob[-99:]
    (run / "checkpoint.ckpt").write_bytes(blob)
    with no_compile():
        rc = train.main(SUB + [f"out={run}", "resume=true", f"total_episodes={32 * N_UPDATES}"])
    err = capsys.readouterr().err
    assert rc == 2 and str(run / "checkpoint.ckpt") in err
    assert ("truncated" in err) if damage == "truncate" else ("corrupted" in err)
