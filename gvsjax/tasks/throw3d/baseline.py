"""Differentiable-physics baseline for throw3d: (T, delta, psi_R) per target by Gauss-Newton
through the simulator (``gvsjax.tasks.aim``) on the residual from the target to the flight's
closest point (``throw_residual``, whose norm is the miss), started from a 3 x 3 x 3 grid of actions
(``solve_targets``) or from a policy's actions (``refine``), and ``plan``: the policy's action
refined until it converges, with multi-start Gauss-Newton for the targets it still misses.

The gradient runs through the arm with its kinematic pass scanned
(``SoftLink.recursion="scan"``, equal to the unrolled one to rounding): the
unrolled pass's reverse mode takes more than 10 GB to compile.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax.numpy as jnp
import numpy as np

from gvsjax.tasks import aim
from gvsjax.tasks.throw3d.params import Throw3DParams
from gvsjax.tasks.throw3d.throw import action_to_physical, throw_residual


def scanned(params: Throw3DParams) -> Throw3DParams:
    """``params`` with every soft link's kinematic pass scanned."""
    links = tuple(dataclasses.replace(link, recursion="scan") if hasattr(link, "recursion") else link
                  for link in params.arm.links)
    return dataclasses.replace(params, arm=dataclasses.replace(params.arm, links=links))


def solve_targets(params: Throw3DParams, targets: np.ndarray, batch: int = 250, **solver_kw) -> dict[str, Any]:
    """Solve every target (n, 3) in batches: actions, T, delta, yaw (rad), miss (m), seconds."""
    fast = scanned(params)
    r = aim.solve_targets(lambda a, t: throw_residual(fast, a, t)[0], 3, targets, batch=batch, **solver_kw)
    T, delta, psi = action_to_physical(jnp.asarray(r["action"]), params)
    return {**r, "T": np.asarray(T), "delta": np.asarray(delta), "yaw": np.asarray(psi)}


def refine(params: Throw3DParams, actions: np.ndarray, targets: np.ndarray, n_iters: int = 4,
           batch: int = 250) -> dict[str, Any]:
    """``n_iters`` Gauss-Newton steps from ``actions`` (n, 3) at ``targets`` (n, 3): as ``solve_targets``."""
    fast = scanned(params)
    r = aim.refine_targets(lambda a, t: throw_residual(fast, a, t)[0], actions, targets, n_iters, batch)
    T, delta, psi = action_to_physical(jnp.asarray(r["action"]), params)
    return {**r, "T": np.asarray(T), "delta": np.asarray(delta), "yaw": np.asarray(psi)}


YAW_TURN = 2.0 * 360.0 / 396.0  # one full turn of psi_R in action units (yaw_range is +-198 deg)
# (T, delta, yaw) offsets in action units around the refined policy action: a full turn either way
# (the other side of the +-180 deg cut), a faster or slower swing, an earlier or later release, a
# yaw +-40 deg
OFFSETS = np.array([[0, 0, YAW_TURN], [0, 0, -YAW_TURN], [-0.25, 0, 0], [0.25, 0, 0], [0, -0.5, 0], [0, 0.5, 0],
                    [0, 0, -0.2], [0, 0, 0.2]])


def plan_starts(action: np.ndarray, n_T: int = 4, n_delta: int = 3, n_yaw: int = 9) -> np.ndarray:
    """Fallback starts (n, K, 3) around actions (n, 3): ``action + OFFSETS`` (clipped to the box),
    then an n_T x n_delta x n_yaw grid (T from the box's fast edge to its middle, where the court's
    throws are; delta in [-0.8, 0.8]; yaw over the whole box)."""
    axes = (np.linspace(-1.0, 0.5, n_T), np.linspace(-0.8, 0.8, n_delta), np.linspace(-1.0, 1.0, n_yaw))
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    near = np.clip(action[:, None, :] + OFFSETS[None], -1.0, 1.0)
    return np.concatenate([near, np.broadcast_to(grid, (len(action), *grid.shape))], 1)


def plan(params: Throw3DParams, actions: np.ndarray, targets: np.ndarray, n_iters: int = 12, chunk: int = 4,
         tol: float = 1e-3, fallback_above: float = 0.01, n_starts: int = 8, batch: int = 100) -> dict[str, Any]:
    """The policy's actions (n, 3) refined, then multi-start where they still miss, at ``targets`` (n, 3).

    ``aim.plan_targets`` on the throw's miss: up to ``n_iters`` Gauss-Newton steps from each action
    (as ``refine``), in chunks of ``chunk``, a target dropping out once its miss is below ``tol`` (m);
    a target still missed by more than ``fallback_above`` (m) is thrown from every start of
    ``plan_starts`` and the ``n_starts`` best are refined likewise (the least raw miss need not be in
    the target's basin; as the refined policy leaves few targets to the fallback, it can afford eight);
    the best action wins, so no target ends worse than its start. As ``refine``, plus ``start_miss``,
    ``steps``, ``fallback``, ``fallback_seconds`` (``aim.plan_targets``).
    """
    fast = scanned(params)
    r = aim.plan_targets(lambda a, t: throw_residual(fast, a, t)[0], actions, targets, plan_starts, n_iters=n_iters,
                         chunk=chunk, tol=tol, fallback_above=fallback_above, n_starts=n_starts, batch=batch)
    T, delta, psi = action_to_physical(jnp.asarray(r["action"]), params)
    return {**r, "T": np.asarray(T), "delta": np.asarray(delta), "yaw": np.asarray(psi)}
