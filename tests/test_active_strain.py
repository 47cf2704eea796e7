"""Rest-strain inputs (active strain, ``gvsjax.core.active_strain``) against closed forms: a constant rest
curvature bends an unloaded rod into an arc of exactly that curvature, piecewise rest curvatures into
the matching chain of arcs, a rest twist turns the tip by the integrated twist; the input under jit,
vmap and grad and in a controller; the checks at the boundary; and ``point_states``."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import gvsjax as gv
from gvsjax.core import active_strain
from gvsjax.core.curvature_arm import SEGMENTS, node_sites, segment_lengths
from gvsjax.core.kinematics import point_states


def one_link(components=("bend_y", "bend_z"), knots=(0.0, 1.0), **arm):
    robot = gv.soft_arm(gravity=0.0, **arm)
    seg = gv.RestStrainSegments(link=0, knots=knots, components=components)
    return dataclasses.replace(robot, tendons=(), rest_strains=(seg,))


def planar_chain(kappa: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Points at the ends of arcs of curvature kappa[i] and length lengths[i], starting up the z axis and
    turning towards +x for kappa > 0 (x-z plane): the closed form of a chain of arcs."""
    theta, p, out = 0.0, np.zeros(2), []
    for k, l in zip(kappa, lengths):
        if abs(k) < 1e-12:
            d = l * np.array([np.sin(theta), np.cos(theta)])
        else:
            d = np.array([np.cos(theta) - np.cos(theta + k * l), np.sin(theta + k * l) - np.sin(theta)]) / k
        p, theta = p + d, theta + k * l
        out.append(p.copy())
    return np.array(out)


def test_constant_rest_curvature_gives_an_arc():
    robot = one_link(bending_order=0, torsion_order=-1, stretch_order=-1)
    kappa = 2.0
    res = gv.equilibrium(robot, rest_strain=np.array([[0.0, kappa]]))
    assert res.converged
    pts = np.asarray(gv.backbone(robot, res.q))
    # an arc from the origin, tangent +z: its centre is 1/kappa off the axis in the plane of the tip
    direction = pts[-1, :2] / np.linalg.norm(pts[-1, :2])
    centre = np.array([*(direction / kappa), 0.0])
    np.testing.assert_allclose(np.linalg.norm(pts - centre, axis=1), 1.0 / kappa, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(pts[-1]), 2 * np.sin(kappa / 2) / kappa, atol=1e-12)


def test_piecewise_rest_curvature_gives_the_chain_of_arcs():
    robot = gv.curvature_arm(planar=True, gravity=0.0)
    rng = np.random.default_rng(0)
    kappa = rng.uniform(-8.0, 8.0, 5)  # 1/m on the five segments
    res = gv.equilibrium(robot, rest_strain=kappa)  # bend_z > 0 turns the tangent towards world +x
    assert res.converged
    knots = np.array([0.0, *SEGMENTS, 1.0])
    curv = np.concatenate([[0.0], kappa, [0.0]])
    ends = planar_chain(curv, np.diff(knots))
    qd = jnp.zeros_like(res.q)
    p, _, _ = point_states(robot, res.q, qd, node_sites(robot, knots[1:]))
    np.testing.assert_allclose(np.asarray(p)[:, [0, 2]], ends, atol=1e-10)
    np.testing.assert_allclose(np.asarray(p)[:, 1], 0.0, atol=1e-12)


def test_rest_twist_turns_the_tip_by_the_integrated_twist():
    robot = gv.curvature_arm(twist=True, gravity=0.0)
    angles = np.array([0.3, -0.2, 0.5, 0.1, 0.4])  # rad per segment
    values = np.zeros((5, 3))
    values[:, 0] = angles / segment_lengths()  # torsion, 1/m
    res = gv.equilibrium(robot, rest_strain=values.reshape(-1))
    R, p = gv.tip_frame(robot, res.q)
    total = angles.sum()
    # the tangent stays up; the section's y axis (world +x at rest) turns by the total twist about z
    np.testing.assert_allclose(np.asarray(p), [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(np.asarray(R)[:, 1], [np.cos(total), np.sin(total), 0.0], atol=1e-10)


def test_simulate_under_jit_vmap_grad_and_a_controller():
    # a small planar rod (two curvature coefficients): gradients through simulate compile in seconds
    link = gv.SoftLink(length=1.0, radius=0.02, material=gv.Material(1e5, 1000.0, 1e3, 0.5),
                       basis=gv.StrainBasis((-1, -1, 1, -1, -1, -1)), joint=gv.Joint("fixed"), n_gauss=2)
    robot = gv.Robot(links=(link,), gravity=0.0, rest_strains=(gv.RestStrainSegments(0, (0.0, 0.5, 1.0), ("bend_z",)),))

    def tip_y(u):
        tr = gv.simulate(robot, 0.5, n_steps=20, rest_strain=lambda t: u * jnp.minimum(t / 0.25, 1.0), save_every=20)
        return tr.tip[-1, 1]

    u = jnp.array([2.0, 1.0])  # 1/m, bend_z > 0: the tip swings towards the section's +y (world +y here)
    batch = jax.jit(jax.vmap(tip_y))(jnp.stack([u, 0.5 * u, 0.0 * u]))
    assert batch[0] > batch[1] > 0.0 and abs(float(batch[2])) < 1e-12
    g = jax.jit(jax.grad(tip_y))(u)
    f, eps = jax.jit(tip_y), 1e-5
    fd = [(f(u.at[i].add(eps)) - f(u.at[i].add(-eps))) / (2 * eps) for i in range(2)]
    np.testing.assert_allclose(np.asarray(g), np.asarray(fd), rtol=1e-5, atol=1e-10)
    assert abs(float(g[0] - g[1])) > 1e-3 * abs(float(g[0]))  # the two segments act differently
    # a sampled controller holding the value matches the constant input
    held = gv.simulate(robot, 0.5, n_steps=20, controller=lambda t, q, qd: {"rest_strain": u}, control_every=20,
                       save_every=20)
    const = gv.simulate(robot, 0.5, n_steps=20, rest_strain=u, save_every=20)
    np.testing.assert_allclose(np.asarray(held.q), np.asarray(const.q), atol=1e-12)


def test_equilibrium_is_differentiable_in_the_rest_strain():
    robot = gv.curvature_arm(planar=True)
    tip_x = lambda u: gv.backbone(robot, gv.equilibrium(robot, rest_strain=u).q)[-1, 0]  # noqa: E731
    u = jnp.asarray(np.linspace(1.0, 3.0, 5))
    g = jax.jit(jax.grad(tip_x))(u)
    f, eps = jax.jit(tip_x), 1e-6
    fd = [(f(u.at[i].add(eps)) - f(u.at[i].add(-eps))) / (2 * eps) for i in range(5)]
    np.testing.assert_allclose(np.asarray(g), np.asarray(fd), rtol=1e-5, atol=1e-9)


def test_force_map_is_the_stiffness_weighted_integral():
    # a uniform section: B's column for bend_z on [a, b] is E I times the integral of the raw basis there
    robot = one_link(components=("bend_z",), knots=(0.0, 0.3, 1.0), bending_order=2, torsion_order=-1,
                     stretch_order=-1)
    B = np.asarray(active_strain.force_map(robot))
    EI = 1e7 * np.pi * 0.05**4 / 4
    # Legendre P0, P1(2X - 1), P2(2X - 1) integrated over [0, 0.3] and [0.3, 1]
    P = [lambda x: x, lambda x: x * x - x, lambda x: 2 * x**3 - 3 * x**2 + x]
    col = robot.dof_slices()[0][1] + 3  # bend_z's first coefficient follows bend_y's three
    for j, prim in enumerate(P):
        np.testing.assert_allclose(B[col + j], EI * np.array([prim(0.3) - prim(0.0), prim(1.0) - prim(0.3)]),
                                   rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("kwargs, match", [
    (dict(rest_strain=np.zeros(3)), r"rest_strain.*shape"),
    (dict(rest_strain=np.array([[np.nan, 0.0]])), r"rest_strain.*finite"),
    (dict(rest_strain="1"), r"rest_strain"),
])
def test_bad_rest_strain_is_named(kwargs, match):
    robot = one_link()
    with pytest.raises(ValueError, match=match):
        gv.simulate(robot, 0.1, 0.01, **kwargs)
    with pytest.raises(ValueError, match=match):
        gv.equilibrium(robot, **kwargs)


def test_bad_segments_are_named():
    base = gv.soft_arm(gravity=0.0, torsion_order=-1)
    with pytest.raises(ValueError, match=r"rest_strains\[0\]\.components.*inactive"):
        gv.simulate(dataclasses.replace(base, rest_strains=(gv.RestStrainSegments(0, (0.0, 1.0), ("torsion",)),)),
                    0.1, 0.01)
    with pytest.raises(ValueError, match=r"rest_strains\[0\]\.knots"):
        gv.simulate(dataclasses.replace(base, rest_strains=(gv.RestStrainSegments(0, (0.5, 0.2)),)), 0.1, 0.01)
    with pytest.raises(ValueError, match=r"rest_strain.*no rest_strains"):
        gv.simulate(base, 0.1, 0.01, rest_strain=np.zeros(2))


def test_point_states_match_the_backbone_and_differentiate_to_velocities():
    robot = gv.curvature_arm()
    rng = np.random.default_rng(1)
    q, qd = jnp.asarray(rng.normal(0, 2, robot.n_dofs)), jnp.asarray(rng.normal(0, 1, robot.n_dofs))
    sites = gv.sample_sites(robot)
    p, v, R = point_states(robot, q, qd, sites)
    np.testing.assert_allclose(np.asarray(p), np.asarray(gv.backbone(robot, q)), atol=1e-13)
    R_ref, _ = gv.frames(robot, q)
    np.testing.assert_allclose(np.asarray(R), np.asarray(R_ref), atol=1e-13)
    nodes = node_sites(robot)
    eps = 1e-6
    fd = (point_states(robot, q + eps * qd, qd, nodes)[0] - point_states(robot, q - eps * qd, qd, nodes)[0]) / (2 * eps)
    np.testing.assert_allclose(np.asarray(point_states(robot, q, qd, nodes)[1]), np.asarray(fd), atol=1e-7)


def test_polar_torsion_constant_twists_an_ellipse_as_sorosim():
    # a torque T twists a rod by T L / (G Jt); "polar" takes Jt = Iy + Iz (SoRoSim's choice)
    a, b, T, L, E = 0.03, 0.015, 0.5, 1.0, 1e7
    G = E / 3
    for kind, Jt in (("saint_venant", np.pi * a**3 * b**3 / (a * a + b * b)),
                     ("polar", np.pi * a * b * (a * a + b * b) / 4)):
        link = gv.SoftLink(length=L, shape="ellipse", width=2 * a, height=2 * b, torsion_constant=kind,
                           material=gv.Material(E, 1000.0, 0.0, 0.5), basis=gv.StrainBasis((0, -1, -1, -1, -1, -1)),
                           joint=gv.Joint("fixed"), n_gauss=2)
        robot = gv.Robot(links=(link,), gravity=0.0)
        # the torque's virtual work T dq on the one torsion coordinate q, the twist angle (strain q / L)
        res = gv.equilibrium(robot, strain_force=np.array([T]))
        np.testing.assert_allclose(float(res.q[0]), T * L / (G * Jt), rtol=1e-12)
    with pytest.raises(ValueError, match="torsion_constant"):
        gv.simulate(gv.Robot(links=(dataclasses.replace(link, torsion_constant="bogus"),)), 0.1, 0.01)
