"""Aiming a one-shot task through the simulator: Gauss-Newton on its miss.

A task passes its miss as a callable of (action, target): either the scalar miss c(a) (m, >= 0)
or a residual vector r(a) whose norm is the miss (the flight's closest point minus the target).
Each step is the minimum-norm Gauss-Newton step onto the solution set, da = -J^+ r (J the
residual's Jacobian through the simulator; for a scalar miss -c grad c / |grad c|^2). A vector
residual converges quadratically where the scalar miss, a cone around its zero set, converges
only linearly. Coordinates at a bound of the box [-1, 1]^d that the step would leave are frozen
and the step recomputed in the others (clipping the whole step would discard its descent when a
steep coordinate presses against the box); a line search over step fractions (1, 1/2, 1/4, 1/8
or no step), each trial clipped to the box, takes the best. ``make_solver`` refines the
``n_starts`` best of a grid of coarse starts (cost only); ``plan_targets`` starts from given
actions (a policy's), steps until each target converges, and falls back to multi-start
Gauss-Newton where the miss stays large.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.tasks.ballistics import distance

FRACTIONS = (1.0, 0.5, 0.25, 0.125, 0.0)
# (action (d,), target) -> the miss (m, a scalar) or a residual (m,) whose norm is the miss
Cost = Callable[[jax.Array, jax.Array], jax.Array]


def coarse_starts(n_side: int = 3, dim: int = 2) -> jax.Array:
    """(n_side^dim, dim) actions on a grid inside the box."""
    g = jnp.linspace(-0.8, 0.8, n_side)
    return jnp.stack(jnp.meshgrid(*([g] * dim), indexing="ij"), -1).reshape(-1, dim)


def miss_of(cost: Cost, action, target) -> jax.Array:
    """The miss (m) of one action: ``cost``'s value, or its residual's norm."""
    c = cost(action, target)
    return c if c.ndim == 0 else distance(c)


def _linearized(cost: Cost, a, t) -> tuple[jax.Array, jax.Array]:
    """The residual (m,) and its Jacobian (m, d) at ``a``: a scalar miss is the residual (c,)."""
    shape = jax.eval_shape(cost, a, t).shape
    if shape == ():
        c, g = jax.value_and_grad(cost)(a, t)
        return c[None], g[None]
    def both(x):  # the residual as output and aux: one evaluation gives it and its Jacobian
        y = cost(x, t)
        return y, y

    jac = jax.jacfwd if a.shape[0] <= shape[0] else jax.jacrev
    J, r = jac(both, has_aux=True)(a)
    return r, J


def box_step(r: jax.Array, J: jax.Array, a: jax.Array) -> jax.Array:
    """The minimum-norm Gauss-Newton step -J^+ r at ``a`` (d,), with the coordinates at a bound of
    [-1, 1] that it would leave frozen and the step recomputed in the others (d rounds: freezing
    one coordinate can turn another outward). The pseudo-inverse (singular values below 1e-10 of
    the largest dropped) serves a rank-deficient J: a residual across the flight spans one
    dimension less than it has."""
    free = jnp.ones_like(a)
    step = jnp.zeros_like(a)
    for _ in range(a.shape[0]):
        step = -jnp.linalg.pinv(J * free, rtol=1e-10) @ r
        out = ((a <= -1.0) & (step < 0.0)) | ((a >= 1.0) & (step > 0.0))
        free = jnp.where(out, 0.0, free)
    return step * free


def gauss_newton(cost: Cost, actions, targets, n_iters: int):
    """``n_iters`` line-searched Gauss-Newton steps (``box_step``) towards miss 0 from ``actions``
    (B, d) at ``targets`` (B, ...): ``(actions, misses (B,))``. Jittable."""
    misses = jax.vmap(lambda a, t: miss_of(cost, a, t))

    def step(a, t):
        r, J = _linearized(cost, a, t)
        return box_step(r, J, a)

    def body(a, _):
        s = jax.vmap(step)(a, targets)
        trials = jnp.stack([jnp.clip(a + f * s, -1.0, 1.0) for f in FRACTIONS], 1)
        ct = jax.vmap(misses, in_axes=(1, None), out_axes=1)(trials, targets)
        ct = jnp.where(jnp.isfinite(ct), ct, jnp.inf)
        best = jnp.argmin(ct, 1)
        return jnp.take_along_axis(trials, best[:, None, None], 1)[:, 0], None

    a, _ = jax.lax.scan(body, actions, None, length=n_iters)
    return a, misses(a, targets)


def make_solver(cost: Cost, dim: int, n_iters: int = 12, n_starts: int = 3, n_side: int = 3):
    """A jitted ``solve(targets (B, ...)) -> (actions (B, dim), costs (B,))``."""
    costs = jax.vmap(lambda a, t: miss_of(cost, a, t))
    starts = coarse_starts(n_side, dim)

    @jax.jit
    def solve(targets):
        B = targets.shape[0]
        tiled = jnp.repeat(targets, starts.shape[0], 0)
        c0 = costs(jnp.tile(starts, (B, 1)), tiled).reshape(B, -1)
        pick = jnp.argsort(jnp.where(jnp.isfinite(c0), c0, jnp.inf), 1)[:, :n_starts]
        a0 = starts[pick].reshape(-1, dim)
        a, c = gauss_newton(cost, a0, jnp.repeat(targets, n_starts, 0), n_iters)
        a, c = a.reshape(B, n_starts, dim), c.reshape(B, n_starts)
        best = jnp.argmin(jnp.where(jnp.isfinite(c), c, jnp.inf), 1)
        return (jnp.take_along_axis(a, best[:, None, None], 1)[:, 0],
                jnp.take_along_axis(c, best[:, None], 1)[:, 0])

    return solve


def solve_targets(cost: Cost, dim: int, targets: np.ndarray, batch: int = 250, **solver_kw) -> dict[str, Any]:
    """Solve every target (n, ...) in batches: ``action`` (n, dim), ``miss`` (n,) m, ``seconds``."""
    solve = make_solver(cost, dim, **solver_kw)
    t0 = time.perf_counter()
    acts, miss = [], []
    for i in range(0, len(targets), batch):
        chunk = jnp.asarray(targets[i:i + batch])
        pad = batch - chunk.shape[0]
        a, c = solve(jnp.concatenate([chunk, jnp.repeat(chunk[-1:], pad, 0)]) if pad else chunk)
        acts.append(np.asarray(a)[: batch - pad])
        miss.append(np.asarray(c)[: batch - pad])
    return {"action": np.concatenate(acts), "miss": np.concatenate(miss), "seconds": time.perf_counter() - t0}


def in_batches(fn: Callable[..., tuple[jax.Array, jax.Array]], batch: int,
               *arrays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``fn(*arrays)`` (each (n, ...)) -> ``(actions, costs)``, called on fixed-size batches (the last
    padded with its final row), so that one compilation of ``fn`` serves any n."""
    acts, miss = [], []
    for i in range(0, len(arrays[0]), batch):
        xs = [jnp.asarray(x[i:i + batch]) for x in arrays]
        pad = batch - xs[0].shape[0]
        if pad:
            xs = [jnp.concatenate([x, jnp.repeat(x[-1:], pad, 0)]) for x in xs]
        a, c = fn(*xs)
        acts.append(np.asarray(a)[: batch - pad])
        miss.append(np.asarray(c)[: batch - pad])
    return np.concatenate(acts), np.concatenate(miss)


def refine_targets(cost: Cost, actions: np.ndarray, targets: np.ndarray, n_iters: int = 4,
                   batch: int = 250) -> dict[str, Any]:
    """``n_iters`` Gauss-Newton steps from given ``actions`` (n, d) (e.g. a policy's) at
    ``targets``, in batches: ``action``, ``miss`` (m), ``seconds``."""
    step = jax.jit(lambda a, t: gauss_newton(cost, a, t, n_iters))
    t0 = time.perf_counter()
    a, miss = in_batches(step, batch, actions, targets)
    return {"action": a, "miss": miss, "seconds": time.perf_counter() - t0}


def _descend(gn, a: np.ndarray, targets: np.ndarray, miss: np.ndarray, n_iters: int, chunk: int, tol: float,
             batch: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Newton in chunks of ``chunk`` steps on the targets still missed by more than ``tol``:
    ``(actions, misses, steps taken)``; a target's miss never grows (a worse chunk is dropped)."""
    a, miss, steps = a.copy(), miss.copy(), np.zeros(len(a), int)
    for _ in range(0, n_iters, chunk):
        active = np.nonzero(miss > tol)[0]
        if active.size == 0:
            break
        a_new, c_new = in_batches(gn, batch, a[active], targets[active])
        better = np.isfinite(c_new) & (c_new <= miss[active])
        a[active[better]], miss[active[better]] = a_new[better], c_new[better]
        steps[active] += chunk
    return a, miss, steps


def plan_targets(cost: Cost, actions: np.ndarray, targets: np.ndarray,
                 starts: Callable[[np.ndarray], np.ndarray], n_iters: int = 12, chunk: int = 4, tol: float = 1e-3,
                 fallback_above: float = 0.01, n_starts: int = 4, batch: int = 100) -> dict[str, Any]:
    """Aim from given ``actions`` (n, d) (a policy's) at ``targets``, falling back to multi-start.

    Up to ``n_iters`` Gauss-Newton steps from each action, ``chunk`` at a time (``n_iters`` rounded
    up to whole chunks; a target drops out once its miss is below ``tol`` m). A target still missed
    by more than ``fallback_above`` m gets the starts ``starts(actions (m, d)) -> (m, K, d)`` (given
    its refined action), thrown once each; the ``n_starts`` with the least miss are refined likewise.
    Per target the best action of all wins: no target ends worse than its start. One compiled
    Gauss-Newton chunk and one compiled cost, of fixed shape ``batch``, serve every stage.
    Returns ``action``, ``miss`` (m), ``start_miss`` (the given actions', clipped to the box),
    ``steps`` (from the given action), ``fallback`` (bool: the target got the multi-start),
    ``seconds``, ``fallback_seconds``.
    """
    gn = jax.jit(lambda a, t: gauss_newton(cost, a, t, chunk))
    costs = jax.jit(lambda a, t: (a, jax.vmap(lambda x, y: miss_of(cost, x, y))(a, t)))
    finite = lambda c: np.where(np.isfinite(c), c, np.inf)  # noqa: E731
    t0 = time.perf_counter()
    targets = np.asarray(targets, float)
    a = np.clip(np.asarray(actions, float), -1.0, 1.0)
    start_miss = finite(in_batches(costs, batch, a, targets)[1])
    a, miss, steps = _descend(gn, a, targets, start_miss, n_iters, chunk, tol, batch)
    t1 = time.perf_counter()
    bad = np.nonzero(miss > fallback_above)[0]
    if bad.size:
        cand = np.asarray(starts(a[bad]), float)
        K = cand.shape[1]
        k = min(n_starts, K)
        c0 = finite(in_batches(costs, batch, cand.reshape(-1, cand.shape[2]), np.repeat(targets[bad], K, 0))[1])
        pick = np.argsort(c0.reshape(-1, K), 1)[:, :k]
        a0 = np.take_along_axis(cand, pick[..., None], 1).reshape(-1, cand.shape[2])
        af, cf, _ = _descend(gn, a0, np.repeat(targets[bad], k, 0),
                             np.take_along_axis(c0.reshape(-1, K), pick, 1).reshape(-1), n_iters, chunk, tol, batch)
        af, cf = af.reshape(bad.size, k, -1), cf.reshape(bad.size, k)
        best = np.argmin(cf, 1)
        cb, ab = cf[np.arange(bad.size), best], af[np.arange(bad.size), best]
        won = cb < miss[bad]
        a[bad[won]], miss[bad[won]] = ab[won], cb[won]
    fallback = np.zeros(len(a), bool)
    fallback[bad] = True
    t2 = time.perf_counter()
    return {"action": a, "miss": miss, "start_miss": start_miss, "steps": steps, "fallback": fallback,
            "seconds": t2 - t0, "fallback_seconds": t2 - t1}
