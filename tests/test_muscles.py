"""Distributed internal moments ("muscle torques", ``gvsjax.core.muscles``) and the ``strain_force``
input of ``simulate`` and ``equilibrium``, against closed forms: a constant moment gives a
constant strain (an arc, a helix: the exponential of one twist), a linear bending moment
the curvature and deflection of beam theory; the map B against the virtual work by autodiff.

A weightless rod's balance K q = B u is linear (no load depends on the configuration), so
the 3D checks solve it directly and test the map and the kinematics; ``equilibrium``'s own
solver runs on a planar rod (its 3D compile takes minutes: the extended tier), as do the
dynamics checks.
"""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import expm

from gvsjax.core import muscles
from gvsjax.core.magnus import rest_strain, scaled_columns, strain
from gvsjax.core.system import FreeDynamics

E, NU, R, L = 5e6, 0.5, 0.05, 1.0
EI = E * np.pi * R**4 / 4
GJ = E / (2 * (1 + NU)) * np.pi * R**4 / 2
# torsion constant, both bendings linear, inextensible, unshearable: 5 DoFs
ROD = gv.rod_3d(length=L, radius=R, youngs_modulus=E, poisson=NU, order=(0, 1, 1, -1, -1, -1), n_gauss=3)
B_ALL = gv.moment_map(ROD, components=("torsion", "bend_y", "bend_z"))
G = gv.control_points()
# bending about z only, linear curvature (2 DoFs): the dynamics and the solver's compile stay small
PLANAR = gv.rod_3d(length=L, radius=R, youngs_modulus=E, poisson=NU, order=(-1, -1, 1, -1, -1, -1), n_gauss=2,
                   damping=2e4)
B_PLANAR = gv.moment_map(PLANAR, components=("bend_z",))


def hat(xi):
    """The 4x4 se(3) matrix of a twist (angular, linear)."""
    w, v = xi[:3], xi[3:]
    out = np.zeros((4, 4))
    out[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
    out[:3, 3] = v
    return out


def test_control_points_and_profile():
    np.testing.assert_allclose(G, [0, 1 / 9, 1 / 3, 2 / 3, 8 / 9, 1], atol=1e-15)
    X = np.linspace(0, 1, 41)
    N = muscles.profile(X)
    np.testing.assert_allclose(N.sum(axis=1), 1.0, atol=1e-14)  # equal coefficients: a uniform moment
    np.testing.assert_allclose(N @ (2 - 3 * G), 2 - 3 * X, atol=1e-14)  # linear profiles reproduced
    np.testing.assert_allclose(N[[0, -1]][:, [0, -1]], np.eye(2), atol=1e-15)  # clamped ends


def static(u, rod=ROD, B=B_ALL):
    """The equilibrium of the weightless rod under moments u: K q = B u, exactly (with no
    load that depends on the configuration the balance of generalized forces is linear)."""
    K = gv.dynamics.full_matrix(gv.stiffness_and_damping(rod)[0], rod.n_dofs)
    return jnp.linalg.solve(K, jnp.asarray(B @ u))


def test_uniform_moments_give_the_constant_strain_exponential():
    """Moments (T, My, Mz) equal at every control point: strain (T/GJ, My/EI, Mz/EI) all
    along, a helix whose tip frame is exp(L hat(xi)); torsion alone turns the tip by T L / GJ."""
    for T, My, Mz in ((3.0, -10.0, 20.0), (5.0, 0.0, 0.0)):
        Rt, pt = gv.tip_frame(ROD, static(np.repeat([T, My, Mz], 6)))
        g = expm(L * hat(np.array([T / GJ, My / EI, Mz / EI, 1.0, 0.0, 0.0])))
        np.testing.assert_allclose(np.asarray(pt), g[:3, 3], rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.asarray(Rt), g[:3, :3], rtol=0, atol=1e-12)
    angle = np.arctan2(float(Rt[2, 1]), float(Rt[1, 1]))
    assert angle == pytest.approx(5.0 * L / GJ, rel=1e-12)


def test_uniform_bending_is_a_circular_arc_in_equilibrium():
    """Through ``equilibrium``'s own solver, on a planar rod (the cheapest compile)."""
    k = 1.0 / L  # one radian of turn over the arm
    res = gv.equilibrium(PLANAR, strain_force=B_PLANAR @ np.full(6, k * EI))
    assert bool(res.converged)
    tip = np.asarray(gv.tip_frame(PLANAR, res.q)[1])
    np.testing.assert_allclose(tip, [np.sin(k * L) / k, (1 - np.cos(k * L)) / k, 0.0], rtol=0, atol=1e-12)


@pytest.mark.extended
def test_helix_in_equilibrium_on_the_3d_rod():
    """The constant-strain helix through ``equilibrium`` on the 3D rod (a minutes-long compile)."""
    T, My, Mz = 3.0, -10.0, 20.0
    res = gv.equilibrium(ROD, strain_force=B_ALL @ np.repeat([T, My, Mz], 6))
    assert bool(res.converged)
    g = expm(L * hat(np.array([T / GJ, My / EI, Mz / EI, 1.0, 0.0, 0.0])))
    np.testing.assert_allclose(np.asarray(gv.tip_frame(ROD, res.q)[1]), g[:3, 3], rtol=0, atol=1e-12)


def test_equilibrium_derivative_in_the_moments_is_the_compliance():
    """d q / d u = K^-1 B on the weightless rod, through the solver's implicit-function rule."""
    u = np.full(6, 0.3 * EI)
    J = jax.jacfwd(lambda v: gv.equilibrium(PLANAR, strain_force=jnp.asarray(B_PLANAR) @ v).q)(jnp.asarray(u))
    K = gv.dynamics.full_matrix(gv.stiffness_and_damping(PLANAR)[0], PLANAR.n_dofs)
    np.testing.assert_allclose(np.asarray(J), np.linalg.solve(np.asarray(K), B_PLANAR), rtol=1e-9, atol=1e-12)


def test_linear_moment_matches_beam_theory():
    """m_z(s) = M0 (1 - s/L): curvature M0 (1 - s/L) / EI, held exactly by the linear basis;
    the tip of that curve by quadrature, to the recursion's own discretisation error (the
    angle is quadratic in s; the 4th-order Magnus steps converge as h^4: ~2e-5 m on the 4
    intervals of n_gauss = 3, ~1e-7 m on 13) and Euler-Bernoulli's M0 L^2 / (3 EI) at small
    load (beam theory's error there ~ angle^2)."""
    link = ROD.links[0]
    fine = gv.rod_3d(length=L, radius=R, youngs_modulus=E, poisson=NU, order=(0, 1, 1, -1, -1, -1), n_gauss=12)
    for M0 in (0.05 * EI, 0.5 * EI):
        q = static(np.concatenate([np.zeros(12), M0 * (1 - G)]))
        for X in (0.0, 0.3, 1.0):
            kappa = link.basis.raw(X)[2] @ np.asarray(q) / L
            assert kappa == pytest.approx(M0 * (1 - X) / EI, abs=1e-12)
        s, w = np.polynomial.legendre.leggauss(60)
        s, w = (s + 1) / 2 * L, w / 2 * L
        theta = M0 / EI * (s - s**2 / (2 * L))
        exact = np.array([w @ np.cos(theta), w @ np.sin(theta), 0.0])
        np.testing.assert_allclose(np.asarray(gv.tip_frame(ROD, q)[1]), exact, rtol=0, atol=3e-5)
        np.testing.assert_allclose(np.asarray(gv.tip_frame(fine, q)[1]), exact, rtol=0, atol=3e-7)
        if M0 < 0.1 * EI:
            assert float(gv.tip_frame(fine, q)[1][1]) == pytest.approx(M0 * L**2 / (3 * EI), rel=1e-3)


def test_map_is_the_gradient_of_the_virtual_work_and_independent_of_q():
    """B u = dW/dq with W(q) = int m(s) . xi_w(q, s) ds (exact: Gauss on each spline span)."""
    link = ROD.links[0]
    u = np.random.default_rng(0).normal(size=18)
    nodes, weights = np.polynomial.legendre.leggauss(6)

    def work(q):
        total = 0.0
        for a, b in ((0, 1 / 3), (1 / 3, 2 / 3), (2 / 3, 1)):
            for x, wq in zip(a + (b - a) * (nodes + 1) / 2, (b - a) * weights / 2):
                xi = strain(scaled_columns(link.basis.raw(x), 1.0 / L), [q[i] for i in range(5)],
                            rest_strain(link, x))
                m = muscles.profile(x)[0] @ u.reshape(3, 6).T
                total = total + wq * L * sum(m[c] * xi[c] for c in range(3))
        return total

    for q in (jnp.zeros(5), jnp.asarray(np.random.default_rng(1).normal(size=5))):
        np.testing.assert_allclose(np.asarray(jax.grad(work)(q)), B_ALL @ u, rtol=1e-12, atol=1e-12)
    # and the dynamics add exactly B u to F
    system = FreeDynamics(ROD, lambda t: jnp.zeros(0), strain_force=lambda t, q, qd: jnp.asarray(B_ALL @ u))
    bare = FreeDynamics(ROD, lambda t: jnp.zeros(0))
    q = tuple(jnp.asarray(0.1 * np.arange(5.0)))
    F1, F0 = system._mf(0.0, q, q)[4], bare._mf(0.0, q, q)[4]
    np.testing.assert_allclose(np.array([float(a - b) for a, b in zip(F1, F0)]), B_ALL @ u, atol=1e-12)


def test_inactive_components_and_other_links_get_zero_columns():
    planar = gv.rod_3d(order=(-1, -1, 1, -1, -1, -1), n_gauss=2)
    B = gv.moment_map(planar, components=("torsion", "bend_z"))
    assert B.shape == (2, 12)
    assert not np.any(B[:, :6]) and np.all(B[0, 6:] > 0)
    arm = gv.paper_arm()  # a revolute joint, then the soft link: the joint's row stays zero
    assert not np.any(gv.moment_map(arm)[0])


@pytest.mark.parametrize("kwargs, match", [
    (dict(components=("bend_x",)), "components"),
    (dict(components=("bend_y", "bend_y")), "components"),
    (dict(n_points=3), "n_points"),
    (dict(link=4), "link"),
])
def test_moment_map_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gv.moment_map(ROD, **kwargs)




@pytest.mark.parametrize("value", [np.zeros(3), np.zeros((2, 1)), 1.0, "0", lambda t: jnp.zeros(3),
                                   lambda t, q, qd: jnp.zeros((2, 2))])
def test_simulate_rejects_bad_strain_force(value):
    with pytest.raises(ValueError, match="strain_force"):
        gv.simulate(PLANAR, 0.01, n_steps=2, strain_force=value)


def test_equilibrium_rejects_bad_strain_force():
    with pytest.raises(ValueError, match="strain_force"):
        gv.equilibrium(PLANAR, strain_force=np.zeros(4))


# one DoF (a constant curvature): the simulate compiles below are the module's largest
ROD_1 = gv.rod_3d(length=L, radius=R, youngs_modulus=E, poisson=NU, order=(-1, -1, 0, -1, -1, -1), n_gauss=1,
                  damping=2e4)
B_1 = jnp.asarray(gv.moment_map(ROD_1, components=("bend_z",)))
U = jnp.linspace(0.5, 1.0, 6)


def tip_y(u):
    return gv.simulate(ROD_1, 0.05, n_steps=10, strain_force=B_1 @ u).tip[-1, 1]


def test_strain_force_under_jit_and_a_controller():
    y = jax.jit(tip_y)(U)
    assert float(y) > 0  # bending about +z turns the tip towards +y
    held = gv.simulate(ROD_1, 0.05, n_steps=10, control_every=5,
                       controller=lambda t, q, qd: {"strain_force": B_1 @ U})
    np.testing.assert_allclose(float(held.tip[-1, 1]), float(y), rtol=1e-12)
    # differentiable where it enters: the accelerations' derivative in u is M^-1 B
    system = lambda u: FreeDynamics(ROD_1, lambda t: jnp.zeros(0), strain_force=lambda t, q, qd: B_1 @ u)  # noqa: E731
    accel = lambda u: system(u).accel(0.0, (jnp.asarray(0.1),), (jnp.asarray(0.0),))[0]  # noqa: E731
    M, _ = gv.mass_and_forces(ROD_1, [0.1], [0.0])
    np.testing.assert_allclose(np.asarray(jax.grad(accel)(U)), np.asarray(B_1[0]) / float(M[0][0]), rtol=1e-12)


@pytest.mark.extended
def test_strain_force_under_grad_vmap_and_a_state_law():
    y = tip_y(U)
    g = jax.grad(tip_y)(U)
    e = jnp.zeros(6).at[2].set(1e-3)
    np.testing.assert_allclose(float(g[2]), float(tip_y(U + e) - tip_y(U - e)) / 2e-3, rtol=1e-6)
    ys = jax.vmap(tip_y)(jnp.stack([U, 2 * U]))
    np.testing.assert_allclose(float(ys[0]), float(y), rtol=1e-12)
    law = gv.simulate(ROD_1, 0.05, n_steps=10, strain_force=lambda t, q, qd: B_1 @ U)
    np.testing.assert_allclose(float(law.tip[-1, 1]), float(y), rtol=1e-12)
