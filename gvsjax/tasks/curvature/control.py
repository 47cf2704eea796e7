"""Natural-curvature control of the benchmark arm (``gv.curvature_arm``), shared by its four tasks.

Each control point k holds an integrated rest curvature (a turning angle, rad) per
bending direction, ``kappa[k]``, and in the IK task a rest twist angle ``twist[k]``.
An action in [-1, 1] adds ``step_scale * action`` to them, clipped to
[-kappa_max, kappa_max] (and ``twist_scale``, [-twist_max, twist_max]); over the
control interval the rest strain moves linearly from the old value to the new one.
Segment k's rest curvature is ``SEGMENT_SHARE[k] * kappa[k] / l_k`` (1/m), l_k its
length. Direction 1 bends the arm towards world -x, direction 2 towards -y (the
benchmark's material directions m1 = -x, m2 = -y of the upright rod); a positive
twist turns the tip's frame anticlockwise about the rod's tangent.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.curvature_arm import SEGMENT_SHARE, curvature_arm, node_sites, segment_lengths
from gvsjax.core.kinematics import point_states
from gvsjax.core.model import Robot
from gvsjax.core.simulation import simulate
from gvsjax.core.validation import require
from gvsjax.utils import episode_returns

N_POINTS = 5  # control points
GAMMA = 0.99  # the benchmark's discount (its SAC's), used for the published returns
Q_BOUND = 1e3  # |q| beyond this (curvature coefficients in 1/m) is a diverged state
QD_BOUND = 1e5


@struct.dataclass
class ArmControl:
    """The arm, the control law and the time stepping (SI units, angles in rad)."""

    robot: Robot = struct.field(default_factory=curvature_arm)
    step_scale: float = 0.05  # rad of turning angle per unit action and step (0.25 in the obstacle tasks)
    kappa_max: float = 2.0  # rad, the turning angle's limit per control point and direction
    twist_scale: float = 0.05  # rad per unit action and step
    twist_max: float = float(np.pi / 2)  # rad
    control_dt: float = 0.1  # s between actions
    # implicit steps per control step (stiffness and damping implicit), as DisMech takes 2: their tip error
    # against 32 under random actions in experiments/studies/curvature_substeps.py. The mass is frozen over
    # each step: with ars443 the twisting rod diverges at 2 (gvsjax.core.integrators)
    n_substeps: int = struct.field(pytree_node=False, default=2)
    integrator: str = struct.field(pytree_node=False, default="ars443_frozen_mass")
    sim_dtype: str = struct.field(pytree_node=False, default="float64")
    save_every: int = struct.field(pytree_node=False, default=0)  # 0: the last state only


def layout(robot: Robot) -> tuple[int, bool]:
    """(bending directions, twist) of the arm's rest-strain input."""
    comps = robot.rest_strains[0].components if robot.rest_strains else ()
    return sum(c in ("bend_y", "bend_z") for c in comps), "torsion" in comps


def check(arm: ArmControl, directions: int, twist: bool, where: str) -> None:
    """The arm is a ``gv.curvature_arm`` with the given control layout (a ValueError naming it)."""
    robot = arm.robot
    ok = len(robot.rest_strains) == N_POINTS and all(seg.shape[0] == 1 for seg in robot.rest_strains)
    require(ok and layout(robot) == (directions, twist), f"{where}.arm.robot", type(robot).__name__,
            f"a gv.curvature_arm(planar={directions == 1}, twist={twist}) (five control segments, "
            f"{directions} bending direction(s){', twist' if twist else ''})")
    for name in ("step_scale", "kappa_max", "twist_scale", "twist_max", "control_dt"):
        value = getattr(arm, name)
        if isinstance(value, (int, float)):
            require(np.isfinite(value) and value > 0, f"{where}.arm.{name}", value, "a finite number > 0")
    require(isinstance(arm.n_substeps, int) and arm.n_substeps >= 1, f"{where}.arm.n_substeps", arm.n_substeps,
            "an int >= 1")


def n_actions(robot: Robot) -> int:
    directions, twist = layout(robot)
    return N_POINTS * (directions + twist)


def apply(arm: ArmControl, kappa: jax.Array, twist: jax.Array, action: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The new (kappa (5, directions), twist (5,)) after ``action`` (clipped to [-1, 1]); the
    action's first 5 x directions entries are the bending ones, point by point, then the twists."""
    a = jnp.clip(action, -1.0, 1.0)
    nb = kappa.size
    kappa = jnp.clip(kappa + arm.step_scale * a[:nb].reshape(kappa.shape), -arm.kappa_max, arm.kappa_max)
    if a.shape[0] > nb:
        twist = jnp.clip(twist + arm.twist_scale * a[nb:], -arm.twist_max, arm.twist_max)
    return kappa, twist


def rest_values(robot: Robot, kappa: jax.Array, twist: jax.Array) -> jax.Array:
    """The rest-strain input (1/m, ``simulate``'s ``rest_strain``) of the turning angles."""
    length = sum(link.length for link in robot.links)
    per_length = jnp.asarray(np.asarray(SEGMENT_SHARE) / segment_lengths(1.0)) / length  # (5,)
    directions, has_twist = layout(robot)
    cols = [twist] if has_twist else []
    cols.append(-kappa[:, 0])  # direction 1, towards -x: bend_z < 0
    if directions == 2:
        cols.append(kappa[:, 1])  # direction 2, towards -y: bend_y > 0
    return (jnp.stack(cols, -1) * per_length[:, None]).reshape(-1)


def advance(arm: ArmControl, q, qd, rest_from, rest_to):
    """One control interval with the rest strain moving linearly from ``rest_from`` to ``rest_to``:
    the ``Trajectory`` (float64; its last state the new one)."""
    dtype = arm.sim_dtype
    cast = lambda x: jnp.asarray(x).astype(dtype)  # noqa: E731
    T = arm.control_dt
    a, b = cast(rest_from), cast(rest_to)
    law = lambda t: a + (t / T) * (b - a)  # noqa: E731
    every = arm.save_every or arm.n_substeps
    tr = simulate(arm.robot, T, n_steps=arm.n_substeps, q0=cast(q), qd0=cast(qd), rest_strain=law,
                  integrator=arm.integrator, save_every=every, check_stability=False, dtype=dtype)
    return jax.tree_util.tree_map(lambda x: x.astype(float), tr)


def open_loop_tips(arm: ArmControl, actions: jax.Array) -> jax.Array:
    """Tip positions (T, 3) after each of T control steps of ``actions`` (T, n_actions), from the arm
    straight and at rest with zero turning angles: the control step without a task (no target, no
    reward, no failure check). Works under ``jit``, ``vmap`` (a batch of action sequences) and ``grad``."""
    robot = arm.robot
    directions, _ = layout(robot)

    def one(carry, a):
        q, qd, kappa, twist = carry
        new_kappa, new_twist = apply(arm, kappa, twist, a)
        tr = advance(arm, q, qd, rest_values(robot, kappa, twist), rest_values(robot, new_kappa, new_twist))
        return (tr.q[-1], tr.qd[-1], new_kappa, new_twist), tr.tip[-1]

    zero = jnp.zeros(robot.n_dofs)
    return jax.lax.scan(one, (zero, zero, jnp.zeros((N_POINTS, directions)), jnp.zeros(N_POINTS)), actions)[1]


def nodes(robot: Robot, q, qd) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Positions (10, 3), velocities (10, 3) of the observed nodes (0.1 m apart, the last the tip)
    and the tip's rotation (3, 3)."""
    p, v, R = point_states(robot, q, qd, node_sites(robot))
    return p, v, R[-1]


def healthy(q, qd) -> jax.Array:
    return jnp.all(jnp.isfinite(q)) & jnp.all(jnp.abs(q) <= Q_BOUND) & jnp.all(jnp.abs(qd) <= QD_BOUND)


def with_sim_dtype(arm: ArmControl, sim_dtype: str) -> ArmControl:
    require(sim_dtype in ("", "float64", "float32"), "sim_dtype", sim_dtype, "'float64' or 'float32'")
    return dataclasses.replace(arm, sim_dtype=sim_dtype or "float64")


def discounted_returns(rewards: np.ndarray, valid: np.ndarray | None = None, gamma: float = GAMMA) -> dict:
    """The benchmark's discounted returns of recorded episodes' rewards (n, T), each counted over its
    actual length: up to and including its first step with ``valid`` (n, T) False (the failed step's
    reward counts), else all T (``gvsjax.utils.episode_returns.discounted_returns``). Per episode (n,):
    ``average``, ``start``, ``undiscounted``."""
    r = np.asarray(rewards, float)
    T = r.shape[1]
    ok = np.ones(r.shape, bool) if valid is None else np.asarray(valid, bool)
    lengths = np.where(ok.all(1), T, np.argmin(ok, 1) + 1)
    return episode_returns.discounted_returns(r, lengths, gamma)


__all__: list[Any] = ["N_POINTS", "GAMMA", "ArmControl", "layout", "check", "n_actions", "apply", "rest_values",
                      "advance", "open_loop_tips", "nodes", "healthy", "with_sim_dtype", "discounted_returns"]
