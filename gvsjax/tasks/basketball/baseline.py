"""Differentiable-physics baseline for basketball: solve (T, delta) per target by gradients.

Gauss-Newton through the simulator on the miss (``gvsjax.tasks.aim``), the
cost being ``throw_cost`` (reverse mode through the simulation's scan; the
closest flight time is held fixed, which by the envelope theorem leaves the
gradient exact). No table of solutions is used (the targets lie on paths of
the env's grid actions, so a table start would be an exact answer).
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp
import numpy as np

from gvsjax.tasks import aim
from gvsjax.tasks.basketball.params import BasketballParams
from gvsjax.tasks.basketball.throw import action_to_physical, throw_cost

FRACTIONS = aim.FRACTIONS
coarse_starts = aim.coarse_starts


def _cost(params: BasketballParams):
    return lambda a, t: throw_cost(params, a, t)[0]


def gauss_newton(params: BasketballParams, actions, targets, n_iters: int):
    """``n_iters`` line-searched Gauss-Newton steps on c(a) = 0 from ``actions`` (B, 2) at
    ``targets`` (B, 2) in the model ``params``: ``(actions, costs (B,))``. Jittable with
    ``params`` traced, so one program serves every arm of one structure."""
    return aim.gauss_newton(_cost(params), actions, targets, n_iters)


def make_solver(params: BasketballParams, n_iters: int = 12, n_starts: int = 3, n_side: int = 3):
    """A jitted ``solve(targets (B, 2)) -> (actions (B, 2), costs (B,))``."""
    return aim.make_solver(_cost(params), 2, n_iters=n_iters, n_starts=n_starts, n_side=n_side)


def solve_targets(params: BasketballParams, targets: np.ndarray, batch: int = 250,
                  **solver_kw) -> dict[str, Any]:
    """Solve every target (n, 2) in batches; returns actions, T, delta, miss (m), seconds."""
    r = aim.solve_targets(_cost(params), 2, targets, batch=batch, **solver_kw)
    T, delta = action_to_physical(jnp.asarray(r["action"]), params)
    return {**r, "T": np.asarray(T), "delta": np.asarray(delta)}
