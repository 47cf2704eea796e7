"""Differentiable-physics baseline for throw3d: (T, delta, psi_R) per target by Gauss-Newton
through the simulator (``gvsjax.tasks.aim``), started from a 3 x 3 x 3 grid of actions
(``solve_targets``) or from a policy's actions (``refine``).

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
from gvsjax.tasks.throw3d.throw import action_to_physical, throw_cost


def scanned(params: Throw3DParams) -> Throw3DParams:
    """``params`` with every soft link's kinematic pass scanned."""
    links = tuple(dataclasses.replace(link, recursion="scan") if hasattr(link, "recursion") else link
                  for link in params.arm.links)
    return dataclasses.replace(params, arm=dataclasses.replace(params.arm, links=links))


def solve_targets(params: Throw3DParams, targets: np.ndarray, batch: int = 250, **solver_kw) -> dict[str, Any]:
    """Solve every target (n, 3) in batches: actions, T, delta, yaw (rad), miss (m), seconds."""
    fast = scanned(params)
    r = aim.solve_targets(lambda a, t: throw_cost(fast, a, t)[0], 3, targets, batch=batch, **solver_kw)
    T, delta, psi = action_to_physical(jnp.asarray(r["action"]), params)
    return {**r, "T": np.asarray(T), "delta": np.asarray(delta), "yaw": np.asarray(psi)}


def refine(params: Throw3DParams, actions: np.ndarray, targets: np.ndarray, n_iters: int = 4,
           batch: int = 250) -> dict[str, Any]:
    """``n_iters`` Gauss-Newton steps from ``actions`` (n, 3) at ``targets`` (n, 3): as ``solve_targets``."""
    fast = scanned(params)
    r = aim.refine_targets(lambda a, t: throw_cost(fast, a, t)[0], actions, targets, n_iters, batch)
    T, delta, psi = action_to_physical(jnp.asarray(r["action"]), params)
    return {**r, "T": np.asarray(T), "delta": np.asarray(delta), "yaw": np.asarray(psi)}
