"""Joints: torque-driven revolute chains against their closed-form Lagrangian equations,
multi-DoF joints (spherical, free) against conservation laws and ballistics, and joint
springs/dampers against the damped oscillator."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax.core import dynamics
from gvsjax.core.system import FreeDynamics

G = 9.81


def double_pendulum(m=(1.3, 0.7), l=(0.9, 0.6), c=(0.4, 0.35), I=(0.05, 0.02)) -> gv.Robot:
    links = tuple(gv.RigidLink(mass=m[i], inertia=(0.01, 0.01, I[i]), com=(c[i], 0.0, 0.0), length=l[i],
                               joint=gv.Joint("revolute", (0.0, 0.0, 1.0))) for i in range(2))
    return gv.Robot(links=links, gravity=G)


def lagrange_double_pendulum(q, qd, tau, m=(1.3, 0.7), l=(0.9, 0.6), c=(0.4, 0.35), I=(0.05, 0.02)):
    """M(q) and qdd of the planar double pendulum (absolute q1, relative q2; gravity -y)."""
    (m1, m2), (l1, _), (c1, c2), (I1, I2) = m, l, c, I
    q1, q2 = q
    d1, d2 = qd
    cos2, sin2 = np.cos(q2), np.sin(q2)
    m12 = I2 + m2 * (c2**2 + l1 * c2 * cos2)
    M = np.array([[I1 + m1 * c1**2 + I2 + m2 * (l1**2 + c2**2 + 2 * l1 * c2 * cos2), m12],
                  [m12, I2 + m2 * c2**2]])
    h = m2 * l1 * c2 * sin2
    coriolis = np.array([-h * (2 * d1 * d2 + d2**2), h * d1**2])
    gravity = np.array([(m1 * c1 + m2 * l1) * G * np.cos(q1) + m2 * c2 * G * np.cos(q1 + q2),
                        m2 * c2 * G * np.cos(q1 + q2)])
    return M, np.linalg.solve(M, np.asarray(tau) - coriolis - gravity)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_torque_driven_double_pendulum_matches_lagrange(seed):
    rng = np.random.default_rng(seed)
    q, qd, tau = rng.uniform(-2, 2, 2), rng.uniform(-3, 3, 2), rng.uniform(-5, 5, 2)
    robot = double_pendulum()
    assert robot.actuated == (0, 1)
    M_ref, qdd_ref = lagrange_double_pendulum(q, qd, tau)
    M, _ = dynamics.mass_and_forces(robot, list(jnp.asarray(q)), list(jnp.asarray(qd)), (), list(jnp.asarray(tau)))
    np.testing.assert_allclose(np.asarray(dynamics.full_matrix(M, 2)), M_ref, rtol=0, atol=1e-9)
    system = FreeDynamics(robot, lambda t: jnp.zeros(0), None, lambda t, q_, qd_: jnp.asarray(tau))
    qdd = np.asarray(system.accel(0.0, tuple(jnp.asarray(q)), tuple(jnp.asarray(qd))))
    np.testing.assert_allclose(qdd, qdd_ref, rtol=0, atol=1e-9)


def test_joint_force_time_law_reaches_the_trajectory():
    """simulate(joint_force=t -> tau) integrates the same equations: rk4 vs a scipy-free RK4 of Lagrange."""
    robot = double_pendulum()
    tau_of = lambda t: jnp.stack([2.0 * jnp.sin(3.0 * t), -1.0 + 0.5 * t])  # noqa: E731
    tr = gv.simulate(robot, 0.5, 1e-3, joint_force=tau_of, q0=jnp.array([0.3, -0.4]))
    x = np.array([0.3, -0.4, 0.0, 0.0])

    def f(t, x):
        _, qdd = lagrange_double_pendulum(x[:2], x[2:], np.asarray(tau_of(t)))
        return np.concatenate([x[2:], qdd])

    h = 1e-3
    for k in range(500):
        t = k * h
        k1 = f(t, x)
        k2 = f(t + h / 2, x + h / 2 * k1)
        k3 = f(t + h / 2, x + h / 2 * k2)
        k4 = f(t + h, x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    np.testing.assert_allclose(np.asarray(tr.q[-1]), x[:2], atol=1e-9)
    np.testing.assert_allclose(np.asarray(tr.joint_force[-1]), np.asarray(tau_of(0.5)), atol=1e-12)


def test_joint_spring_and_damper_give_the_damped_oscillator():
    I_zz, m, c, k, d, theta0 = 0.02, 0.8, 0.3, 3.0, 0.4, 0.5
    link = gv.RigidLink(mass=m, inertia=(0.01, 0.01, I_zz), com=(c, 0.0, 0.0), length=0.6,
                        joint=gv.Joint("revolute", (0.0, 0.0, 1.0)), joint_stiffness=k, joint_damping=d)
    tr = gv.simulate(gv.Robot(links=(link,), gravity=0.0), 3.0, 1e-3, q0=jnp.array([theta0]))
    J = I_zz + m * c**2
    wn, z = np.sqrt(k / J), d / (2 * np.sqrt(k * J))
    wd = wn * np.sqrt(1 - z**2)
    t = np.asarray(tr.t)
    ref = theta0 * np.exp(-z * wn * t) * (np.cos(wd * t) + z * wn / wd * np.sin(wd * t))
    np.testing.assert_allclose(np.asarray(tr.q[:, 0]), ref, atol=1e-9)


def spherical_pendulum() -> gv.Robot:
    body = gv.RigidLink(mass=1.2, inertia=(0.02, 0.05, 0.04), com=(0.5, 0.05, -0.02), length=0.7,
                        joint=gv.Joint("spherical"))
    return gv.Robot(links=(body,), gravity=G)


def test_spherical_joint_conserves_energy_and_vertical_angular_momentum():
    """A rigid body on a frictionless ball joint: energy and the angular momentum about the
    vertical through the pivot are conserved (gravity exerts no moment about it)."""
    robot = spherical_pendulum()
    assert robot.n_dofs == 3 and robot.actuated == (0, 1, 2)
    q0, qd0 = jnp.array([0.3, -0.5, 0.2]), jnp.array([1.0, 0.5, -0.8])
    tr = gv.simulate(robot, 1.0, 5e-4, q0=q0, qd0=qd0, save_every=20)

    def total_energy(q, qd):
        e = gv.energy(robot, q, qd)
        return e["kinetic"] + e["gravity"]

    def vertical_momentum(q, qd):  # world angular momentum about +y through the pivot
        R, p = gv.frames(robot, q)
        J = gv.jacobians(robot, q)[-2]  # the CoM point: body twist = J qd
        eta = J @ qd
        w_world, v_world = R[-2] @ eta[:3], R[-2] @ eta[3:]
        I_world = R[-2] @ jnp.diag(jnp.array([0.02, 0.05, 0.04])) @ R[-2].T
        L = I_world @ w_world + 1.2 * jnp.cross(p[-2], v_world)
        return L[1]

    E = np.asarray(jax.jit(jax.vmap(total_energy))(tr.q, tr.qd))
    Ly = np.asarray(jax.jit(jax.vmap(vertical_momentum))(tr.q, tr.qd))
    assert np.ptp(E) < 1e-8 * np.max(np.abs(E)) + 1e-9
    assert np.ptp(Ly) < 1e-8
    assert np.ptp(np.asarray(tr.q[:, 0])) > 0.1  # it did move


def test_free_body_flies_ballistically():
    """A free-floating body (6-DoF base, CoM at the body origin): the CoM follows
    p0 + v0 t - g t^2 / 2 whatever it spins, and a spin about a principal axis stays constant."""
    body = gv.RigidLink(mass=2.0, inertia=(0.03, 0.05, 0.07), com=(0.0, 0.0, 0.0), length=0.0,
                        joint=gv.Joint("free"))
    robot = gv.Robot(links=(body,), gravity=G)
    assert robot.n_dofs == 6
    q0 = jnp.array([0.1, 0.2, -0.3, 0.0, 0.0, 0.0])
    qd0 = jnp.array([1.0, 4.0, -0.5, 0.0, 0.0, 2.5])  # spin about the body z axis
    tr = gv.simulate(robot, 0.8, 1e-3, q0=q0, qd0=qd0)
    t = np.asarray(tr.t)[:, None]
    ref = np.asarray(q0[:3]) + np.asarray(qd0[:3]) * t + 0.5 * np.array([0.0, -G, 0.0]) * t**2
    np.testing.assert_allclose(np.asarray(tr.q[:, :3]), ref, atol=1e-9)
    np.testing.assert_allclose(np.asarray(tr.qd[:, 5]), 2.5, atol=1e-9)
    np.testing.assert_allclose(np.asarray(tr.q[-1, 5]), 2.5 * 0.8, atol=1e-9)


def test_joint_kinds_and_bad_joint_parameters():
    assert [gv.Joint(k).n_dofs for k in ("fixed", "revolute", "prismatic", "universal", "spherical", "planar",
                                          "free")] == [0, 1, 1, 2, 3, 3, 6]
    with pytest.raises(ValueError, match="Joint.kind"):
        gv.Joint("ball")
    with pytest.raises(ValueError, match="axis2"):
        gv.Joint("universal", axis2=(1.0, 1.0, 0.0))
    body = gv.RigidLink(mass=1.0, joint=gv.Joint("universal"), joint_stiffness=(1.0, 2.0, 3.0))
    with pytest.raises(ValueError, match=r"links\[0\].joint_stiffness"):
        gv.simulate(gv.Robot(links=(body,)), 0.1, 1e-3)
    body = gv.RigidLink(mass=1.0, joint=gv.Joint("revolute"), joint_damping=-1.0)
    with pytest.raises(ValueError, match=r"links\[0\].joint_damping"):
        gv.simulate(gv.Robot(links=(body,)), 0.1, 1e-3)


def test_universal_joint_matches_two_revolute_joints():
    """A universal joint is the product of its two rotations: the same as two revolute joints
    with a massless, zero-length link between them."""
    axis, axis2 = (0.0, 0.0, 1.0), (0.0, 1.0, 0.0)
    body = dict(mass=1.0, inertia=(0.02, 0.03, 0.04), com=(0.4, 0.0, 0.1), length=0.8)
    one = gv.Robot(links=(gv.RigidLink(joint=gv.Joint("universal", axis, axis2), **body),), gravity=G)
    spacer = gv.RigidLink(mass=1e-30, inertia=(1e-30,) * 3, joint=gv.Joint("revolute", axis))
    two = gv.Robot(links=(spacer, gv.RigidLink(joint=gv.Joint("revolute", axis2), **body)), gravity=G)
    q, qd = jnp.array([0.4, -0.7]), jnp.array([1.5, 0.3])
    for robot in (one, two):
        assert robot.n_dofs == 2
    a = FreeDynamics(one, lambda t: jnp.zeros(0)).accel(0.0, tuple(q), tuple(qd))
    b = FreeDynamics(two, lambda t: jnp.zeros(0)).accel(0.0, tuple(q), tuple(qd))
    np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.asarray(gv.frames(one, q)[1][-1]), np.asarray(gv.frames(two, q)[1][-1]),
                               atol=1e-14)


def test_joint_force_works_under_jit_vmap_grad():
    body = gv.RigidLink(mass=1.0, inertia=(0.01, 0.01, 0.02), com=(0.3, 0.0, 0.0), length=0.6)
    robot = gv.Robot(links=(body,), gravity=G)

    def final_angle(gain):
        return gv.simulate(robot, 0.2, n_steps=50, joint_force=lambda t, q, qd: 1.0 - gain * qd).q[-1, 0]

    gains = jnp.array([0.0, 1.0, 2.0])
    batched = jax.jit(jax.vmap(final_angle))(gains)
    np.testing.assert_allclose(batched, [final_angle(g) for g in gains], atol=1e-12)
    g = jax.grad(final_angle)(1.0)
    fd = (final_angle(1.0 + 1e-4) - final_angle(1.0 - 1e-4)) / 2e-4
    np.testing.assert_allclose(g, fd, rtol=1e-5)
