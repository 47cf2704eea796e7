"""The SPD solves of ``gvsjax.core.linalg`` against NumPy's dense solver, in both layouts,
under jit, vmap and grad, and inside the dynamics of a robot large enough to use the
stacked one."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax.core import dynamics, lie, linalg


def _spd(n: int, seed: int, cond: float = 1e4) -> np.ndarray:
    """A random SPD matrix with eigenvalues spread over ``cond`` (as a mass matrix's are)."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return (Q * np.geomspace(1.0, cond, n)) @ Q.T


@pytest.mark.parametrize("n", [1, 2, 7, 16, 30])
def test_ldl_solve_matches_numpy(n):
    A, b = _spd(n, n), np.random.default_rng(100 + n).normal(size=n)
    x = jax.jit(linalg.ldl_solve)(jnp.asarray(A), jnp.asarray(b))  # eager: one dispatch per scalar op
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(A, b), rtol=1e-10, atol=1e-12)


def test_ldl_solve_reads_only_the_lower_triangle():
    A, b = _spd(9, 3), np.ones(9)
    garbage = np.triu(np.full((9, 9), 1e3), 1)
    x = linalg.ldl_solve(jnp.asarray(np.tril(A) + garbage), jnp.asarray(b))
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(A, b), rtol=1e-10)


def test_ldl_solve_under_jit_vmap_and_grad():
    n, batch = 12, 5
    As = np.stack([_spd(n, s) for s in range(batch)])
    bs = np.random.default_rng(0).normal(size=(batch, n))
    xs = jax.jit(jax.vmap(linalg.ldl_solve))(jnp.asarray(As), jnp.asarray(bs))
    np.testing.assert_allclose(np.asarray(xs), np.linalg.solve(As, bs[..., None])[..., 0], rtol=1e-9, atol=1e-12)

    # d(c . x)/db = A^-1 c and d(c . x)/dA = -(A^-1 c) x^T (only the lower triangle is
    # read, so its gradient collects both symmetric halves)
    A, b, c = As[0], bs[0], np.arange(1.0, n + 1)
    gA, gb = jax.jit(jax.grad(lambda A, b: jnp.dot(c, linalg.ldl_solve(A, b)), argnums=(0, 1)))(
        jnp.asarray(A), jnp.asarray(b))
    lam, x = np.linalg.solve(A, c), np.linalg.solve(A, b)
    np.testing.assert_allclose(np.asarray(gb), lam, rtol=1e-9)
    full = -np.outer(lam, x)
    np.testing.assert_allclose(np.asarray(gA), np.tril(full + full.T, -1) + np.diag(np.diag(full)), rtol=1e-8,
                               atol=1e-12)


def test_ldl_solve_names_bad_shapes():
    with pytest.raises(ValueError, match="ldl_solve: A must be"):
        linalg.ldl_solve(jnp.eye(3), jnp.ones(4))


def test_both_layouts_of_solve_spd_agree_with_structural_zeros():
    """A block-diagonal system (as the stiffness of separate strains is) given with Python
    zeros: the scalar layout prunes them, the stacked one fills them in; both solve it."""
    n = linalg.STACKED_MIN_DOFS + 2
    A = np.zeros((n, n))
    for s in (slice(0, 5), slice(5, n)):
        k = s.stop - s.start
        A[s, s] = _spd(k, k)
    b = np.random.default_rng(1).normal(size=n)
    As = [[0 if A[i, j] == 0 else jnp.asarray(A[i, j]) for j in range(n)] for i in range(n)]
    bs = [jnp.asarray(v) for v in b]
    stacked = linalg.solve_spd(As, bs)
    scalar = linalg._solve_scalar(As, bs)
    ref = np.linalg.solve(A, b)
    np.testing.assert_allclose(np.array([lie.as_array(v) for v in stacked]), ref, rtol=1e-10)
    np.testing.assert_allclose(np.array([lie.as_array(v) for v in scalar]), ref, rtol=1e-10)
    assert linalg.solve_spd(As, [0] * n) == [0] * n  # no load, no motion: still structural


def test_a_24_dof_rod_accelerates_as_numpy_solves_its_dynamics():
    """M qdd = F for a spatial rod with all six strains of order 3 (24 DoFs: the stacked
    solve), against NumPy's solve of the same M and F."""
    robot = gv.rod_3d(order=3, n_gauss=5, gravity=9.81)
    n = robot.n_dofs
    assert n >= linalg.STACKED_MIN_DOFS
    rng = np.random.default_rng(0)
    q, qd = 0.05 * rng.normal(size=n), 0.5 * rng.normal(size=n)

    def parts(q, qd):
        M, F = dynamics.mass_and_forces(robot, [q[i] for i in range(n)], [qd[i] for i in range(n)])
        acc = dynamics.split_solve(robot, M, F, [])
        return dynamics.full_matrix(M, n), jnp.stack([lie.as_array(f) for f in F]), jnp.stack(acc)

    M, F, acc = jax.jit(parts)(jnp.asarray(q), jnp.asarray(qd))
    np.testing.assert_allclose(np.asarray(acc), np.linalg.solve(np.asarray(M), np.asarray(F)), rtol=1e-9,
                               atol=1e-9 * float(np.abs(acc).max()))


def test_stacked_solves_switches_the_layout_while_tracing_and_restores_it():
    """Inside the block a 12-unknown solve traces as the stacked LDL^T (far fewer equations than
    the entry-by-entry one), both solve it, and the threshold is back afterwards, also after an
    error; a bad threshold is named."""
    n = 12
    A, b = _spd(n, 5), np.random.default_rng(2).normal(size=n)

    def solver():  # a new function per trace: JAX caches traces per function
        return lambda A, b: jnp.stack(linalg.solve_spd([[A[i, j] for j in range(n)] for i in range(n)],
                                                       [b[i] for i in range(n)]))

    before = linalg.STACKED_MIN_DOFS
    scalar_eqns = len(jax.make_jaxpr(solver())(A, b).eqns)
    x_scalar = jax.jit(solver())(jnp.asarray(A), jnp.asarray(b))
    with linalg.stacked_solves(4):
        assert linalg.STACKED_MIN_DOFS == 4
        stacked_eqns = len(jax.make_jaxpr(solver())(A, b).eqns)
        x_stacked = jax.jit(solver())(jnp.asarray(A), jnp.asarray(b))
    assert linalg.STACKED_MIN_DOFS == before
    assert stacked_eqns < scalar_eqns / 2, (stacked_eqns, scalar_eqns)
    for x in (x_scalar, x_stacked):
        np.testing.assert_allclose(np.asarray(x), np.linalg.solve(A, b), rtol=1e-10)
    with pytest.raises(RuntimeError), linalg.stacked_solves(2):
        raise RuntimeError
    assert linalg.STACKED_MIN_DOFS == before
    with pytest.raises(ValueError, match="min_dofs=0 is invalid"), linalg.stacked_solves(0):
        pass


def test_reverse_gradient_through_stacked_ars443_steps_matches_finite_differences():
    """d tip / d (damping, gravity) through ten ``ars443`` steps of a 12-DoF rod traced with
    stacked solves, against central differences of the default layout's forward simulation."""
    def tip_z(p):
        robot = gv.rod_3d(order=1, n_gauss=3, damping=p[0], gravity=p[1])
        return gv.simulate(robot, 0.05, n_steps=10, integrator="ars443").tip[-1, 2]

    p = jnp.array([1e5, 9.81])
    with linalg.stacked_solves(1):
        g = jax.jit(jax.grad(tip_z))(p)
        eager = tip_z(p)  # an eager run's cached program is keyed on the layout
    assert abs(float(eager) - float(tip_z(p))) < 1e-12
    h = np.array([1e2, 1e-3])
    fd = [(tip_z(p + h[i] * e) - tip_z(p - h[i] * e)) / (2 * h[i]) for i, e in enumerate(np.eye(2))]
    np.testing.assert_allclose(np.asarray(g), np.asarray(fd), rtol=1e-5)
