"""Sections and rest shapes: tapered, elliptical and rectangular rods against beam theory
(Euler-Bernoulli deflection integrals, Saint-Venant torsion), and pre-curved or pre-twisted
rods that stay at rest in their reference shape."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad

from gvsjax.core import dynamics

E, NU = 5e7, 0.5
G_SHEAR = E / (2 * (1 + NU))


def cantilever(tip_load, direction, orders, **link) -> gv.Robot:
    """A clamped rod along +x (no gravity) with a dead load at its tip. A tapered section
    gets 8 Gauss points (its stiffness is a polynomial of high degree in X); a uniform one
    the fewest that integrate its stiffness exactly (they compile fastest)."""
    tapered = link.get("taper", 1.0) != 1.0
    rod = gv.SoftLink(length=1.0, material=gv.Material(E, 1000.0, 0.0, NU), joint=gv.Joint("fixed"),
                      basis=gv.StrainBasis(orders=orders, kind="legendre"),
                      n_gauss=8 if tapered else max(orders) + 1, **link)
    moment = direction[0] != 0 and direction == (1.0, 0.0, 0.0)
    load = gv.PointLoad(magnitude=tip_load, link=0, X=1.0, direction=direction, moment=moment, follower=moment)
    return gv.Robot(links=(rod,), gravity=0.0, loads=(load,))


def _force(robot, q):
    _, F = dynamics.mass_and_forces(robot, [q[i] for i in range(robot.n_dofs)], [0] * robot.n_dofs)  # qd: int zeros
    return jnp.stack([jnp.asarray(f, float) for f in F])


@jax.jit
def _step(robot, q):
    """One Newton step on the generalized forces F(q, 0) = 0 (a tool for the test, not the reference)."""
    f = _force(robot, q)
    return q - jnp.linalg.solve(jax.jacfwd(lambda x: _force(robot, x))(q), f), jnp.max(jnp.abs(f))


def equilibrium(robot: gv.Robot, iterations: int = 8) -> jax.Array:
    q = jnp.zeros(robot.n_dofs)
    for _ in range(iterations):
        q, residual = _step(robot, q)
    assert float(residual) < 1e-8
    return q


# a uniform beam's curvature under a tip load is linear in s: order 1 is exact; a tapered
# one's, P (L - s) / E I(s), is rational and wants a higher order
BEND_Z = (-1, -1, 1, -1, -1, -1)  # curvature about z: deflection along y
BEND_Y = (-1, 1, -1, -1, -1, -1)
BEND_Z_TAPERED = (-1, -1, 4, -1, -1, -1)


@pytest.mark.parametrize("taper", [1.0, 0.5])
def test_tapered_cantilever_deflection_matches_the_beam_integral(taper):
    """Tip deflection under a small tip load: delta = int_0^L P (L - s)^2 / (E I(s)) ds with
    r(s) = r0 (1 + (taper - 1) s / L), I = pi r^4 / 4 (Euler-Bernoulli)."""
    r0, P = 0.02, 0.02
    robot = cantilever(P, (0.0, -1.0, 0.0), BEND_Z if taper == 1.0 else BEND_Z_TAPERED, radius=r0, taper=taper)
    tip = gv.backbone(robot, equilibrium(robot))[-1]
    inertia = lambda s: np.pi * (r0 * (1 + (taper - 1) * s)) ** 4 / 4  # noqa: E731
    ref, _ = quad(lambda s: P * (1 - s) ** 2 / (E * inertia(s)), 0.0, 1.0)
    assert ref < 0.01  # small deflection: linear theory holds
    np.testing.assert_allclose(-float(tip[1]), ref, rtol=5e-3)


@pytest.mark.parametrize("shape", ["rectangle", "ellipse"])
def test_rectangular_and_elliptical_sections_bend_by_their_own_second_moments(shape):
    """Loads along y and along z deflect a w x h section by P L^3 / (3 E I) with I_z, I_y of the shape."""
    w, h, P = 0.06, 0.02, 0.01
    Iy, Iz = (w * h**3 / 12, h * w**3 / 12) if shape == "rectangle" else \
        (np.pi * (w / 2) * (h / 2) ** 3 / 4, np.pi * (w / 2) ** 3 * (h / 2) / 4)
    along_y = cantilever(P, (0.0, -1.0, 0.0), BEND_Z, shape=shape, width=w, height=h)
    along_z = cantilever(P, (0.0, 0.0, -1.0), BEND_Y, shape=shape, width=w, height=h)
    dy = -float(gv.backbone(along_y, equilibrium(along_y))[-1, 1])
    dz = -float(gv.backbone(along_z, equilibrium(along_z))[-1, 2])
    np.testing.assert_allclose(dy, P / (3 * E * Iz), rtol=5e-3)
    np.testing.assert_allclose(dz, P / (3 * E * Iy), rtol=5e-3)


def test_elliptical_torsion_constant_is_saint_venants():
    """A tip torque T twists an elliptical rod by T L / (G Jt), Jt = pi a^3 b^3 / (a^2 + b^2)."""
    a, b, T = 0.03, 0.015, 0.05
    robot = cantilever(T, (1.0, 0.0, 0.0), (0, -1, -1, -1, -1, -1), shape="ellipse", width=2 * a, height=2 * b)
    q = equilibrium(robot)
    R, _ = gv.frames(robot, q)
    twist = float(jnp.arctan2(R[-1, 2, 1], R[-1, 1, 1]))  # the section's y axis turned about x
    np.testing.assert_allclose(twist, T / (G_SHEAR * np.pi * a**3 * b**3 / (a * a + b * b)), rtol=1e-6)


def test_pre_curved_arc_stays_at_rest_on_its_circle():
    kappa = 2.0  # 1/m: 1 m of a circle of radius 0.5 m
    rod = gv.SoftLink(length=1.0, radius=0.02, material=gv.Material(E, 1000.0, 1e4, NU), joint=gv.Joint("fixed"),
                      basis=gv.StrainBasis(orders=(-1, -1, 0, -1, -1, -1), kind="legendre"),
                      rest_strain=jnp.array([0.0, 0.0, kappa, 1.0, 0.0, 0.0]))
    robot = gv.Robot(links=(rod,), gravity=0.0)
    tr = gv.simulate(robot, 0.05, 1e-3, save_every=50)
    np.testing.assert_allclose(np.asarray(tr.q), 0.0, atol=1e-14)
    pts = np.asarray(gv.backbone(robot, tr.q[-1]))
    s = np.arccos(np.clip(1 - kappa * pts[:, 1], -1, 1)) / kappa  # arc length from the height
    np.testing.assert_allclose(pts[:, 0], np.sin(kappa * s) / kappa, atol=1e-12)
    np.testing.assert_allclose(np.hypot(pts[:, 0], pts[:, 1] - 1 / kappa), 1 / kappa, atol=1e-12)


def test_pre_twisted_rod_is_straight_with_its_sections_turned():
    tau = 1.5  # rad/m
    rest = jnp.array([[tau, 0.0], [0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 0.0]])  # constant
    rod = gv.SoftLink(length=1.0, radius=0.02, material=gv.Material(E, 1000.0, 0.0, NU), joint=gv.Joint("fixed"),
                      basis=gv.StrainBasis(orders=(1, 1, 1, -1, -1, -1), kind="legendre"), rest_strain=rest)
    robot = gv.Robot(links=(rod,), gravity=0.0)
    _, F = dynamics.mass_and_forces(robot, [0.0] * robot.n_dofs, [0.0] * robot.n_dofs)
    np.testing.assert_allclose([float(jnp.asarray(f)) for f in F], 0.0, atol=1e-14)
    R, p = gv.frames(robot, jnp.zeros(robot.n_dofs))
    np.testing.assert_allclose(np.asarray(p[-1]), [1.0, 0.0, 0.0], atol=1e-14)
    np.testing.assert_allclose(float(jnp.arctan2(R[-1, 2, 1], R[-1, 1, 1])), tau, atol=1e-12)


def test_section_parameters_are_checked():
    with pytest.raises(ValueError, match=r"links\[0\].taper"):
        gv.simulate(cantilever(0.0, (0.0, -1.0, 0.0), BEND_Z, taper=-0.5), 0.01, 1e-3)
    with pytest.raises(ValueError, match=r"links\[0\].shape"):
        gv.simulate(cantilever(0.0, (0.0, -1.0, 0.0), BEND_Z, shape="square"), 0.01, 1e-3)
    with pytest.raises(ValueError, match=r"links\[0\].rest_strain"):
        gv.simulate(cantilever(0.0, (0.0, -1.0, 0.0), BEND_Z, rest_strain=jnp.ones(5)), 0.01, 1e-3)


@pytest.mark.extended
def test_taper_is_differentiable():
    """d(tip height)/d(taper) at equilibrium by the implicit function theorem, from JAX's
    derivatives of the generalized forces, equals a central difference of the equilibria."""
    def robot_at(taper):
        return cantilever(0.02, (0.0, -1.0, 0.0), BEND_Z, radius=0.02, taper=taper)

    def height(taper):
        robot = robot_at(taper)
        return float(gv.backbone(robot, equilibrium(robot))[-1, 1])

    q = equilibrium(robot_at(0.7))
    dF_dq = jax.jacfwd(lambda x: _force(robot_at(0.7), x))(q)
    dF_dtaper = jax.jacfwd(lambda t: _force(robot_at(t), q))(0.7)
    dq = -jnp.linalg.solve(dF_dq, dF_dtaper)
    g = jax.grad(lambda x: gv.backbone(robot_at(0.7), x)[-1, 1])(q) @ dq
    fd = (height(0.7 + 1e-5) - height(0.7 - 1e-5)) / 2e-5
    np.testing.assert_allclose(g, fd, rtol=1e-5)
