"""Aiming a one-shot task through the simulator: Gauss-Newton on its miss, c(a) = 0.

For each target the miss c(a) (m, >= 0) is differentiated through the
simulator. From a grid of coarse starts over the action box (cost only) the
``n_starts`` best are refined by Gauss-Newton steps on the scalar equation
c(a) = 0, a <- a - c grad c / |grad c|^2 (the minimum-norm step onto the
solution set), with a line search over step fractions (1, 1/2, 1/4, 1/8 or
no step) and the box [-1, 1]^d enforced by clipping; the best final action
per target wins. The throwing tasks' differentiable-physics baselines.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

FRACTIONS = (1.0, 0.5, 0.25, 0.125, 0.0)
Cost = Callable[[jax.Array, jax.Array], jax.Array]  # (action (d,), target) -> miss (m)


def coarse_starts(n_side: int = 3, dim: int = 2) -> jax.Array:
    """(n_side^dim, dim) actions on a grid inside the box."""
    g = jnp.linspace(-0.8, 0.8, n_side)
    return jnp.stack(jnp.meshgrid(*([g] * dim), indexing="ij"), -1).reshape(-1, dim)


def gauss_newton(cost: Cost, actions, targets, n_iters: int):
    """``n_iters`` line-searched Gauss-Newton steps on c(a) = 0 from ``actions`` (B, d) at
    ``targets`` (B, ...): ``(actions, costs (B,))``. Jittable."""
    value_grad = jax.vmap(jax.value_and_grad(cost))
    costs = jax.vmap(cost)

    def body(a, _):
        c, g = value_grad(a, targets)
        step = -(c / jnp.maximum(jnp.sum(g * g, -1), 1e-12))[:, None] * g
        trials = jnp.stack([jnp.clip(a + f * step, -1.0, 1.0) for f in FRACTIONS], 1)
        ct = jax.vmap(costs, in_axes=(1, None), out_axes=1)(trials, targets)
        ct = jnp.where(jnp.isfinite(ct), ct, jnp.inf)
        best = jnp.argmin(ct, 1)
        return jnp.take_along_axis(trials, best[:, None, None], 1)[:, 0], None

    a, _ = jax.lax.scan(body, actions, None, length=n_iters)
    return a, costs(a, targets)


def make_solver(cost: Cost, dim: int, n_iters: int = 12, n_starts: int = 3, n_side: int = 3):
    """A jitted ``solve(targets (B, ...)) -> (actions (B, dim), costs (B,))``."""
    costs = jax.vmap(cost)
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


def refine_targets(cost: Cost, actions: np.ndarray, targets: np.ndarray, n_iters: int = 4,
                   batch: int = 250) -> dict[str, Any]:
    """``n_iters`` Gauss-Newton steps from given ``actions`` (n, d) (e.g. a policy's) at
    ``targets``, in batches: ``action``, ``miss`` (m), ``seconds``."""
    step = jax.jit(lambda a, t: gauss_newton(cost, a, t, n_iters))
    t0 = time.perf_counter()
    acts, miss = [], []
    for i in range(0, len(targets), batch):
        a, t = jnp.asarray(actions[i:i + batch]), jnp.asarray(targets[i:i + batch])
        pad = batch - a.shape[0]
        if pad:
            a, t = (jnp.concatenate([x, jnp.repeat(x[-1:], pad, 0)]) for x in (a, t))
        a, c = step(a, t)
        acts.append(np.asarray(a)[: batch - pad])
        miss.append(np.asarray(c)[: batch - pad])
    return {"action": np.concatenate(acts), "miss": np.concatenate(miss), "seconds": time.perf_counter() - t0}
