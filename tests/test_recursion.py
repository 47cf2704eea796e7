"""The two ways the kinematic pass visits a soft link (``SoftLink.recursion``): unrolled
(one traced Magnus step per interval) and scanned (one step inside ``lax.scan``, the
Jacobian's columns as arrays). They compute the same sums in other orders, so every
output must agree to rounding, on robots that exercise what the scan has to carry:
a joint before the link, a child after it, a taper, a polynomial rest strain, point
loads and masses between Gauss points, a distributed load, float32."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import raises_naming

from gvsjax.core import dynamics, kinematics, lie, linalg, scan
from gvsjax.core.validation import check_robot

Z, Y = (0.0, 0.0, 1.0), (0.0, 1.0, 0.0)


def _with(robot: gv.Robot, recursion: str) -> gv.Robot:
    return robot.replace(links=tuple(link.replace(recursion=recursion) if isinstance(link, gv.SoftLink) else link
                                     for link in robot.links))


def _drag(X, R, p, eta, t):
    """Linear drag on the section's velocity plus a twisting couple growing along the rod (per metre)."""
    return jnp.concatenate([jnp.array([0.3 * X, 0.0, 0.0]), -2.0 * eta[3:]])


def chain() -> gv.Robot:
    """A revolute hub, a tapered rod with all six strains (linear bending), a rest strain
    that is a polynomial in X, a second rod hanging from its tip, a point load and a
    point mass between Gauss points, and a distributed load."""
    rest = np.zeros((6, 2))
    rest[:, 0] = (0.2, 0.0, 0.5, 1.0, 0.0, 0.0)
    rest[1, 1] = 1.5  # bending about y grows along the rod
    first = gv.SoftLink(length=0.8, radius=0.04, taper=0.6, rest_strain=rest, n_gauss=4,
                        material=gv.Material(2e6, 1100.0, 3e4, 0.45),
                        basis=gv.StrainBasis(orders=(0, 1, 1, 0, 0, 0), kind="legendre"),
                        joint=gv.Joint("revolute", Z))
    second = gv.SoftLink(length=0.5, radius=0.03, n_gauss=3, material=gv.Material(1e6, 1000.0, 1e4, 0.5),
                         basis=gv.StrainBasis(orders=(0, 0, 0, 0, -1, -1)),
                         joint=gv.Joint("fixed", rotation=gv.axis_rotation(Y, 0.4)))
    return gv.Robot(links=(first, second), gravity=9.81, distributed=_drag,
                    loads=(gv.PointLoad(magnitude=3.0, link=0, X=0.37, direction=(0.0, 0.6, 0.8)),),
                    masses=(gv.PointMass(mass=0.2, link=1, X=0.55),))


def single() -> gv.Robot:
    """``chain``'s first rod alone on a fixed joint, unshearable (6 DoFs: the scan computes its Magnus
    steps before the loop), with its taper, polynomial rest strain, a point load, a point mass and the
    distributed load."""
    link = chain().links[0].replace(joint=gv.Joint("fixed"), basis=gv.StrainBasis(orders=(0, 1, 1, 0, -1, -1),
                                                                                   kind="legendre"))
    return gv.Robot(links=(link,), gravity=9.81, distributed=_drag,
                    loads=(gv.PointLoad(magnitude=3.0, link=0, X=0.37, direction=(0.0, 0.6, 0.8)),),
                    masses=(gv.PointMass(mass=0.2, link=0, X=0.55),))


def _state(robot, seed=0, dtype=np.float64):
    rng = np.random.default_rng(seed)
    n = robot.n_dofs
    return jnp.asarray(0.4 * rng.normal(size=n), dtype), jnp.asarray(rng.normal(size=n), dtype)


def _outputs(robot, q, qd):
    n = robot.n_dofs
    M, F = dynamics.mass_and_forces(robot, [q[i] for i in range(n)], [qd[i] for i in range(n)], t=0.3)
    R, p = gv.frames(robot, q)
    return dict(M=dynamics.full_matrix(M, n), F=jnp.stack([lie.as_array(f) for f in F]), R=R, p=p,
                J=gv.jacobians(robot, q), tip=jnp.concatenate(gv.tip_state(robot, q, qd)),
                energy=jnp.stack(list(dynamics.energy(robot, q, qd).values())))


def test_auto_scans_the_links_of_large_robots():
    assert scan.uses_scan(gv.rod_3d(order=1, n_gauss=3).links[0])  # 12 strain DoFs
    # 6 spatial DoFs: unrolled up to 3 Gauss points (a small program), scanned from 4 (its compile time)
    assert not scan.uses_scan(gv.rod_3d(order=0, n_gauss=3).links[0])
    assert scan.uses_scan(gv.rod_3d(order=0, n_gauss=4).links[0]) and scan.uses_scan(gv.rod_3d(order=0).links[0])
    assert not scan.uses_scan(gv.paper_arm().links[0])  # planar: one active strain keeps it small
    assert not scan.uses_scan(gv.tendon_arm().links[1], gv.tendon_arm().n_dofs)
    assert not scan.uses_scan(gv.rod_3d(order=0, n_gauss=1).links[0], 12)  # one Gauss point: nothing to loop over
    # a link of 6 DoFs in a chain of two: every link of the 12-DoF robot is scanned
    link = gv.rod_3d(length=0.5, order=0, n_gauss=2).links[0]
    assert not scan.uses_scan(link, 6) and scan.uses_scan(link, 12)
    assert scan.uses_scan(link.replace(recursion="scan"), 6)
    assert not scan.uses_scan(link.replace(recursion="unrolled"), 12)
    # the kinematic pass asks with the robot's DoFs: both links come back as one stacked point each
    chain2 = gv.Robot(links=(link, link))
    z = [0.0] * chain2.n_dofs
    stacked = [p.link for p in kinematics.forward(chain2, z, z) if np.ndim(p.X) == 1]
    assert stacked == [0, 1]
    one = gv.Robot(links=(link,))
    assert not any(np.ndim(p.X) for p in kinematics.forward(one, z[:6], z[:6]))


@pytest.mark.extended
@pytest.mark.parametrize("make", [chain, single])
def test_scan_and_unrolled_agree_on_every_output(make):
    robot = make()
    assert (robot.n_dofs <= scan.HOIST_MAX_DOFS) == (make is single)  # both layouts of the scan
    q, qd = _state(robot)
    a = _outputs(_with(robot, "unrolled"), q, qd)  # op by op: no compile
    scanned = _with(robot, "scan")
    b = jax.jit(lambda q, qd: _outputs(scanned, q, qd))(q, qd)
    for key in a:
        scale = max(1.0, float(jnp.abs(a[key]).max()))
        np.testing.assert_allclose(b[key], a[key], rtol=0, atol=1e-12 * scale, err_msg=key)
    assert float(jnp.abs(a["M"] - a["M"].T).max()) == 0.0
    assert float(jnp.abs(a["F"]).max()) > 1.0  # the comparison is not between zeros


@pytest.mark.extended
def test_scan_matches_under_jit_vmap_and_grad():
    robot = chain()
    n = robot.n_dofs
    q, qd = _state(robot)

    def tip_x(E, rec):
        r = _with(robot, rec)
        r = r.replace(links=(r.links[0].replace(material=r.links[0].material.replace(youngs_modulus=E)),
                             *r.links[1:]))
        M, F = dynamics.mass_and_forces(r, [q[i] for i in range(n)], [qd[i] for i in range(n)])
        acc = linalg.solve_spd(M, F)  # linear in E: squared, so the gradient differs between Es
        return lie.as_array(acc[0]) ** 2 + gv.tip_state(r, q, qd)[0][0]

    Es = jnp.array([1e6, 4e6])
    vals, grads = jax.jit(jax.vmap(jax.value_and_grad(lambda E: tip_x(E, "scan"))))(Es)
    ref, ref_grad = jax.value_and_grad(tip_x)(Es[1], "unrolled")  # op by op: no compile
    np.testing.assert_allclose(vals[1], ref, rtol=1e-11)
    np.testing.assert_allclose(grads[1], ref_grad, rtol=1e-8)
    assert float(jnp.abs(grads[0] - grads[1])) > 1e-3 * float(jnp.abs(grads[1]))  # the batch is not one value
    assert float(jnp.abs(ref_grad)) > 0


@pytest.mark.extended
def test_scan_keeps_float32():
    robot = gv.rod_3d(order=1, n_gauss=3, gravity=9.81)
    q, qd = _state(robot, 1, np.float32)
    scanned = _with(robot, "scan")
    out = jax.jit(lambda q, qd: _outputs(scanned, q, qd))(q, qd)
    ref = _outputs(_with(robot, "unrolled"), q, qd)
    for key in out:
        assert out[key].dtype == jnp.float32, key
        scale = max(1.0, float(jnp.abs(ref[key]).max()))
        np.testing.assert_allclose(out[key], ref[key], rtol=0, atol=2e-5 * scale, err_msg=key)


def test_a_bad_recursion_is_refused_by_name():
    link = gv.rod_3d().links[0].replace(recursion="vectorised")
    raises_naming("links[0].recursion", check_robot, gv.Robot(links=(link,)))


@pytest.mark.parametrize("recursion", [pytest.param("unrolled", marks=pytest.mark.extended), "scan"])
def test_a_spatial_cantilever_under_a_tip_couple_is_a_closed_form_arc(recursion):
    """A pure end couple bends a rod into an arc of curvature m / EI (exact in Cosserat
    theory); with constant bending about y and z the tip sits on that arc."""
    E, r, L, m = 5e6, 0.05, 1.0, 20.0
    EI = E * np.pi * r**4 / 4
    rod = gv.rod_3d(order=0, n_gauss=3, youngs_modulus=E, radius=r, length=L)
    couple = np.array([0.0, 0.6, 0.8]) * m
    rod = _with(rod.replace(loads=(gv.PointLoad(magnitude=m, link=0, X=1.0, direction=(0.0, 0.6, 0.8),
                                                 follower=True, moment=True),)), recursion)
    q = gv.equilibrium(rod).q
    tip = np.asarray(gv.backbone(rod, q)[-1])
    k = m / EI
    axis = couple / m
    # the arc turns about the couple's axis with radius 1/k: chord along x rotated by k L / 2
    theta = k * L
    expected = np.array([np.sin(theta), 0.0, 0.0]) / k + (1 - np.cos(theta)) / k * np.cross(axis, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(tip, expected, atol=1e-3 * L)


def three_rods() -> gv.Robot:
    """A revolute hub and three scanned soft links end to end (other lengths, radii, a taper, a rest strain on the
    middle one, gravity, a tip load): one run of ``scan.chain_groups``."""
    basis = gv.StrainBasis(orders=(0, 1, 0, -1, -1, -1), kind="legendre")  # 4 DoFs each, 13 with the hub
    mat = gv.Material(3e6, 1000.0, 2e4, 0.5)
    rest = np.zeros(6)
    rest[:4] = (0.3, 0.0, -0.8, 1.0)
    links = (gv.SoftLink(length=0.3, radius=0.03, material=mat, basis=basis, n_gauss=2, recursion="scan",
                         joint=gv.Joint("revolute", axis=(0.0, 0.0, 1.0))),
             gv.SoftLink(length=0.2, radius=0.025, taper=0.8, material=mat, basis=basis, n_gauss=2,
                         rest_strain=rest, recursion="scan", joint=gv.Joint("fixed")),
             gv.SoftLink(length=0.4, radius=0.02, material=mat, basis=basis, n_gauss=3, recursion="scan",
                         joint=gv.Joint("fixed")))
    return gv.Robot(links=links, gravity=9.81, loads=(gv.PointLoad(magnitude=2.0, link=2, X=1.0,
                                                                  direction=(0.0, 0.6, 0.8)),))


def test_a_chain_of_links_is_one_scan_with_the_same_outputs_and_gradients(monkeypatch):
    robot = three_rods()
    assert scan.chain_groups(robot) == [[0, 1, 2]]
    n = robot.n_dofs
    q, qd = _state(robot, 2)
    z = [0.0] * n
    jaxpr = jax.make_jaxpr(lambda q: dynamics.mass_and_forces(robot, [q[i] for i in range(n)], z))(q)
    assert sum(e.primitive.name == "scan" for e in jaxpr.jaxpr.eqns) == 1  # one Magnus step traced, not three

    def scalar(q):  # a smooth function of every output of the dynamics
        out = _outputs(robot, q, qd)
        return jnp.sum(jnp.sin(out["M"])) + 1e-3 * jnp.sum(out["F"] ** 2) + jnp.sum(out["p"])

    grouped = jax.jit(lambda q: _outputs(robot, q, qd))(q)
    value, grad = jax.jit(jax.value_and_grad(scalar))(q)
    monkeypatch.setattr(scan, "chain_groups", lambda r: [[i] for i in range(len(r.links))])
    alone = jax.jit(lambda q: _outputs(robot, q, qd))(q)
    for key in grouped:
        scale = max(1.0, float(jnp.abs(alone[key]).max()))
        np.testing.assert_allclose(grouped[key], alone[key], rtol=0, atol=1e-13 * scale, err_msg=key)
    assert float(jnp.abs(alone["F"]).max()) > 1.0  # the comparison is not between zeros
    # the gradient through the run's scan (rematerialised) against central differences
    f = jax.jit(scalar)
    h = 1e-6
    fd = np.array([(f(q.at[i].add(h)) - f(q.at[i].add(-h))) / (2 * h) for i in range(n)])
    np.testing.assert_allclose(np.asarray(grad), fd, rtol=1e-6, atol=1e-6 * float(np.abs(fd).max()))
    assert float(value) == float(f(q))
