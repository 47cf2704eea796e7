"""Equations of motion (gvsjax.core.dynamics): the recursion against the Lagrangian by autodiff,
the mass matrix at rest against its closed form, energy conservation of a rigid-soft 3D
chain on free joints, and 3D statics (lateral-load symmetry, planar bending, pure torsion)."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import rigid_soft_chain

from gvsjax.core import dynamics, lie


def _mf_arrays(robot, q, qd):
    n = robot.n_dofs
    M, F = dynamics.mass_and_forces(robot, [q[i] for i in range(n)], [qd[i] for i in range(n)])
    return dynamics.full_matrix(M, n), jnp.stack([lie.as_array(f) for f in F])


def _lagrangian(robot):
    def L(q, qd):
        e = gv.energy(robot, q, qd)
        return e["kinetic"] - e["elastic"] - e["gravity"] - e["loads"]

    return L


# The identity holds for any quadrature: the 3D robots use the fewest Gauss points their
# bases allow, which compiles fastest.
ROBOTS = {
    "paper_arm": lambda: gv.paper_arm(tip_force=5.886, tip_mass=0.3, damping=0.0),
    "rod_3d": lambda: gv.rod_3d(gravity=9.81, damping=0.0, n_gauss=2),
    "rigid_soft": lambda: rigid_soft_chain(n_gauss=2),
}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.extended) if n in ("rigid_soft", "rod_3d") else n
                                  for n in sorted(ROBOTS)])
def test_recursion_equals_lagrangian_autodiff(name):
    """M and F from the recursion equal those of the discrete Lagrangian,
    differentiated by autodiff: M = d2T/dqd2, F = dL/dq - (d2L/dqd dq) qd."""
    robot = ROBOTS[name]()
    n = robot.n_dofs
    rng = np.random.default_rng(0)
    q = jnp.asarray(rng.normal(scale=0.8, size=n))
    qd = jnp.asarray(rng.normal(scale=1.5, size=n))
    M, F = _mf_arrays(robot, q, qd)
    L = _lagrangian(robot)
    M_ref = jax.hessian(L, argnums=1)(q, qd)
    dL_dq = jax.grad(L, argnums=0)(q, qd)
    mixed = jax.jacfwd(jax.grad(L, argnums=1), argnums=0)(q, qd)
    F_ref = dL_dq - mixed @ qd
    np.testing.assert_allclose(M, M_ref, atol=1e-9 * float(jnp.abs(M).max()))
    np.testing.assert_allclose(F, F_ref, atol=1e-8 * (1 + float(jnp.abs(F).max())))
    assert np.all(np.linalg.eigvalsh(np.asarray(M)) > 0)


def test_mass_matrix_at_rest_matches_closed_form():
    M, _ = _mf_arrays(gv.paper_arm(), jnp.zeros(3), jnp.zeros(3))
    ref = [[2.622903, 0.984202, 0.262618], [0.984202, 0.394335, 0.109697],
           [0.262618, 0.109697, 0.031412]]  # gvs-notes 10.3 (closed form, 9.4)
    np.testing.assert_allclose(M, ref, atol=2e-6)


@pytest.mark.slow
@pytest.mark.extended
def test_rigid_soft_chain_conserves_energy_with_free_joints():
    robot = rigid_soft_chain(n_gauss=2)  # conservation holds for any quadrature; 2 points compile fastest
    qd0 = np.zeros(robot.n_dofs)
    qd0[0], qd0[1] = 1.0, -0.5
    traj = gv.simulate(robot, 2.0, 1e-3, qd0=qd0, save_every=20)
    assert np.all(np.isfinite(traj.q))
    e = jax.vmap(lambda q, v: gv.energy(robot, q, v))(traj.q, traj.qd)
    total = np.asarray(e["kinetic"] + e["elastic"] + e["gravity"] + e["loads"])
    assert np.ptp(total) < 1e-6 * (1 + np.abs(total).max())
    assert float(np.ptp(traj.q[:, 0])) > 0.1  # it really moved


def _static_state(robot, duration=20.0, dt=0.05):
    """Equilibrium by dynamic relaxation with IMEX Euler. Its fixed point is exactly
    F(q) = 0 whatever the step, so a long step relaxes in few steps; the run must
    have come to rest."""
    traj = gv.simulate(robot, duration, dt, integrator="imex", save_every=int(round(duration / dt)))
    assert float(jnp.abs(traj.qd[-1]).max()) < 1e-10, "not yet at rest"
    return traj


def _loaded_rod(force_y=0.0, force_z=0.0, torque_x=0.0):
    """The 3D rod (all six strains, linear bending as in the planar paper arm)
    with all three tip loads present, so every case shares one compiled program;
    the magnitudes pick the case."""
    rod = gv.rod_3d(order=(0, 1, 1, 0, 0, 0), n_gauss=3, basis="legendre")
    tip_load = lambda m, d, moment=False: gv.PointLoad(magnitude=m, link=0, X=1.0, direction=d,  # noqa: E731
                                                       moment=moment)
    return rod.replace(loads=(tip_load(force_y, (0.0, 1.0, 0.0)), tip_load(force_z, (0.0, 0.0, 1.0)),
                              tip_load(torque_x, (1.0, 0.0, 0.0), moment=True)))


@pytest.mark.slow
@pytest.mark.extended
def test_3d_rod_lateral_load_is_symmetric_and_matches_planar_bending():
    P = 3.0
    tip_y = np.asarray(_static_state(_loaded_rod(force_y=P)).tip[-1])
    tip_z = np.asarray(_static_state(_loaded_rod(force_z=P)).tip[-1])
    # the circular section makes z-loading the y-loading turned 90 deg about x
    np.testing.assert_allclose([tip_z[0], tip_z[2], tip_z[1]], [tip_y[0], tip_y[1], tip_y[2]], atol=1e-9)
    # planar, bending-only arm pointing along +x with the same load (gravity off)
    arm = gv.paper_arm(gravity=0.0, tip_force=-P)  # -P along -y = +P along +y
    planar = gv.simulate(arm, 20.0, 5e-3, base_angle=lambda t: jnp.pi / 2, integrator="imex",
                         save_every=4000)
    # shear and stretch compliance of the 6-strain rod differ by O((r/L)^2)
    np.testing.assert_allclose(tip_y[:2], np.asarray(planar.tip[-1, :2]), atol=3e-3)
    assert tip_y[1] > 0.02


@pytest.mark.extended
def test_pure_tip_torque_gives_pure_torsion():
    torque = 0.2  # N m about the rod axis
    rod = _loaded_rod(torque_x=torque)
    traj = _static_state(rod)
    q = np.asarray(traj.q[-1])
    R = np.asarray(gv.frames(rod, jnp.asarray(q))[0][-1])
    G = 5e6 / 3.0
    J = np.pi * 0.05**4 / 2
    twist = np.arctan2(R[2, 1], R[1, 1])
    assert twist == pytest.approx(torque * 1.0 / (G * J), rel=1e-6)
    np.testing.assert_allclose(traj.tip[-1], [1.0, 0.0, 0.0], atol=1e-9)  # no bending
