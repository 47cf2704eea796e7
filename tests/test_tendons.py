"""Routed tendons (gvsjax.core.tendons): the generalized force against independent references.

With no other load, the statics of a cable-driven rod is local: cut the rod and the cable
at s, and the distal part (rod and cable, anchored at the tip) is held only by the rod's
internal wrench and the cable's tension at the cut, so K (xi(s) - xi*) = -T (d x t, t) with
t the cable's unit tangent, a few algebraic equations at each s. The boundary-value problem
of a tendon robot (Rucker and Webster 2011) reduces to that pointwise solve plus the
integration of the frames, done here with scipy, independently of gvsjax. The GVS statics
is the Galerkin projection of the same equations on the strain basis.
"""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, fsolve

from gvsjax.core import lie, tendons
from helpers import raises_naming

E, NU, RADIUS, LENGTH = 5e6, 0.5, 0.05, 1.0
EI = E * np.pi * RADIUS**4 / 4
GJ = E / (2 * (1 + NU)) * np.pi * RADIUS**4 / 2


def _rod(orders, n_links=1, joint=None):
    link = gv.SoftLink(length=LENGTH, radius=RADIUS, material=gv.Material(E, 1000.0, 0.0, NU),
                       basis=gv.StrainBasis(orders=orders, kind="legendre"), joint=gv.Joint("fixed"),
                       n_gauss=max(orders) + 1)
    links = (link,) + tuple(link.replace(joint=joint or gv.Joint("fixed")) for _ in range(n_links - 1))
    return gv.Robot(links=links, gravity=0.0)


def _force(robot, tension):
    n = robot.n_dofs
    f = lambda q: jnp.stack([lie.as_array(x) for x in  # noqa: E731
                             tendons.generalized_force(robot, [q[i] for i in range(n)], list(tension))])
    return jax.jit(f)


def _statics(robot, tension):
    """Newton on K q = tau(q) (no other load: the configuration the tendons hold)."""
    n = robot.n_dofs
    K = np.array([[float(lie.as_array(k)) for k in row] for row in gv.stiffness_and_damping(robot)[0]])
    tau = _force(robot, tension)
    jac = jax.jit(jax.jacfwd(tau))
    q = np.zeros(n)
    for _ in range(30):
        r = K @ q - np.asarray(tau(jnp.asarray(q)))
        q = q - np.linalg.solve(K - np.asarray(jac(jnp.asarray(q))), r)
        if np.abs(r).max() < 1e-12:
            break
    return q


def _tip(robot, q):
    return np.asarray(gv.tip_state(robot, jnp.asarray(q), jnp.zeros(robot.n_dofs))[0])


def _integrate_frames(u_of_s, length):
    """Tip of an inextensible, unshearable rod along +x with body angular strain u(s)."""
    def rhs(s, y):
        R = y[:9].reshape(3, 3)
        u = u_of_s(s)
        u_hat = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        return np.concatenate([(R @ u_hat).ravel(), R[:, 0]])

    y0 = np.concatenate([np.eye(3).ravel(), np.zeros(3)])
    return solve_ivp(rhs, (0.0, length), y0, rtol=1e-11, atol=1e-13).y[9:, -1]


# ----------------------------------------------------------------------------- planar oblique cable

Y0, Y1, TENSION = 0.03, 0.01, 200.0  # a converging cable: 3 cm from the midline at the base, 1 cm at the tip


def test_oblique_planar_cable_matches_the_pointwise_solution_and_the_small_strain_closed_form():
    robot = _rod((-1, -1, 4, -1, -1, -1))  # bending about z only: inextensible, unshearable
    cable = gv.RoutedTendon(paths=(gv.TendonPath(offsets=np.array([[Y0, 0.0], [Y1, 0.0]]), link=0,
                                                 knots=(0.0, 1.0)),))
    robot = robot.replace(tendons=(cable,))
    tip = _tip(robot, _statics(robot, [TENSION]))

    slope = (Y1 - Y0) / LENGTH
    y = lambda s: Y0 + slope * s  # noqa: E731

    def kappa(s):  # EI k = T y t_x, t = unit(1 - k y, y')
        return brentq(lambda k: EI * k - TENSION * y(s) * (1 - k * y(s)) / np.hypot(1 - k * y(s), slope), -10, 10)

    ref = _integrate_frames(lambda s: (0.0, 0.0, kappa(s)), LENGTH)
    assert np.linalg.norm(tip - ref) < 1e-6 * LENGTH, (tip, ref)
    # small strain: k = T y / EI, tip deflection = integral of k(s) (L - s) ds
    closed = TENSION / EI * (Y0 * LENGTH**2 / 2 + (Y1 - Y0) * LENGTH**2 / 6)
    assert tip[1] == pytest.approx(closed, rel=0.02)  # the rest is the large-deflection correction
    assert tip[1] > 0.05  # bent towards the cable's side, by ~10% of the length


def test_constant_routed_path_reproduces_the_straight_tendon():
    robot = _rod((-1, -1, 3, -1, -1, -1))
    straight = robot.replace(tendons=(gv.Tendon(offset=0.02, link=0, direction=(1.0, 0.0)),))
    routed = robot.replace(tendons=(gv.RoutedTendon(paths=(gv.TendonPath(
        offsets=np.array([[0.02, 0.0], [0.02, 0.0]]), link=0, knots=(0.0, 1.0), n_quad=4),)),))
    q = jnp.asarray(np.random.default_rng(1).normal(scale=0.5, size=robot.n_dofs))
    np.testing.assert_allclose(_force(routed, [7.0])(q), _force(straight, [7.0])(q), rtol=1e-13, atol=1e-13)


# ----------------------------------------------------------------------------- helical cable

RHO, TURNS, HELIX_T = 0.03, 0.5, 60.0


def _helix(X):
    phi = 2 * jnp.pi * TURNS * X
    return jnp.stack([RHO * jnp.cos(phi), RHO * jnp.sin(phi)])


def test_helical_cable_twists_and_bends_as_the_pointwise_solution():
    robot = _rod((5, 5, 5, -1, -1, -1))  # torsion and both bendings
    robot = robot.replace(tendons=(gv.RoutedTendon(paths=(gv.TendonPath(path=_helix, link=0, n_quad=12),)),))
    q = _statics(robot, [HELIX_T])
    tip = _tip(robot, q)
    K = np.array([GJ, EI, EI])

    def u_of_s(s):
        phi = 2 * np.pi * TURNS * s / LENGTH
        d = np.array([0.0, RHO * np.cos(phi), RHO * np.sin(phi)])
        dd = 2 * np.pi * TURNS / LENGTH * np.array([0.0, -RHO * np.sin(phi), RHO * np.cos(phi)])

        def residual(u):
            t = np.array([1.0, 0, 0]) + np.cross(u, d) + dd
            return K * u + HELIX_T * np.cross(d, t / np.linalg.norm(t))

        return fsolve(residual, np.zeros(3), xtol=1e-13)

    ref = _integrate_frames(u_of_s, LENGTH)
    assert np.linalg.norm(tip - ref) < 1e-3 * LENGTH, (tip, ref)
    twist = q[:6]  # torsion coefficients: the cable's helix twists the rod
    assert np.abs(twist).max() > 1e-3
    assert np.linalg.norm(tip[1:]) > 0.02  # and bends it (by ~3% of the length)


# ----------------------------------------------------------------------------- spanning links


def test_cable_ending_at_a_link_boundary_leaves_the_distal_link_unstrained():
    robot = _rod((-1, -1, 2, -1, -1, -1), n_links=2)
    half = np.array([[0.02, 0.0], [0.02, 0.0]])
    first_only = gv.RoutedTendon(paths=(gv.TendonPath(offsets=half, link=0, knots=(0.0, 1.0)),))
    both = gv.RoutedTendon(paths=(gv.TendonPath(offsets=half, link=0, knots=(0.0, 1.0)),
                                  gv.TendonPath(offsets=half, link=1, knots=(0.0, 0.5))))
    r1, r2 = robot.replace(tendons=(first_only,)), robot.replace(tendons=(both,))
    q1, q2 = _statics(r1, [50.0]), _statics(r2, [50.0])
    assert np.abs(q1[:3]).max() > 1e-2 and np.abs(q1[3:]).max() == 0.0  # distal link straight
    # spanning into the second link: the first carries the same load, the second bends too
    np.testing.assert_allclose(q2[:3], q1[:3], rtol=1e-12)
    assert np.abs(q2[3:]).max() > 1e-2


def test_generalized_force_is_minus_tension_times_the_gradient_of_the_cable_length():
    robot = _rod((-1, 2, 2, -1, -1, -1))
    path = gv.TendonPath(offsets=np.array([[0.01, 0.02], [0.03, -0.01], [0.0, 0.02]]), link=0,
                         knots=(0.1, 0.6, 0.9))  # starts and ends inside the link, one kink
    cable = gv.RoutedTendon(paths=(path,))
    robot = robot.replace(tendons=(cable,))
    q = jnp.asarray(np.random.default_rng(2).normal(scale=0.8, size=robot.n_dofs))
    grad = jax.grad(lambda x: tendons.cable_length(robot, cable, x))(q)
    np.testing.assert_allclose(_force(robot, [3.0])(q), -3.0 * grad, rtol=1e-12, atol=1e-14)


# ----------------------------------------------------------------------------- jit, vmap, grad and bad input


@pytest.mark.slow
@pytest.mark.extended
def test_simulate_with_a_routed_tendon_under_jit_vmap_and_grad():
    robot = _rod((-1, -1, 1, -1, -1, -1)).replace(gravity=0.0)
    robot = robot.replace(links=(robot.links[0].replace(material=gv.Material(E, 1000.0, 1e5, NU)),))

    def tip_y(tension, offsets):
        r = robot.replace(tendons=(gv.RoutedTendon(paths=(gv.TendonPath(offsets=offsets, link=0,
                                                                        knots=(0.0, 1.0)),)),))
        return gv.simulate(r, 0.1, n_steps=50, tendon_force=tension, integrator="ars443", save_every=50).tip[-1, 1]

    off = jnp.array([[0.03, 0.0], [0.01, 0.0]])
    ys = jax.jit(jax.vmap(tip_y, in_axes=(0, None)))(jnp.array([0.0, 10.0, 20.0]), off)
    assert ys[0] == 0.0 and 0 < ys[1] < ys[2]
    g_T, g_off = jax.jit(jax.grad(tip_y, argnums=(0, 1)))(10.0, off)
    assert g_T > 0 and np.all(np.isfinite(np.asarray(g_off))) and float(g_off[0, 0]) > 0


@pytest.mark.parametrize("path, name", [
    (gv.TendonPath(offsets=np.zeros((2, 2)), link=0, knots=(0.5, 0.2)), "tendons[0].paths[0].knots"),
    (gv.TendonPath(offsets=np.zeros((3, 2)), link=0, knots=(0.0, 1.0)), "tendons[0].paths[0].offsets"),
    (gv.TendonPath(offsets=np.array([[0.2, 0.0], [0.0, 0.0]]), link=0, knots=(0.0, 1.0)),
     "tendons[0].paths[0].offsets"),
    (gv.TendonPath(offsets=np.zeros((2, 2)), link=3, knots=(0.0, 1.0)), "tendons[0].paths[0].link"),
    (gv.TendonPath(path=_helix, link=0, X0=0.7, X1=0.2), "tendons[0].paths[0].X0, X1"),
])
def test_bad_paths_name_the_field(path, name):
    robot = _rod((-1, -1, 1, -1, -1, -1)).replace(tendons=(gv.RoutedTendon(paths=(path,)),))
    raises_naming(name, gv.simulate, robot, 0.1, 1e-3)


def test_a_path_function_is_checked_inside_jit():
    """The check evaluates a path function on concrete numbers also while jit traces."""
    robot = _rod((-1, -1, 1, -1, -1, -1)).replace(tendons=(gv.RoutedTendon(paths=(gv.TendonPath(path=_helix,
                                                                                                 link=0),)),))
    shape = jax.eval_shape(jax.jit(lambda T: gv.simulate(robot, 0.01, n_steps=2, tendon_force=T).tip), 1.0)
    assert shape.shape == (3, 3)


def test_paths_must_continue_across_a_fixed_joint():
    robot = _rod((-1, -1, 1, -1, -1, -1), n_links=2, joint=gv.Joint("revolute"))
    off = np.zeros((2, 2))
    cable = gv.RoutedTendon(paths=(gv.TendonPath(offsets=off, link=0, knots=(0.0, 1.0)),
                                   gv.TendonPath(offsets=off, link=1, knots=(0.0, 1.0))))
    raises_naming("tendons[0].paths[1]", gv.simulate, robot.replace(tendons=(cable,)), 0.1, 1e-3)
