"""Kinematics (gvsjax.core.kinematics): the frame conventions, convergence of the tip with
quadrature points, Jacobians against autodiff and finite differences, finite gradients at
the straight configuration, and coordinate vectors of the wrong length named."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import rigid_soft_chain


def test_conventions_hanging_and_horizontal():
    arm = gv.paper_arm()
    tip, _ = gv.tip_state(arm, jnp.zeros(3), jnp.zeros(3))
    np.testing.assert_allclose(tip, [0.0, -1.0, 0.0], atol=1e-12)
    arm0 = gv.paper_arm(gravity=0.0)
    traj = gv.simulate(arm0, 0.2, 2e-3, base_angle=lambda t: jnp.pi / 2)
    np.testing.assert_allclose(traj.tip[-1], [1.0, 0.0, 0.0], atol=1e-12)


def test_tip_converges_with_quadrature_points():
    q = jnp.array([np.pi / 2, -3.0, 5.0])
    tip = lambda n: np.asarray(gv.tip_state(gv.paper_arm(n_gauss=n), q, jnp.zeros(3))[0])  # noqa: E731
    ref = tip(60)
    errs = [np.linalg.norm(tip(n) - ref) for n in (3, 5, 8)]
    # gvs-notes 3.2: 1.8e-3, 3.3e-4, 6.1e-5 m for 4th-order Magnus
    np.testing.assert_allclose(errs, [1.8e-3, 3.3e-4, 6.1e-5], rtol=0.1)


def test_jacobians_map_rates_to_twists():
    robot = rigid_soft_chain()
    rng = np.random.default_rng(1)
    q = jnp.asarray(rng.normal(size=robot.n_dofs))
    qd = jnp.asarray(rng.normal(size=robot.n_dofs))
    J = gv.jacobians(robot, q)  # (points, 6, n), body frame
    R, p = gv.frames(robot, q)
    _, v_tip = gv.tip_state(robot, q, qd)
    np.testing.assert_allclose(R[-1] @ (J[-1] @ qd)[3:], v_tip, atol=1e-12)
    # world velocity of every point equals the time derivative of its position
    p_dot = jax.jvp(lambda x: gv.frames(robot, x)[1], (q,), (qd,))[1]
    np.testing.assert_allclose(jnp.einsum("kij,kj->ki", R, (J @ qd)[:, 3:]), p_dot, atol=1e-12)
    # Jdot is the derivative of J along qd (central differences)
    h = 1e-6
    fd = (gv.jacobians(robot, q + h * qd) - gv.jacobians(robot, q - h * qd)) / (2 * h)
    np.testing.assert_allclose(gv.jacobian_rates(robot, q, qd), fd, atol=1e-7)


@pytest.mark.parametrize("make", [rigid_soft_chain, lambda: gv.soft_arm(recursion="scan")], ids=["unrolled", "scan"])
def test_the_pass_without_jacobians_gives_the_same_poses_and_twists(make):
    """``forward(jacobian=False)`` (tip_state, frames, energy and the contact report use it)
    leaves every J zero and every pose and twist as the full pass has them (to rounding: the
    scanned pass is one compiled loop, whose fusions differ when it carries no Jacobian)."""
    from gvsjax.core import lie
    from gvsjax.core.kinematics import forward, rows

    robot = make()
    rng = np.random.default_rng(2)
    q, qd = (list(jnp.asarray(0.3 * rng.normal(size=robot.n_dofs))) for _ in range(2))
    full, lean = (rows(forward(robot, q, qd, with_psi=False, jacobian=j)) for j in (True, False))
    assert len(full) == len(lean) > 3
    as_array = lambda tree: np.asarray(jax.tree.map(lie.as_array, tree), float)  # noqa: E731
    for a, b in zip(full, lean):
        for name in ("R", "p", "eta"):
            np.testing.assert_allclose(as_array(getattr(b, name)), as_array(getattr(a, name)), rtol=1e-14, atol=1e-16)
        assert not np.any(as_array(b.J))
    assert np.any(as_array(full[-1].J))


def test_gradients_finite_at_straight_configuration():
    arm = gv.paper_arm(tip_force=5.886)
    g = jax.jit(jax.grad(lambda q: jnp.sum(gv.tip_state(arm, q, jnp.ones(3))[1])))(jnp.zeros(3))
    assert np.all(np.isfinite(g))
    rod = gv.rod_3d()  # jitted: eagerly, each of its many scalar ops would be dispatched on its own
    g3 = jax.jit(jax.grad(lambda q: jnp.sum(gv.tip_state(rod, q, jnp.ones(rod.n_dofs))[1])))(jnp.zeros(rod.n_dofs))
    assert np.all(np.isfinite(g3))


@pytest.mark.parametrize("fn, args", [
    (gv.backbone, ("q",)), (gv.frames, ("q",)), (gv.jacobians, ("q",)),
    (gv.tip_state, ("q", "qd")), (gv.energy, ("q", "qd")),
])
def test_wrong_coordinate_length_is_named(fn, args):
    arm = gv.paper_arm()
    n = arm.n_dofs
    for bad in args:  # one argument of length n + 1, the others right
        values = [np.zeros(n + 1) if name == bad else np.zeros(n) for name in args]
        with pytest.raises(AssertionError, match=rf"{bad} must have shape \(n_dofs,\) = \({n},\)"):
            fn(arm, *values)
