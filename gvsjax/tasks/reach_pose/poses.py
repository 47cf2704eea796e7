"""Reachable target poses: static equilibria of the arm under random held actions.

A target is the tip's position and the rod's tangent there when the arm rests
under an action drawn uniformly from [-1, 1]^k and held (``gv.equilibrium``,
gravity included; k = 4 tendon or 12 muscle actions, ``ArmParams.actuation``).
Every target is therefore reachable with the arm at rest,
and the action that reaches it is kept: the open-loop baseline holds it.
Training and evaluation draw from tables of different seeds, so the evaluated
poses are held out. Building a table compiles the statics once (~15 s) and
solves thousands of equilibria per second; ``reset`` only looks the table up.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core.kinematics import tip_frame
from gvsjax.core.statics import equilibrium
from gvsjax.tasks import arm3d
from gvsjax.tasks.reach_pose.params import ReachPoseParams

TRAIN_POSES, TRAIN_SEED = 16384, 0  # the training table
EVAL_POSES, EVAL_SEED = 1000, 1  # the held-out table evaluation walks through
LOAD_STEPS = 4  # continuation steps of the statics: the largest actions curl the tip below the base


def reachable_poses(arm: arm3d.ArmParams, n: int, seed: int) -> dict[str, np.ndarray]:
    """``n`` equilibria under actions uniform in [-1, 1]^k from ``seed``: ``position`` (n, 3),
    ``axis`` (n, 3), ``action`` (n, k). Raises if any equilibrium fails to converge."""
    if not (isinstance(n, int) and n >= 1):
        raise ValueError(f"n={n!r} is invalid; expected an int >= 1 (poses in the table)")
    robot = arm.robot
    actions = jax.random.uniform(jax.random.PRNGKey(seed), (n, arm3d.n_actions(arm)), minval=-1.0, maxval=1.0)

    def solve(action):
        tension, strain_force = arm3d.actuate(action, arm)
        eq = equilibrium(robot, tendon_force=tension, strain_force=strain_force, load_scale_steps=LOAD_STEPS)
        R, p = tip_frame(robot, eq.q)
        return p, R[:, 0], eq.converged

    position, axis, converged = jax.jit(jax.vmap(solve))(actions)
    if not bool(jnp.all(converged)):
        raise RuntimeError(f"{int(jnp.sum(~converged))} of {n} equilibria did not converge; raise LOAD_STEPS")
    return {"position": np.asarray(position), "axis": np.asarray(axis), "action": np.asarray(actions)}


_CACHE: dict[tuple, dict] = {}  # tables of the default arms, per (n, seed, actuation)


def make_params(n_poses: int = EVAL_POSES, seed: int = EVAL_SEED, actuation: str = "tendon",
                **overrides: Any) -> ReachPoseParams:
    """Params with a table of ``n_poses`` targets from ``seed`` (cached for the default arm).

    ``actuation``: the default arm's (``ArmParams.actuation``); the targets are equilibria under
    its actions. ``overrides`` are fields of ``ReachPoseParams`` other than the table (e.g. ``arm``,
    which then sets the actuation, ``k_position``).
    """
    allowed = set(ReachPoseParams.__dataclass_fields__) - {"position", "axis", "action"}
    unknown = sorted(set(overrides) - allowed)
    if unknown:
        raise ValueError(f"unknown reach_pose parameter(s) {unknown}; valid: {sorted(allowed)}")
    base = ReachPoseParams(**{"arm": arm3d.ArmParams(actuation=actuation), **overrides})
    arm3d.check(base.arm)
    if "arm" in overrides:
        table = reachable_poses(base.arm, n_poses, seed)
    else:
        if (n_poses, seed, actuation) not in _CACHE:
            _CACHE[(n_poses, seed, actuation)] = reachable_poses(base.arm, n_poses, seed)
        table = _CACHE[(n_poses, seed, actuation)]
    arrays: dict[str, Any] = {k: jnp.asarray(v) for k, v in table.items()}
    return dataclasses.replace(base, **arrays)
