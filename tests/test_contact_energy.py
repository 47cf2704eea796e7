"""The penalty is conservative: its contact stiffness is symmetric, and an elastic arm that hits an
obstacle and leaves it keeps its energy up to the integrator's own error. References: the
symmetry of a Hessian, the energy balance of an undamped system (kinetic + elastic + gravity,
``dynamics.energy``), and finite differences of the penalty's energy."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax.core import contact, dynamics
from gvsjax.core.kinematics import forward


def contact_force(robot, q, qd=None):
    """The generalized contact force (n,) at q (qd: zeros), from the recursion's points as the
    dynamics passes them (a scanned link's one stacked point, an unrolled link's points)."""
    n = robot.n_dofs
    qs = [q[i] for i in range(n)]
    qds = [jnp.zeros_like(q[i]) for i in range(n)] if qd is None else [qd[i] for i in range(n)]
    F = contact.evaluate(robot, forward(robot, qs, qds, with_psi=False), qs, qds, 0.0)[0]
    return jnp.stack([jnp.broadcast_to(jnp.asarray(f, q.dtype), ()) for f in F])


def pressed_rod(n_points=11, tilt=0.01, depth=-0.003, obstacle=None, recursion="auto"):
    """A clamped rod along +x (no gravity, quadratic curvature) on a plane ``depth`` (m) into its
    underside at the base, rising by ``tilt`` (rad) along it: at the defaults the rod touches from
    x = 0.3 m on, so one piece overlaps in part."""
    link = gv.SoftLink(length=1.0, radius=0.02, material=gv.Material(1e9, 1000.0, 0.0, 0.5), joint=gv.Joint("fixed"),
                       basis=gv.StrainBasis(orders=(-1, -1, 2, -1, -1, -1), kind="legendre"), n_gauss=4,
                       recursion=recursion)
    plane = gv.Plane(point=(0.0, -0.02 + depth, 0.0), normal=(-np.sin(tilt), np.cos(tilt), 0.0))
    c = gv.Contact(obstacles=(obstacle or plane,), rod=gv.Penalty(stiffness=1e7, damping=0.0), n_points=n_points)
    return gv.Robot(links=(link,), gravity=0.0, contact=c)


@pytest.mark.parametrize("obstacle", [None, gv.Sphere(centre=(0.64, -0.118, 0.0), radius=0.1),
                                      gv.Capsule(start=(0.55, -0.05, -0.3), end=(0.62, -0.045, 0.3), radius=0.03)])
@pytest.mark.parametrize("recursion", ["unrolled", "scan"])
def test_contact_stiffness_is_symmetric_and_the_force_is_minus_the_energy_gradient(obstacle, recursion):
    """K_c = -dF/dq of a rod pressed on a tilted plane (partly overlapping pieces), a ball and an
    oblique bar: symmetric to rounding, and F = -dE/dq, E the penalty's energy; the link unrolled
    (one point per grid point) or scanned (one stacked point)."""
    robot = pressed_rod(obstacle=obstacle, recursion=recursion)
    q = jnp.array([-0.01, 0.005, -0.002])  # bent down, into the obstacle
    F = contact_force(robot, q)
    K = -jax.jacfwd(lambda x: contact_force(robot, x))(q)
    assert float(jnp.max(jnp.abs(F))) > 10.0  # pressing
    scale = float(jnp.max(jnp.abs(K)))
    assert float(jnp.max(jnp.abs(K - K.T))) <= 1e-12 * scale
    # the energy's central differences (independent of the law's derivatives)
    E = lambda x: float(contact.energy(robot, x))  # noqa: E731
    h = 1e-7
    fd = np.array([(E(q + h * e) - E(q - h * e)) / (2 * h) for e in np.eye(3)])
    np.testing.assert_allclose(-fd, np.asarray(F), rtol=1e-6, atol=1e-6 * float(jnp.max(jnp.abs(F))))


def test_samples_on_the_grid_points_give_the_energy_gradient_on_a_multi_link_arm():
    """The benchmark tasks' arm (seven constant-curvature links, one Gauss point each, so its three
    samples per link are the link's grid points and take no Magnus step) bent into a capsule:
    F = -dE/dq by central differences of the energy."""
    arm = gv.curvature_arm()
    q = jnp.asarray(np.random.default_rng(0).uniform(-0.5, 0.5, arm.n_dofs))
    R, p = (np.asarray(x) for x in gv.frames(arm, q))
    i = len(p) // 2  # a bar across the arm's middle, oblique, 1 cm into it
    t, n = R[i, :, 0], R[i, :, 1]
    centre, along = p[i] + 0.07 * n, np.cross(t, n) + 0.3 * t
    bar = gv.Capsule(start=tuple(centre - 0.4 * along), end=tuple(centre + 0.4 * along), radius=0.03)
    robot = arm.replace(contact=gv.Contact(obstacles=(bar,), rod=gv.Penalty(stiffness=3e5, damping=0.0), n_points=3))
    F = contact_force(robot, q)
    assert float(jnp.max(jnp.abs(F))) > 1.0
    h, eye = 1e-7, jnp.eye(robot.n_dofs)
    E = jax.jit(jax.vmap(lambda x: contact.energy(robot, x)))(jnp.concatenate([q + h * eye, q - h * eye]))
    fd = np.asarray(E[: robot.n_dofs] - E[robot.n_dofs:]) / (2 * h)
    np.testing.assert_allclose(-fd, np.asarray(F), rtol=1e-6, atol=1e-6 * float(jnp.max(jnp.abs(F))))


def test_gradients_are_finite_and_smooth_at_a_rod_exactly_parallel_to_the_plane():
    """A straight rod at slope exactly 0 to the plane (and 1e-9 either side): the stiffness is
    finite and continuous through 0 (the energy is even in the slope about the middle)."""
    def stiffness(tilt):
        robot = pressed_rod(tilt=tilt, depth=0.001)
        return -jax.jacfwd(lambda x: contact_force(robot, x))(jnp.zeros(3))

    K0, Kp, Km = (np.asarray(stiffness(t)) for t in (0.0, 1e-9, -1e-9))
    assert np.all(np.isfinite(K0)) and np.abs(K0).max() > 1e3
    np.testing.assert_allclose(Kp, K0, rtol=1e-6, atol=1e-6 * np.abs(K0).max())
    np.testing.assert_allclose(Km, K0, rtol=1e-6, atol=1e-6 * np.abs(K0).max())
    grad = jax.grad(lambda y: contact.energy(pressed_rod(tilt=0.0, depth=y), jnp.zeros(3)))(0.001)
    assert np.isfinite(float(grad)) and float(grad) > 0.0


# ----------------------------------------------------------------------------
# an undamped arm that hits an obstacle and leaves it


def swinging_arm(obstacle):
    """The paper's arm (4 Legendre modes, no damping, free revolute base), released horizontal."""
    arm = gv.paper_arm(base="torque", damping=0.0, n_modes=4, basis="legendre")
    return arm.replace(contact=gv.Contact(obstacles=(obstacle,), rod=gv.Penalty(damping=0.0)))


def energy_errors(robot, duration, n_steps, splits=(1, 2, 4)):
    """(|E(T) - E(0)| / peak kinetic energy) at dt = T / (n_steps s) for s in splits: one compiled
    program, run s times back to back (the obstacles are static). The arm must have left the
    obstacle by T."""
    run = jax.jit(lambda T, q, qd: gv.simulate(robot, T, n_steps=n_steps, q0=q, qd0=qd, check_stability=False))
    total = jax.jit(jax.vmap(lambda q, qd: sum(dynamics.energy(robot, q, qd).values())))
    kinetic = jax.jit(jax.vmap(lambda q, qd: dynamics.energy(robot, q, qd)["kinetic"]))
    out = []
    for s in splits:
        q, qd = jnp.zeros(robot.n_dofs).at[0].set(np.pi / 2), jnp.zeros(robot.n_dofs)
        peak, touched = 0.0, False
        for _ in range(s):
            tr = run(duration / s, q, qd)
            q, qd = tr.q[-1], tr.qd[-1]
            peak = max(peak, float(jnp.max(kinetic(tr.q, tr.qd))))
            touched |= bool(jnp.any(tr.in_contact))
        assert touched and not bool(tr.in_contact[-1])
        e0, e1 = total(jnp.stack([jnp.zeros(robot.n_dofs).at[0].set(np.pi / 2), q]),
                       jnp.stack([jnp.zeros(robot.n_dofs), qd]))
        out.append(abs(float(e1 - e0)) / peak)
    return np.array(out)


@pytest.mark.slow
@pytest.mark.parametrize("obstacle, duration", [
    (gv.Sphere(centre=(0.55, -0.55, 0.0), radius=0.1), 1.0),
    pytest.param(gv.Plane(point=(0.0, -0.85, 0.0), normal=(0.05, 1.0, 0.0)), 0.8, marks=pytest.mark.extended)])
def test_an_elastic_arm_hitting_an_obstacle_keeps_its_energy_to_the_integrators_error(obstacle, duration):
    """RK4 at 1, 0.5 and 0.25 ms through the hit, swung down through a ball (sliding round it)
    or onto a tilted floor (bouncing): the energy error falls at least 3x per halving (RK4
    damps the contact's fast oscillation; the contact's onset, like Hertz's d^1.5, is not
    smooth enough for RK4's full order), and at 0.25 ms it is below 1e-3 of the peak kinetic
    energy. A law that is not a gradient leaves a gain that does not fall with dt (0.66% for
    the ball with the penalty applied at the overlap's middle)."""
    err = energy_errors(swinging_arm(obstacle), duration, int(round(duration * 1000)))
    assert np.all(err[1:] <= err[:-1] / 3), err
    assert err[-1] <= 1e-3, err
