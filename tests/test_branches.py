"""Branched robots (``Robot.parents``, ``Joint.offset``/``rotation``) against references
independent of the recursion: the poses of constant-curvature arcs composed in numpy, the
exact zero of the mass matrix between branches that share no body, each branch of a held
tree against the same rod alone, linear beam theory for a Y of horizontal cantilevers, and
energy conservation of a free-swinging tree."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import raises_naming

from gvsjax.core import dynamics, lie

UP = ((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))  # the first link's x along world +y
Z, Y = (0.0, 0.0, 1.0), (0.0, 1.0, 0.0)


def _rod(length, basis_orders, joint, E=5e6, radius=0.03, n_gauss=2):
    return gv.SoftLink(length=length, radius=radius, material=gv.Material(E, 1000.0, 0.0, 0.5),
                       basis=gv.StrainBasis(orders=basis_orders), joint=joint, n_gauss=n_gauss)


def y_tree(gravity=9.81) -> gv.Robot:
    """A trunk on a revolute base and two branches from its end, tilted +-40 deg out of
    the trunk's bending plane; branch B starts 2 cm off the centreline. Every link has
    constant curvature q / L about its local z (one DoF), so every pose has a closed form."""
    bend, E = (-1, -1, 0, -1, -1, -1), 5e5
    trunk = _rod(0.5, bend, gv.Joint("revolute", Z), E=E)
    a = _rod(0.4, bend, gv.Joint("fixed", rotation=gv.axis_rotation(Y, np.deg2rad(40.0))), E=E)
    b = _rod(0.3, bend, gv.Joint("fixed", offset=(0.0, 0.02, 0.0), rotation=gv.axis_rotation(Y, np.deg2rad(-40.0))),
             E=E)
    return gv.Robot(links=(trunk, a, b), parents=(-1, 0, 0), gravity=gravity, base_rotation=UP)


def _arc(k, L):
    """Pose after an arc of curvature k about local z over length L (exact)."""
    c, s = np.cos(k * L), np.sin(k * L)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    p = np.array([s / k, (1 - c) / k, 0.0]) if abs(k) > 1e-12 else np.array([L, 0.0, 0.0])
    return R, p


def _rot_z(a):
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])


def test_poses_of_a_y_match_composed_closed_form_arcs():
    robot = y_tree()
    q = np.array([0.7, 1.3, -2.1, 3.0])  # base angle (rad); trunk, A, B bending angles k L (rad)
    R, p = jax.jit(gv.frames, static_argnums=0)(robot, jnp.asarray(q))
    R0 = np.asarray(UP) @ _rot_z(q[0])
    Rt, pt = _arc(q[1] / 0.5, 0.5)
    R_end, p_end = R0 @ Rt, R0 @ pt
    Ra = R_end @ np.asarray(gv.axis_rotation(Y, np.deg2rad(40.0)))
    expected = {0: (R_end, p_end)}
    expected[1] = (Ra @ _arc(q[2] / 0.4, 0.4)[0], p_end + Ra @ _arc(q[2] / 0.4, 0.4)[1])
    Rb = R_end @ np.asarray(gv.axis_rotation(Y, np.deg2rad(-40.0)))
    pb = p_end + R_end @ np.array([0.0, 0.02, 0.0])
    expected[2] = (Rb @ _arc(q[3] / 0.3, 0.3)[0], pb + Rb @ _arc(q[3] / 0.3, 0.3)[1])
    for link, (R_ref, p_ref) in expected.items():
        row = gv.end_row(robot, link)
        np.testing.assert_allclose(np.asarray(p[row]), p_ref, atol=1e-12)
        np.testing.assert_allclose(np.asarray(R[row]), R_ref, atol=1e-12)
    # each branch starts where the trunk ends (plus B's offset), not where the previous link ended
    starts = [i for i, site in enumerate(gv.sample_sites(robot)) if site[1] == 0.0]
    np.testing.assert_allclose(np.asarray(p[starts[1]]), p_end, atol=1e-12)
    np.testing.assert_allclose(np.asarray(p[starts[2]]), pb, atol=1e-12)
    # the Jacobian of a branch's end is that of the closed form (forward differences of it)
    tip_a = lambda x: gv.backbone(robot, x)[gv.end_row(robot, 1)]  # noqa: E731
    J = np.asarray(jax.jacfwd(tip_a)(jnp.asarray(q)))
    assert np.all(J[:, 3] == 0.0)  # B's strain does not move A
    h = 1e-6
    for k in range(3):
        dq = np.zeros(4)
        dq[k] = h
        fd = (np.asarray(tip_a(jnp.asarray(q + dq))) - np.asarray(tip_a(jnp.asarray(q - dq)))) / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, atol=1e-7)


def _mf(robot, q, qd):
    n = robot.n_dofs
    M, F = dynamics.mass_and_forces(robot, [q[i] for i in range(n)], [qd[i] for i in range(n)])
    return dynamics.full_matrix(M, n), jnp.stack([lie.as_array(f) for f in F])


@pytest.mark.extended
def test_branches_share_no_inertia_and_the_lagrangian_holds():
    """M between the two branches is exactly zero (they share no body), between the trunk
    and a branch it is not; M and F equal the Lagrangian's by autodiff on the tree."""
    robot = y_tree()
    rng = np.random.default_rng(1)
    q, qd = jnp.asarray(rng.normal(size=4)), jnp.asarray(rng.normal(size=4))
    M, F = jax.jit(_mf, static_argnums=0)(robot, q, qd)
    M = np.asarray(M)
    assert M[2, 3] == 0.0 and M[3, 2] == 0.0
    assert abs(M[1, 2]) > 1e-3 * M[2, 2] and abs(M[0, 3]) > 1e-3 * M[3, 3]

    def lagrangian(q, qd):
        e = gv.energy(robot, q, qd)
        return e["kinetic"] - e["elastic"] - e["gravity"]

    M_ref = jax.hessian(lagrangian, argnums=1)(q, qd)
    F_ref = jax.grad(lagrangian)(q, qd) - jax.jacfwd(jax.grad(lagrangian, argnums=1))(q, qd) @ qd
    np.testing.assert_allclose(M, M_ref, atol=1e-10 * np.abs(M).max())
    np.testing.assert_allclose(F, F_ref, atol=1e-9 * (1 + float(jnp.abs(F).max())))


def held_y(E=1e8, gravity=9.81) -> gv.Robot:
    """A rigid vertical trunk (fixed) and two horizontal soft branches pointing to +-x,
    bending about z with quadratic curvature (it holds the self-weight curvature exactly)."""
    trunk = gv.RigidLink(mass=1.0, length=0.3, joint=gv.Joint("fixed"))
    bend = (-1, -1, 2, -1, -1, -1)
    right = _rod(1.0, bend, gv.Joint("fixed", rotation=gv.axis_rotation(Z, -np.pi / 2)), E=E, radius=0.05,
                 n_gauss=3)
    left = right.replace(joint=gv.Joint("fixed", rotation=gv.axis_rotation(Z, np.pi / 2)))
    return gv.Robot(links=(trunk, right, left), parents=(-1, 0, 0), gravity=gravity, base_rotation=UP)


def test_each_branch_of_a_held_y_is_the_single_cantilever():
    """Mass matrix and forces of each branch equal those of the same rod clamped alone in
    the same orientation, at a random moving state."""
    tree = held_y(E=5e6)
    rng = np.random.default_rng(2)
    q, qd = jnp.asarray(rng.normal(size=6)), jnp.asarray(rng.normal(size=6))
    M, F = jax.jit(_mf, static_argnums=0)(tree, q, qd)
    for link, cols in ((1, slice(0, 3)), (2, slice(3, 6))):
        R_mount = np.asarray(UP) @ np.asarray(tree.links[link].joint.rotation)
        alone = gv.Robot(links=(tree.links[link].replace(joint=gv.Joint("fixed")),), gravity=9.81,
                         base_rotation=tuple(map(tuple, R_mount)))
        M1, F1 = _mf(alone, q[cols], qd[cols])
        np.testing.assert_allclose(np.asarray(M)[cols, cols], np.asarray(M1), rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(np.asarray(F)[cols], np.asarray(F1), rtol=1e-12, atol=1e-12)
    assert np.all(np.asarray(M)[0:3, 3:6] == 0.0)


def test_a_y_of_horizontal_cantilevers_sags_as_beam_theory_says():
    """Each branch's tip drops w L^4 / (8 E I) under self-weight (small load, 1%), and the
    two tips mirror each other about the trunk."""
    E, g, r = 1e8, 9.81, 0.05
    tree = held_y(E=E, gravity=g)
    res = gv.equilibrium(tree)
    assert bool(res.converged)
    pts = np.asarray(gv.backbone(tree, res.q))
    right, left = pts[gv.end_row(tree, 1)], pts[gv.end_row(tree, 2)]
    expected = 1000.0 * np.pi * r**2 * g / (8 * E * np.pi * r**4 / 4)
    assert 0.3 - right[1] == pytest.approx(expected, rel=1e-2)
    assert 0.3 - left[1] == pytest.approx(expected, rel=1e-2)
    np.testing.assert_allclose(left * np.array([-1, 1, 1]), right, atol=1e-12)


@pytest.mark.slow
def test_a_free_swinging_y_conserves_energy():
    robot = y_tree()
    qd0 = np.array([2.0, 0.0, 0.0, 0.0])
    traj = gv.simulate(robot, 1.0, 1e-3, qd0=qd0, save_every=25)
    e = jax.jit(jax.vmap(lambda q, v: gv.energy(robot, q, v)))(traj.q, traj.qd)
    total = np.asarray(e["kinetic"] + e["elastic"] + e["gravity"])
    assert np.all(np.isfinite(total))
    assert np.ptp(total) < 1e-6 * np.abs(np.asarray(e["kinetic"])).max()
    assert float(np.ptp(traj.q[:, 2])) > 0.1 and float(np.ptp(traj.q[:, 3])) > 0.1  # the branches bend


@pytest.mark.parametrize("parents, name", [((-1, 0), "parents"), ((-1, 1, 0), "parents[1]"),
                                            ((0, 0, 0), "parents[0]"), ((-1, 0.5, 0), "parents[1]")])
def test_bad_parents_are_named(parents, name):
    raises_naming(name, gv.simulate, y_tree().replace(parents=parents), 0.01, 1e-3)


def test_bad_mount_is_named():
    raises_naming("Joint.rotation", gv.Joint, "fixed", rotation=((1.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, 0.0, 1.0)))
    raises_naming("Joint.offset", gv.Joint, "fixed", offset=(0.0, np.nan, 0.0))


@pytest.mark.extended
def test_a_routed_tendon_follows_the_tree():
    """A cable may run from the trunk into one branch (its child) but not from one branch
    into the other."""
    tree = held_y(E=5e6)
    soft_trunk = _rod(0.3, (-1, -1, 0, -1, -1, -1), gv.Joint("fixed"))
    tree = tree.replace(links=(soft_trunk, *tree.links[1:]))
    path = lambda link: gv.TendonPath(link=link, knots=(0.0, 1.0), offsets=((0.0, 0.01), (0.0, 0.01)))  # noqa: E731
    ok = tree.replace(tendons=(gv.RoutedTendon(paths=(path(0), path(2))),))
    assert np.all(np.isfinite(np.asarray(gv.simulate(ok, 0.002, 1e-3, tendon_force=1.0).q)))
    bad = tree.replace(tendons=(gv.RoutedTendon(paths=(path(1), path(2))),))
    raises_naming("tendons[0].paths[1]", gv.simulate, bad, 0.002, 1e-3, tendon_force=1.0)
