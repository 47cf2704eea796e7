"""The step limit with an explicit contact penalty, and runs that diverge saying so.

References: RK4's stability bound on an undamped oscillator (|lambda| dt <= 2 sqrt 2), the
integrators' own steps on a linear system (for the IMEX schemes' linear model), and runs just
inside and well outside the estimate."""

import warnings

import jax.numpy as jnp
import numpy as np
import pytest
from helpers import raises_naming

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
from gvsjax.core import integrators, lie
from gvsjax.core.stability import amplification, stable_step_estimate


class LinearSystem:
    """M qdd = -(K + Kc) q - (D + Dc) qd in the integrators' interface (``accel``, ``parts``)."""

    def __init__(self, M, K, D, Kc, Dc):
        self.M, self.K, self.D, self.Kc, self.Dc = M, K, D, Kc, Dc

    def _f(self, q, qd):
        q, qd = jnp.stack(q), jnp.stack(qd)
        return -(self.K + self.Kc) @ q - (self.D + self.Dc) @ qd

    def parts(self, t, q, qd):
        rows = lambda A: [[A[i, j] for j in range(A.shape[1])] for i in range(A.shape[0])]  # noqa: E731
        return rows(self.M), list(self._f(q, qd)), rows(self.K), rows(self.D)

    def accel(self, t, q, qd):
        return tuple(jnp.linalg.solve(self.M, self._f(q, qd)))


@pytest.mark.parametrize("name", ["ars443", "imex"])
def test_the_imex_schemes_linear_model_is_their_own_step(name):
    """``amplification`` (the step-limit's model: K, D implicit, the contact explicit) maps
    (q, qd) as one step of the integrator itself on the linear system."""
    rng = np.random.default_rng(0)
    n = 3
    B = rng.normal(size=(n, n))
    M = B @ B.T + n * np.eye(n)
    K, Kc = (np.diag(rng.uniform(1.0, 2.0, n)) * s for s in (1e3, 1e5))
    D, Dc = 0.01 * K, 0.002 * Kc
    dt = 2e-3
    system = LinearSystem(*(jnp.asarray(A) for A in (M, K, D, Kc, Dc)))
    step = integrators.get(name).step
    columns = []
    for y in np.eye(2 * n):
        q1, qd1 = step(system, 0.0, tuple(jnp.asarray(y[:n])), tuple(jnp.asarray(y[n:])), dt)
        columns.append(np.concatenate([np.asarray([lie.as_array(x) for x in q1]),
                                       np.asarray([lie.as_array(x) for x in qd1])]))
    np.testing.assert_allclose(amplification(name, M, K, D, Kc, Dc, dt), np.stack(columns, 1), rtol=1e-10,
                               atol=1e-12)


def test_rk4_step_limit_includes_the_penalty_as_an_oscillator():
    """An undamped penalty of k = 1e9 N/m^2 on a rod of rho A per metre: RK4's limit is
    2 sqrt 2 sqrt(rho A / k) (its bound on the imaginary axis), below the rod's own."""
    arm = gv.paper_arm(base="torque")
    k = 1e9
    robot = arm.replace(contact=gv.Contact(obstacles=(gv.Plane(point=(0.0, -2.0, 0.0)),),
                                           rod=gv.Penalty(stiffness=k, damping=0.0)))
    q0 = np.zeros(robot.n_dofs)
    rho_a = 1000.0 * np.pi * 0.05**2
    assert stable_step_estimate(robot, "rk4", q0, with_contact=False) > 1e-3
    np.testing.assert_allclose(stable_step_estimate(robot, "rk4", q0), 2 * np.sqrt(2) * np.sqrt(rho_a / k), rtol=1e-6)


def test_an_explicit_penalty_at_too_large_a_step_is_refused_naming_the_contact():
    """The closed-loop arm with a ball in reach, ``ars443`` at 5 ms: the penalty's limit
    (1.37 ms at the default k) refuses it before compiling; the arm alone has none."""
    arm = gv.soft_arm()
    robot = arm.replace(contact=gv.Contact(obstacles=(gv.Sphere(centre=(0.35, 0.0, 0.75), radius=0.1),)))
    assert stable_step_estimate(robot, "ars443", np.zeros(robot.n_dofs), with_contact=False) == np.inf
    limit = stable_step_estimate(robot, "ars443", np.zeros(robot.n_dofs))
    assert 1e-3 < limit < 2e-3
    err = raises_naming("dt", gv.simulate, robot, 0.5, 5e-3, integrator="ars443")
    assert "contact" in str(err)


def test_a_run_beyond_the_limit_is_flagged_non_finite_and_an_eager_run_warns():
    """The paper's arm lying pressed along a floor (the estimate's worst case), ``ars443``:
    at 0.8x the estimate it rests; at 2.5x it diverges, and says so."""
    arm = gv.paper_arm(base="torque", n_modes=3, basis="legendre")
    robot = arm.replace(contact=gv.Contact(obstacles=(gv.Plane(point=(0.0, -0.05, 0.0)),), n_points=11))
    q0 = jnp.zeros(robot.n_dofs).at[0].set(np.pi / 2)
    limit = stable_step_estimate(robot, "ars443", np.asarray(q0))
    runs = {}
    for factor in (0.8, 2.5):
        dt = factor * limit
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            runs[factor] = gv.simulate(robot, 600 * dt, dt, q0=q0, integrator="ars443", check_stability=False)
        runs[factor] = (runs[factor], [str(w.message) for w in caught if w.category is RuntimeWarning])
    calm, noted = runs[0.8]
    assert bool(jnp.all(calm.finite)) and float(jnp.max(jnp.abs(calm.qd))) < 1.0 and not noted
    wild, noted = runs[2.5]
    assert not bool(wild.finite[-1]) and bool(wild.finite[0])
    assert len(noted) == 1 and "non-finite" in noted[0] and "contact" in noted[0]
