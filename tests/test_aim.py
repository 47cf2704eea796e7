"""The aiming solver (gvsjax.tasks.aim) on analytic misses: the Gauss-Newton step along the box's
bound, a residual vector against its scalar norm, and the flight's closest-point residual."""

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.tasks import aim, ballistics


def test_the_step_slides_along_a_bound_the_miss_presses_against():
    """c(a) = |a_1 - 10 (a_0 + 1) - t| from a_0 = -1, the box's edge: the miss falls fastest
    outwards in a_0, so clipping the whole step keeps 1% of it per step; freezing a_0 and stepping
    in a_1 hits the target (at a_1 = t) in one step. Under jit, as the tasks run it."""
    cost = lambda a, t: jnp.abs(a[1] - 10.0 * (a[0] + 1.0) - t[0])  # noqa: E731
    start = jnp.array([[-1.0, 0.0], [-1.0, -0.4]])
    targets = jnp.array([[0.5], [0.3]])
    a, c = jax.jit(lambda a, t: aim.gauss_newton(cost, a, t, 3))(start, targets)
    assert np.max(np.asarray(c)) < 1e-12
    np.testing.assert_allclose(np.asarray(a), [[-1.0, 0.5], [-1.0, 0.3]], atol=1e-12)
    # inside the box, or at a bound it moves away from, the step is the plain minimum-norm one
    r, J = jnp.array([0.2]), jnp.array([[3.0, 4.0]])
    for x in ([0.0, 0.0], [0.0, 1.0]):
        np.testing.assert_allclose(np.asarray(aim.box_step(r, J, jnp.array(x))), [-0.024, -0.032], atol=1e-9)
    np.testing.assert_allclose(np.asarray(aim.box_step(r, J, jnp.array([0.0, -1.0]))), [-0.2 / 3, 0.0], atol=1e-9)


def test_a_residual_vector_converges_where_its_norm_crawls():
    """r(a) = A tanh(a) - t, A badly scaled: Gauss-Newton on the residual converges quadratically
    (1e-12 in 6 steps); on its norm, a cone around the solution, the same 6 steps leave
    centimetres. The solver takes either, and reports the norm as the miss."""
    A = jnp.array([[1.0, 0.2], [0.0, 0.05]])
    res = lambda a, t: A @ jnp.tanh(a) - t  # noqa: E731
    norm = lambda a, t: jnp.sqrt(jnp.sum(res(a, t) ** 2))  # noqa: E731
    truth = np.array([[0.4, -0.6], [-0.3, 0.5], [0.7, 0.7]])
    targets = jnp.asarray(np.tanh(truth) @ np.asarray(A).T)
    start = jnp.zeros((3, 2))
    a, c = jax.jit(lambda a, t: aim.gauss_newton(res, a, t, 6))(start, targets)
    assert np.max(np.asarray(c)) < 1e-12
    np.testing.assert_allclose(np.asarray(a), truth, atol=1e-9)
    _, c_norm = jax.jit(lambda a, t: aim.gauss_newton(norm, a, t, 6))(start, targets)
    assert np.min(np.asarray(c_norm)) > 1e-3
    # the residual's miss is its norm
    assert float(aim.miss_of(res, start[0], targets[0])) == float(jnp.linalg.norm(res(start[0], targets[0])))


def test_the_closest_offset_moves_as_the_closest_point_does():
    """``ballistics.closest_offset`` (the closest point minus the target) is the residual whose
    norm is ``closest_approach``; its derivative in (p0, v0) matches central differences of the
    closest point (which moves along the flight too) for targets a millimetre off the path, not the
    derivative at a fixed flight time (off by the velocity times d tau*)."""
    g, rng = 9.81, np.random.default_rng(4)
    for _ in range(4):
        p0, v0 = rng.uniform(-1, 1, 3), rng.uniform([-6, -6, 2], [6, 6, 8], 3)
        tau = rng.uniform(0.2, 0.6) * float(ballistics.floor_time(jnp.asarray(p0), jnp.asarray(v0), g, -1.95))
        on = np.asarray(ballistics.flight_point(jnp.asarray(p0), jnp.asarray(v0), tau, g))
        target = jnp.asarray(on + 1e-3 * np.cross(v0, rng.normal(size=3)) / np.linalg.norm(v0))

        def offset(x, target=target):
            end = ballistics.floor_time(x[:3], x[3:], g, -1.95)
            return ballistics.closest_offset(x[:3], x[3:], target, g, end)[0]

        x = jnp.asarray(np.concatenate([p0, v0]))
        r = offset(x)
        d, _ = ballistics.closest_approach(x[:3], x[3:], target, g, ballistics.floor_time(x[:3], x[3:], g, -1.95))
        np.testing.assert_allclose(float(jnp.linalg.norm(r)), float(d), rtol=1e-12)
        J = np.asarray(jax.jacfwd(offset)(x))
        eps = 1e-6
        fd = np.stack([(np.asarray(offset(x.at[i].add(eps))) - np.asarray(offset(x.at[i].add(-eps)))) / (2 * eps)
                       for i in range(6)], 1)
        np.testing.assert_allclose(J, fd, atol=1e-2 * np.max(np.abs(fd)))
