"""Point wrenches as inputs (world and section frames, laws of time or state) and distributed
loads per unit length, against closed forms and an independent ODE solve."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from gvsjax.core import dynamics, loads

MASS, COM, I_ZZ, LENGTH = 1.0, 0.4, 0.02, 0.8
J_JOINT = I_ZZ + MASS * COM**2


def bar(**robot) -> gv.Robot:
    body = gv.RigidLink(mass=MASS, inertia=(0.01, 0.01, I_ZZ), com=(COM, 0.0, 0.0), length=LENGTH)
    return gv.Robot(links=(body,), wrenches=(gv.PointWrench(link=0, X=1.0, local=robot.pop("local", False)),),
                    **{"gravity": 0.0, **robot})


def test_follower_force_spins_the_bar_at_constant_acceleration():
    """A force f along the bar's own y at its far end: torque f L always, theta = f L t^2 / (2 J)."""
    f = 0.7
    tr = gv.simulate(bar(local=True), 1.0, 1e-3, wrench=jnp.array([[0.0, 0.0, 0.0, 0.0, f, 0.0]]))
    t = np.asarray(tr.t)
    np.testing.assert_allclose(np.asarray(tr.q[:, 0]), f * LENGTH * t**2 / (2 * J_JOINT), atol=1e-10)
    np.testing.assert_allclose(np.asarray(tr.wrench[:, 0, 4]), f)


def test_world_force_is_a_pendulum_against_an_ode_solve():
    """A constant world force F along -y at the far end: J theta'' = -F L cos(theta)."""
    F = 2.0
    tr = gv.simulate(bar(), 1.5, 1e-3, wrench=lambda t: jnp.array([0.0, 0.0, 0.0, 0.0, -F, 0.0]))
    sol = solve_ivp(lambda t, x: [x[1], -F * LENGTH * np.cos(x[0]) / J_JOINT], (0.0, 1.5), [0.0, 0.0],
                    t_eval=np.asarray(tr.t), rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(np.asarray(tr.q[:, 0]), sol.y[0], atol=1e-8)


def test_state_dependent_moment_is_a_spring_and_damper():
    k, c = 3.0, 0.2
    moment = lambda t, q, qd: jnp.array([0.0, 0.0, -k * q[0] - c * qd[0], 0.0, 0.0, 0.0])  # noqa: E731
    tr = gv.simulate(bar(), 2.0, 1e-3, wrench=moment, q0=jnp.array([0.4]))
    wn, z = np.sqrt(k / J_JOINT), c / (2 * np.sqrt(k * J_JOINT))
    wd, t = wn * np.sqrt(1 - z**2), np.asarray(tr.t)
    ref = 0.4 * np.exp(-z * wn * t) * (np.cos(wd * t) + z * wn / wd * np.sin(wd * t))
    np.testing.assert_allclose(np.asarray(tr.q[:, 0]), ref, atol=1e-9)


E, RADIUS, RHO = 1e8, 0.02, 1000.0
AREA, SECOND = np.pi * RADIUS**2, np.pi * RADIUS**4 / 4


def rod(distributed, joint="fixed", gravity=0.0, orders=(-1, -1, 1, -1, -1, -1)) -> gv.Robot:
    link = gv.SoftLink(length=1.0, radius=RADIUS, material=gv.Material(E, RHO, 0.0, 0.5), joint=gv.Joint(joint),
                       basis=gv.StrainBasis(orders=orders, kind="legendre"), n_gauss=6)
    return gv.Robot(links=(link,), gravity=gravity, gravity_direction=(0.0, -1.0, 0.0), distributed=distributed)


def test_uniform_distributed_force_bends_a_cantilever_by_w_l4_over_8ei():
    w = 0.5  # N/m along -y, small: linear theory
    robot = rod(loads.uniform_force([0.0, -w, 0.0]), orders=(-1, -1, 2, -1, -1, -1))
    result = gv.equilibrium(robot)
    assert bool(result.converged)
    np.testing.assert_allclose(-float(gv.backbone(robot, result.q)[-1, 1]), w / (8 * E * SECOND), rtol=2e-3)


def test_buoyancy_equal_to_the_weight_leaves_no_force():
    weight = RHO * AREA * 9.81
    robot = rod(loads.uniform_force([0.0, weight, 0.0]), gravity=9.81)
    _, F = dynamics.mass_and_forces(robot, [0.0] * robot.n_dofs, [0.0] * robot.n_dofs)
    np.testing.assert_allclose([float(jnp.asarray(f)) for f in F], 0.0, atol=1e-13)
    heavy = rod(None, gravity=9.81)
    _, F = dynamics.mass_and_forces(heavy, [0.0] * heavy.n_dofs, [0.0] * heavy.n_dofs)
    assert max(abs(float(jnp.asarray(f))) for f in F) > 1e-3  # without it, the weight bends the rod


def test_viscous_drag_slows_a_spinning_rod_exponentially():
    """Normal drag c per metre on a stiff rod spinning about its base (no gravity): the torque is
    -c omega L^3 / 3, so omega = omega0 exp(-c L^3 t / (3 J)), J = rho A L^3 / 3 + rho I_z L."""
    c, omega0 = 0.05, 2.0
    robot = rod(loads.viscous_drag(c), joint="revolute", orders=(-1, -1, 0, -1, -1, -1))
    tr = gv.simulate(robot, 1.0, n_steps=200, qd0=jnp.array([omega0, 0.0]), integrator="ars443")
    J = RHO * AREA / 3 + RHO * SECOND
    ref = omega0 * np.exp(-c * np.asarray(tr.t) / (3 * J))
    np.testing.assert_allclose(np.asarray(tr.qd[:, 0]), ref, rtol=2e-4)


@pytest.mark.parametrize("kwargs, name", [
    (dict(wrench=jnp.zeros((2, 6))), "wrench"),
    (dict(wrench=lambda t: jnp.zeros(5)), "wrench"),
])
def test_bad_wrench_inputs_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        gv.simulate(bar(), 0.1, 1e-3, **kwargs)


def test_bad_wrench_sites_and_distributed_loads_are_named():
    body = gv.RigidLink(mass=1.0)
    with pytest.raises(ValueError, match=r"wrenches\[0\].X"):
        gv.simulate(gv.Robot(links=(body,), wrenches=(gv.PointWrench(X=1.5),)), 0.1, 1e-3)
    with pytest.raises(ValueError, match="distributed"):
        gv.simulate(gv.Robot(links=(body,), distributed=3.0), 0.1, 1e-3)
