"""Differentiable-physics baseline for basketball: solve (T, delta) per target by gradients.

For each target the cost c(a) (closest distance in m, ``throw_cost``) is
differentiated through the simulator (reverse mode through the simulation's scan; the
closest flight time is held fixed, which by the envelope theorem leaves the
gradient exact). From ``n_coarse`` coarse starts (a grid over the action box,
cost only) the ``n_starts`` best are refined by Gauss-Newton steps on the
scalar equation c(a) = 0, a <- a - c grad c / |grad c|^2 (the minimum-norm
step onto the solution curve), with a line search over step fractions
(1, 1/2, 1/4, 1/8 or no step) and the box [-1, 1]^2 enforced by clipping.
The best final action per target wins. No table of solutions is used (the
targets lie on paths of the env's grid actions, so a table start would be
an exact answer).
"""

from __future__ import annotations

import time
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.tasks.basketball.params import BasketballParams
from gvsjax.tasks.basketball.throw import action_to_physical, throw_cost

FRACTIONS = (1.0, 0.5, 0.25, 0.125, 0.0)


def coarse_starts(n_side: int = 3) -> jnp.ndarray:
    """(n_side^2, 2) actions on a grid inside the box."""
    g = jnp.linspace(-0.8, 0.8, n_side)
    return jnp.stack(jnp.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)


def gauss_newton(params: BasketballParams, actions, targets, n_iters: int):
    """``n_iters`` line-searched Gauss-Newton steps on c(a) = 0 from ``actions`` (B, 2) at
    ``targets`` (B, 2) in the model ``params``: ``(actions, costs (B,))``. Jittable with
    ``params`` traced, so one program serves every arm of one structure."""
    cost = lambda a, t: throw_cost(params, a, t)[0]  # noqa: E731
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


def make_solver(params: BasketballParams, n_iters: int = 12, n_starts: int = 3, n_side: int = 3):
    """A jitted ``solve(targets (B, 2)) -> (actions (B, 2), costs (B,))``."""
    costs = jax.vmap(lambda a, t: throw_cost(params, a, t)[0])
    starts = coarse_starts(n_side)

    def refine(a, target):  # a: (B, 2), target: (B, 2)
        return gauss_newton(params, a, target, n_iters)

    @jax.jit
    def solve(targets):
        B = targets.shape[0]
        tiled = jnp.repeat(targets, starts.shape[0], 0)
        c0 = costs(jnp.tile(starts, (B, 1)), tiled).reshape(B, -1)
        pick = jnp.argsort(jnp.where(jnp.isfinite(c0), c0, jnp.inf), 1)[:, :n_starts]
        a0 = starts[pick].reshape(-1, 2)
        a, c = refine(a0, jnp.repeat(targets, n_starts, 0))
        a, c = a.reshape(B, n_starts, 2), c.reshape(B, n_starts)
        best = jnp.argmin(jnp.where(jnp.isfinite(c), c, jnp.inf), 1)
        return (jnp.take_along_axis(a, best[:, None, None], 1)[:, 0],
                jnp.take_along_axis(c, best[:, None], 1)[:, 0])

    return solve


def solve_targets(params: BasketballParams, targets: np.ndarray, batch: int = 250,
                  **solver_kw) -> dict[str, Any]:
    """Solve every target (n, 2) in batches; returns actions, T, delta, miss (m), seconds."""
    solve = make_solver(params, **solver_kw)
    t0 = time.perf_counter()
    acts, miss = [], []
    for i in range(0, len(targets), batch):
        chunk = jnp.asarray(targets[i:i + batch])
        pad = batch - chunk.shape[0]
        a, c = solve(jnp.concatenate([chunk, jnp.repeat(chunk[-1:], pad, 0)]) if pad else chunk)
        acts.append(np.asarray(a)[: batch - pad])
        miss.append(np.asarray(c)[: batch - pad])
    a = np.concatenate(acts)
    T, delta = action_to_physical(jnp.asarray(a), params)
    return {"action": a, "T": np.asarray(T), "delta": np.asarray(delta),
            "miss": np.concatenate(miss), "seconds": time.perf_counter() - t0}
