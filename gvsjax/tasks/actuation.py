"""How the 3D arm's actions become forces: tendon tensions or distributed bending moments.

Two actuations of the same arm (``gv.soft_arm``), chosen by ``ArmParams.actuation``:

* ``"tendon"``: two numbers in [-1, 1] per group of four tendons, one per bending
  direction; ``a > 0`` pulls the tendon on the section's +side (y or z) with
  ``a * tension_max``, ``a < 0`` the opposite one, so opposing tendons never pull
  together and every tension is >= 0.
* ``"muscle"``: 12 numbers in [-1, 1], bending moments ``a * moment_max`` (N m) at the
  six control points of ``gv.moment_map`` (a clamped cubic B-spline along the arm,
  at X = 0, 1/9, 1/3, 2/3, 8/9, 1): the first six bend the arm towards the
  section's +y, the last six towards +z, the directions the tendon actions pull
  in (``a > 0`` on the whole arm turns the tip the same way in both). Torsion is
  not actuated: it only rolls the tip about its own axis, which no 3D task asks for.

Both give the arm constant inputs held over a control step: ``actuate`` returns
``(tendon_force, strain_force)``, the second ``B @ u`` with B built once per arm
structure (it depends on the strain basis only, not on the material or the state).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core.model import Robot, SoftLink
from gvsjax.core.muscles import moment_map
from gvsjax.core.validation import require

ACTUATIONS = ("tendon", "muscle")
MUSCLE_POINTS = 6  # control points along the arm, as the Elastica soft-arm benchmarks' muscle torques
MUSCLE_ACTIONS = 2 * MUSCLE_POINTS  # (towards +y, towards +z) at each control point


def check_actuation(actuation: Any, tension_max: Any, moment_max: Any, strict: bool = True) -> None:
    """A ValueError naming the parameter when the actuation's name or a limit is invalid.

    Traced limits (jit, vmap, domain randomisation) have no value to check and pass; with
    ``strict=False`` so do values that are not numbers (pytree placeholders)."""
    require(isinstance(actuation, str) and actuation in ACTUATIONS, "ArmParams.actuation", actuation,
            f"one of {list(ACTUATIONS)}")
    for name, value, unit in (("tension_max", tension_max, "N"), ("moment_max", moment_max, "N m")):
        if isinstance(value, jax.core.Tracer):
            continue
        number = isinstance(value, (int, float, np.number, np.ndarray, jax.Array)) and not isinstance(value, bool)
        if not number and not strict and not isinstance(value, (str, bytes, bool)):
            continue
        ok = number and np.ndim(value) == 0 and np.isrealobj(value) and bool(np.isfinite(value) and value > 0)
        require(ok, f"ArmParams.{name}", value, f"a finite number > 0 ({unit})")


def n_actions(robot: Robot, actuation: str) -> int:
    """The action size: two per group of four tendons, or 12 moments."""
    return len(robot.tendons) // 2 if actuation == "tendon" else MUSCLE_ACTIONS


def tensions(action: jax.Array, tension_max: Any) -> jax.Array:
    """Tendon actions (..., 2 g) in [-1, 1] (clipped) -> tensions (..., 4 g) N, >= 0."""
    a = jnp.clip(action, -1.0, 1.0) * tension_max
    groups = a.reshape(a.shape[:-1] + (-1, 2))  # (..., g, [y, z])
    pull = jnp.concatenate([jnp.maximum(groups, 0.0), jnp.maximum(-groups, 0.0)], -1)  # +y, +z, -y, -z
    return pull.reshape(a.shape[:-1] + (-1,))


_MAPS: dict[tuple, np.ndarray] = {}  # per arm structure


def muscle_map(robot: Robot) -> np.ndarray:
    """(n_dofs, 12): the generalized force of unit muscle actions (N m each) on the arm's soft link.

    Cached per strain basis: B depends on the basis alone (the link's length cancels), so a
    robot with traced material (domain randomisation) maps like the default one.
    """
    link = robot.links[0]
    require(len(robot.links) == 1 and isinstance(link, SoftLink), "robot", type(robot).__name__,
            "a gv.soft_arm (one soft link)")
    key = (robot.n_dofs, tuple(robot.dof_slices()[0]), tuple(link.basis.orders), link.basis.kind)
    if key not in _MAPS:
        B = moment_map(robot, link=0, n_points=MUSCLE_POINTS, components=("bend_y", "bend_z"))
        # towards +y is a positive moment about the section's z axis, towards +z a negative one about y
        _MAPS[key] = np.concatenate([B[:, MUSCLE_POINTS:], -B[:, :MUSCLE_POINTS]], axis=1)
    return _MAPS[key]


def moments(action: jax.Array, moment_max: Any) -> jax.Array:
    """Muscle actions (..., 12) in [-1, 1] (clipped) -> control-point moments (..., 12) N m."""
    return jnp.clip(action, -1.0, 1.0) * moment_max


def actuate(action: jax.Array, robot: Robot, actuation: str, tension_max: Any,
            moment_max: Any) -> tuple[jax.Array, jax.Array]:
    """``(tendon_force (n_tendons,), strain_force (n_dofs,))`` of one action; the unused one is 0."""
    if actuation == "tendon":
        return tensions(action, tension_max), jnp.zeros(robot.n_dofs, jnp.result_type(action, float))
    B = jnp.asarray(muscle_map(robot))
    return jnp.zeros(len(robot.tendons), jnp.result_type(action, float)), B @ moments(action, moment_max)


__all__ = ["ACTUATIONS", "MUSCLE_POINTS", "MUSCLE_ACTIONS", "check_actuation", "n_actions", "tensions",
           "muscle_map", "moments", "actuate"]
