"""The simulation driver (gvsjax.core.simulation, its argument checks in gvsjax.core.inputs and the step
limit of gvsjax.core.stability): bad arguments raise a ValueError naming them before anything
compiles, a step beyond the stability limit is refused (also inside ``jit``), a rejected call
adds no compiled program, ``simulate`` works under ``jit``/``vmap``/``grad`` (gradients equal
central differences), and random physical parameters give finite states and gradients."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import importlib
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import FAST, nan_inf, not_positive, raises_naming
from hypothesis import example, given, settings
from hypothesis import strategies as st

from gvsjax.core.integrators import INTEGRATORS

bad_count = st.one_of(st.integers(max_value=0), st.floats(allow_nan=True), st.booleans(),
                      st.text(max_size=3), st.none())

ARM = gv.paper_arm()  # q = (theta, q1, q2)
TENDON_ARM = gv.paper_arm(tendon_offset=0.025)
THETA_F = math.radians(210.0)

# ----------------------------------------------------------------------------- argument checks

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
@given(case=st.sampled_from(sorted(SIM_BAD)).flatmap(lambda name: st.tuples(st.just(name), SIM_BAD[name])))
@example(case=("duration", dict(duration=-1.0, dt=1e-3)))
@example(case=("dt", dict(duration=1.0, dt=3e-3)))  # does not divide the duration
@example(case=("dt", dict(duration=1.0, dt=-math.inf)))
@example(case=("q0", dict(duration=1.0, dt=1e-3, q0=np.zeros(2))))
@example(case=("qd0", dict(duration=1.0, dt=1e-3, qd0=[0.0, math.nan, 0.0])))
@example(case=("integrator", dict(duration=1.0, dt=1e-3, integrator="rk45")))
@example(case=("save_every", dict(duration=1.0, dt=1e-3, save_every=7)))
@example(case=("base_angle", dict(duration=1.0, dt=1e-3, base_angle=1.0)))
def test_simulate_arguments_invalid(case):
    name, kwargs = case
    raises_naming(name, gv.simulate, ARM, **kwargs)


@FAST
@given(force=st.one_of(
    st.floats(max_value=-1e-9), nan_inf, st.text(max_size=3), st.just([]),
    st.integers(2, 5).map(np.ones),  # one tendon: a (k,) array is the wrong shape
    st.integers(2, 3).map(lambda k: (lambda t: jnp.ones(k)))))
def test_simulate_tendon_force_invalid(force):
    raises_naming("tendon_force", gv.simulate, TENDON_ARM, 1.0, 1e-3, tendon_force=force)


def test_simulate_tendon_force_needs_a_tendon():
    raises_naming("tendon_force", gv.simulate, ARM, 1.0, 1e-3, tendon_force=1.0)


@settings(max_examples=10, deadline=None)
@given(dt=st.sampled_from([0.02, 0.025, 0.05, 0.1, 0.125, 0.2, 0.25, 0.5]))
def test_simulate_step_beyond_stability_is_rejected_before_the_program_compiles(dt):
    # the estimate itself runs a few eager JAX ops (tiny compilations), the simulation never
    sim = importlib.import_module("gvsjax.core.simulation")
    programs = sim._run._cache_size()
    with pytest.raises(ValueError, match=rf"dt={dt}.*stability limit"):
        gv.simulate(ARM, 1.0, dt)
    assert sim._run._cache_size() == programs


def test_imex_has_no_step_limit():
    assert gv.stable_step_estimate(ARM, "imex", np.zeros(ARM.n_dofs)) == math.inf
    traj = gv.simulate(ARM, 1.0, 0.05, integrator="imex")  # refused for rk4 above
    assert np.all(np.isfinite(traj.q))


# ----------------------------------------------------------------------------- jit, vmap, grad


# Two Gauss points (the fewest for two modes): what is checked here does not depend on the
# quadrature, and reverse mode through the scan compiles in half the time of the default five.
SMALL_ARM = dict(tip_force=5.886, n_gauss=2)


def _release_x(T):
    """The paper's throw of duration T, simulated with a concrete dt: the tip's x after 0.2 s."""
    arm = gv.paper_arm(**SMALL_ARM)
    return gv.simulate(arm, 0.2, 1e-3, base_angle=lambda t: THETA_F * (t / T) ** 2, save_every=200).tip[-1, 0]


@pytest.mark.slow
def test_simulate_with_a_concrete_dt_under_jit_vmap_and_grad():
    """With ``dt`` given (not ``n_steps``) the stability check evaluates eagerly inside a trace:
    ``simulate`` works under ``jit(vmap)`` and ``grad``, and still refuses a too-large dt there."""
    h = 1e-5
    T = jnp.array([1.5, 2.0 - h, 2.0, 2.0 + h, 2.5])
    x = np.asarray(jax.jit(jax.vmap(_release_x))(T))
    assert np.all(np.isfinite(x)) and x[0] > x[2] > x[4]  # a faster swing is further along (+x)
    slope = float(jax.grad(_release_x)(2.0))
    assert np.isfinite(slope) and slope < 0
    assert slope == pytest.approx((x[3] - x[1]) / (2 * h), rel=1e-5)
    # the stability limit is still enforced while jit traces
    unstable = lambda T: gv.simulate(gv.paper_arm(**SMALL_ARM), 0.2, 0.1,  # noqa: E731
                                     base_angle=lambda t: THETA_F * (t / T) ** 2).tip[-1, 0]
    with pytest.raises(ValueError, match=r"dt=0\.1 .*stability limit"):
        jax.jit(unstable)(2.0)


def test_traced_inputs_skip_concrete_checks_but_run():
    def tip(E):
        arm = gv.paper_arm(youngs_modulus=E)
        return gv.simulate(arm, 0.2, n_steps=50, base_angle=lambda t: t, save_every=50).tip[-1]

    out = jax.vmap(tip)(jnp.array([4e6, 5e6]))
    assert out.shape == (2, 3) and np.all(np.isfinite(out))


def test_under_jit_the_run_is_traced_into_the_callers_program():
    """Inside a caller's jit (or scan) ``simulate`` traces its run into that program instead of
    calling its own jitted run (which ``vmap`` would trace, then batch in a second pass); eager
    calls and eager ``vmap`` keep the jitted run. Both give the same states."""
    from gvsjax.core import simulation

    seen = []

    def tip(T):
        seen.append(simulation._building_a_program())
        arm = gv.paper_arm(**SMALL_ARM)
        return gv.simulate(arm, 0.2, n_steps=40, base_angle=lambda t: THETA_F * (t / T) ** 2,
                           integrator="ars443", save_every=40, check_stability=False).tip[-1]

    T = jnp.array([1.5, 2.5])
    eager = np.asarray(jax.vmap(tip)(T))
    inline = np.asarray(jax.jit(jax.vmap(tip))(T))
    scanned = np.asarray(jax.lax.scan(lambda c, t: (c, tip(t)), 0.0, T)[1])
    assert seen == [False, True, True]
    assert np.all(np.isfinite(eager))
    np.testing.assert_allclose(inline, eager, rtol=0, atol=1e-12)
    np.testing.assert_allclose(scanned, eager, rtol=0, atol=1e-12)


@pytest.mark.slow
def test_gradients_match_central_differences():
    """Derivatives of the tip with respect to E, damping, tip load and swing, by forward mode
    (4 inputs: it compiles in less than half the time of reverse mode; reverse mode is
    checked against a central difference in the test above and in notebook 01)."""
    def tip_x(params):
        E, eta, P, theta_f = params
        arm = gv.paper_arm(youngs_modulus=E, damping=eta, **{**SMALL_ARM, "tip_force": P})
        traj = gv.simulate(arm, 1.0, n_steps=1000, base_angle=lambda t: theta_f * t**2, save_every=1000)
        return traj.tip[-1, 0] + 0.3 * traj.tip[-1, 1]

    x0 = jnp.array([5e6, 1e5, 5.886, 2.0])
    grad = np.asarray(jax.jit(jax.jacfwd(tip_x))(x0))
    f = jax.jit(tip_x)
    for i in range(4):
        h = 1e-5 * float(x0[i])
        e = jnp.zeros(4).at[i].set(h)
        fd = (float(f(x0 + e)) - float(f(x0 - e))) / (2 * h)
        assert grad[i] == pytest.approx(fd, rel=1e-4, abs=1e-12), i


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


@pytest.mark.extended
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
