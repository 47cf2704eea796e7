"""The integrators (gvsjax.core.integrators): each converges at its documented order on the fast throw;
the ARS(4,4,3) tableau meets the order conditions and stays accurate beyond RK4's step limit."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import functools
from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax.core import integrators
from gvsjax.core.system import FreeDynamics

THETA_F, T = np.deg2rad(210.0), 0.5
ARM = gv.paper_arm(tip_force=5.886)


@functools.partial(jax.jit, static_argnames="integrator")
def _release_tip(integrator, n_steps, duration):
    """The tip after ``n_steps`` steps of the named integrator on the swing of ``duration``.
    The step count is traced, so one program per integrator serves every resolution."""
    system = FreeDynamics(ARM, lambda t: jnp.atleast_1d(THETA_F * (t / duration) ** 2))
    step = integrators.get(integrator).step
    dt = duration / n_steps
    zero = tuple(jnp.zeros((), jnp.float64) for _ in ARM.free)

    def body(k, state):
        return step(system, k * dt, *state, dt)

    q_u, qd_u = jax.lax.fori_loop(0, n_steps, body, (zero, zero))
    q, qd, _ = system.full_state(duration, q_u, qd_u)
    return gv.tip_state(ARM, jnp.stack(q), jnp.stack(qd))[0]


def release_tip(integrator, n_steps, duration=T):
    return np.asarray(_release_tip(integrator, n_steps, duration))


REFERENCE = None


def reference():
    global REFERENCE
    if REFERENCE is None:
        REFERENCE = release_tip("rk4", 4000)
    return REFERENCE


@pytest.mark.parametrize("integrator, order, n", [("rk4", 4, 100), ("midpoint", 2, 400),
                                                  ("euler", 1, 800), ("imex", 1, 800),
                                                  ("ars443", 3, 800), ("ars443_frozen_mass", 1, 800)])
def test_observed_order(integrator, order, n):
    e1 = np.linalg.norm(release_tip(integrator, n) - reference())
    e2 = np.linalg.norm(release_tip(integrator, 2 * n) - reference())
    observed = np.log2(e1 / e2)
    assert observed == pytest.approx(order, abs=0.35), (e1, e2)


def test_ars443_tableau_order_conditions():
    """The stored ARS(4,4,3) pair meets every order-1..3 condition of an additive RK
    method, checked against the paper's rational entries (diagonal 1/2 restored)."""
    E = np.zeros((5, 5))
    E[1:, :4] = np.asarray(integrators._ARS443_E)
    I = np.zeros((5, 5))
    I[1:, :4] = np.asarray(integrators._ARS443_I)
    I[1:, 1:] += 0.5 * np.eye(4)
    rational_I = [[0, 0, 0, 0, 0], [0, Fraction(1, 2), 0, 0, 0], [0, Fraction(1, 6), Fraction(1, 2), 0, 0],
                  [0, Fraction(-1, 2), Fraction(1, 2), Fraction(1, 2), 0],
                  [0, Fraction(3, 2), Fraction(-3, 2), Fraction(1, 2), Fraction(1, 2)]]
    np.testing.assert_allclose(I, np.array(rational_I, dtype=float), atol=1e-15)
    c = E.sum(1)
    np.testing.assert_allclose(I.sum(1), c, atol=1e-15)  # same abscissae in both halves
    np.testing.assert_allclose(c[1:], np.asarray(integrators._ARS443_C), atol=1e-15)
    bE, bI = E[4], I[4]  # stiffly accurate: the step is the last stage
    for b in (bE, bI):
        assert b.sum() == pytest.approx(1.0, abs=1e-14)
        assert b @ c == pytest.approx(1 / 2, abs=1e-14)
        assert b @ c**2 == pytest.approx(1 / 3, abs=1e-14)
        for A in (E, I):
            assert b @ A @ c == pytest.approx(1 / 6, abs=1e-14)


def test_ars443_beyond_rk4_stability():
    """At 75 ms steps (5.4x RK4's limit on this arm) ARS(4,4,3) stays within 1 mm of a
    converged RK4 run on the slowest throw, where RK4 itself diverges."""
    T3 = 3.0
    tip = lambda integrator, n: release_tip(integrator, n, T3)  # noqa: E731
    ref = tip("rk4", 3000)
    assert np.linalg.norm(tip("ars443", 40) - ref) < 1e-3
    q0 = np.zeros(ARM.n_dofs)
    assert gv.stable_step_estimate(ARM, "ars443", q0) == np.inf  # so simulate accepts dt = 75 ms
    assert gv.stable_step_estimate(ARM, "rk4", q0) < T3 / 40
    assert not np.linalg.norm(tip("rk4", 40) - ref) < 1.0  # RK4 at the same step: diverged (nan) or far off


@pytest.mark.parametrize("robot", [gv.paper_arm(tip_force=5.886),
                                   pytest.param(gv.rod_3d(order=(0, 0, 0, -1, -1, -1), n_gauss=2, gravity=9.81),
                                                marks=pytest.mark.extended)],
                         ids=["paper_arm_prescribed_base", "twisting_bending_rod"])
def test_ars443_layouts_are_one_scheme(robot):
    """``ars443`` picks a loop layout by the number of free DoFs (split, folded, folded with
    stacked arrays); all must be the same arithmetic: one step from a moving state agrees
    to rounding."""
    law = lambda t: jnp.array([1.2 * t**2]) if robot.prescribed else jnp.zeros(0)  # noqa: E731
    system = FreeDynamics(robot, law)
    rng = np.random.default_rng(3)
    n = len(robot.free)
    q = tuple(jnp.asarray(x) for x in 0.3 * rng.normal(size=n))
    qd = tuple(jnp.asarray(x) for x in rng.normal(size=n))
    t, dt = jnp.asarray(0.4), 0.02
    def one_step(fn):
        return jax.jit(lambda q, qd: fn(system, t, q, qd, dt))(q, qd)

    for frozen in (False, True):  # ars443, ars443_frozen_mass
        a, b, c = (np.concatenate([np.stack(x) for x in one_step(functools.partial(fn, frozen_mass=frozen))])
                   for fn in (integrators._ars443_folded, integrators._ars443_split, integrators._ars443_stacked))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * np.abs(b).max())
        np.testing.assert_allclose(c, b, rtol=0, atol=1e-12 * np.abs(b).max())
        assert np.abs(b[n:] - np.stack(qd)).max() > 1e-3  # the step moved the state
