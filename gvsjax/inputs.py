"""Checks and normalisation of ``simulate``'s arguments, before anything is traced.

Every bad value raises ``ValueError`` naming the parameter and what is allowed.
Checks that need numbers are skipped for traced values (a ``vmap``-ed
duration, say); shape checks always run.
"""

from __future__ import annotations

import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax import integrators
from gvsjax.model import Robot
from gvsjax.system import Law
from gvsjax.validation import concrete, require


def check_call(robot: Robot, integrator, duration, dt, n_steps, save_every, laws) -> None:
    """Types and shapes of the scalar arguments and the output size of each law."""
    require(isinstance(integrator, str), "integrator", integrator, f"one of {sorted(integrators.INTEGRATORS)}")
    integrators.get(integrator)
    for name, value in (("duration", duration), ("dt", dt)):
        if (value is not None or name == "duration") and concrete(value):
            require(not isinstance(value, (bool, str, bytes)) and np.ndim(value) == 0
                    and np.issubdtype(np.asarray(value).dtype, np.number), name, value, "a scalar time (s)")
    for name, value in (("n_steps", n_steps), ("save_every", save_every)):
        require(value is None or not isinstance(value, (bool, np.bool_)), name, value, "an int >= 1")
    for name, fn, sizes in laws:
        if callable(fn):  # abstract evaluation only: catches a wrong output shape without compiling
            out = jax.eval_shape(fn, jax.ShapeDtypeStruct((), jax.dtypes.canonicalize_dtype(jnp.float64)))
            size = math.prod(out.shape) if hasattr(out, "shape") else None
            allowed = " or ".join(map(str, sorted(set(sizes))))
            require(size in sizes, name, fn, f"a callable t -> {allowed} value(s); "
                    f"it returns shape {getattr(out, 'shape', type(out).__name__)}")


def motion_law(robot: Robot, base_angle, joint_motion) -> Law | None:
    """The prescribed DoFs' law, or None (held at their initial values)."""
    n_a = len(robot.prescribed)
    if base_angle is not None and joint_motion is not None:
        raise ValueError("give base_angle or joint_motion, not both")
    if base_angle is not None:
        require(callable(base_angle), "base_angle", base_angle, "None or a callable t -> angle (rad)")
        require(n_a == 1, "base_angle", base_angle, "only for robots with exactly one prescribed joint")
        return Law(base_angle, 1)
    if joint_motion is not None:
        require(callable(joint_motion), "joint_motion", joint_motion, f"a callable t -> ({n_a},) array")
        return Law(joint_motion, n_a)
    return None


def tension_law(robot: Robot, tendon_force) -> tuple[Law | None, Any]:
    """(callable law or None, constant tension array or None)."""
    if tendon_force is None:
        return None, None
    require(bool(robot.tendons), "tendon_force", tendon_force, "None: this robot has no tendon")
    if callable(tendon_force):
        return Law(tendon_force, len(robot.tendons)), None
    if concrete(tendon_force):
        try:  # numpy would read the string "0" as 0.0: text is not a tension
            ok = (not isinstance(tendon_force, (str, bytes))
                  and np.issubdtype(np.asarray(tendon_force).dtype, np.number))
            value = np.asarray(tendon_force, dtype=float)
        except (TypeError, ValueError):
            ok = False
        require(ok, "tendon_force", tendon_force, "a tension >= 0 N (one per tendon), or a callable")
        require(value.shape in ((), (len(robot.tendons),)) and np.all(np.isfinite(value)) and np.all(value >= 0),
                "tendon_force", tendon_force, "a finite tension >= 0 N (one per tendon), or a callable")
    return None, jnp.broadcast_to(jnp.asarray(tendon_force, dtype=float), (len(robot.tendons),))


def steps(duration, dt, n_steps) -> tuple[int, Any]:
    """(n_steps, dt) from either a concrete dt or n_steps."""
    if concrete(duration):
        require(math.isfinite(float(duration)) and float(duration) > 0, "duration", duration, "a finite time > 0 s")
    if n_steps is not None:
        require(dt is None, "dt", dt, "None when n_steps is given (dt = duration / n_steps)")
        require(isinstance(n_steps, (int, np.integer)) and n_steps >= 1, "n_steps", n_steps, "an int >= 1")
        return int(n_steps), duration / n_steps
    require(dt is not None, "dt", dt, "a step > 0 s (or give n_steps)")
    require(concrete(dt) and concrete(duration), "dt", dt,
            "concrete numbers with duration; for traced durations pass n_steps instead")
    dt_f = float(dt)
    require(math.isfinite(dt_f) and dt_f > 0, "dt", dt, "a finite step > 0 s")
    n = int(round(float(duration) / dt_f))
    require(n >= 1 and abs(n * dt_f - float(duration)) <= 1e-9 * max(1.0, float(duration)),
            "dt", dt, f"a step that divides duration={float(duration)} s into whole steps")
    return n, dt_f


def float_dtype(dtype) -> np.dtype:
    """float64 or float32 as a numpy dtype, from any of their spellings (jnp/np types, names)."""
    try:
        parsed = None if dtype is None or isinstance(dtype, (bool, int, float)) else np.dtype(dtype)
    except TypeError:
        parsed = None
    require(parsed in (np.float64, np.float32), "dtype", dtype, "jnp.float64 (default) or jnp.float32")
    assert parsed is not None  # for mypy: require raised otherwise
    return parsed


def initial(x, n: int, name: str):
    """An initial state (n,): zeros for None; checked when concrete."""
    if x is None:
        return np.zeros(n)
    if concrete(x):
        try:  # a ragged or non-numeric q0/qd0 is named, not a numpy error
            arr = np.asarray(x, dtype=float)
        except (TypeError, ValueError):
            require(False, name, x, f"an array of {n} numbers")
        require(arr.shape == (n,), name, x, f"an array of shape ({n},)")
        require(bool(np.all(np.isfinite(arr))), name, x, "finite values")
        return arr
    require(jnp.shape(x) == (n,), name, x, f"an array of shape ({n},)")
    return x


def robot_is_concrete(robot: Robot) -> bool:
    return all(concrete(leaf) for leaf in jax.tree_util.tree_leaves(robot))
