"""Checks and normalisation of ``simulate``'s arguments, before anything is traced.

Every bad value raises ``ValueError`` naming the parameter and what is allowed.
Checks that need numbers are skipped for traced values (a ``vmap``-ed
duration, say); shape checks always run.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core import active_strain, integrators
from gvsjax.core.model import Robot
from gvsjax.core.system import Law
from gvsjax.core.validation import concrete, require


def takes_state(name: str, fn) -> bool:
    """True for a law of ``(t, q, qd)``, False for one of ``t``; else a ValueError naming ``name``."""
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):  # a builtin or C callable: taken as a law of t
        return False
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    needed = [p for p in sig.parameters.values() if p.kind in kinds and p.default is p.empty]
    variadic = any(p.kind == inspect.Parameter.VAR_POSITIONAL for p in sig.parameters.values())
    if len(needed) == 3:
        return True
    require(len(needed) == 1 or (variadic and not needed), name, fn,
            "a callable of t, or of (t, q, qd) with the full coordinate and velocity vectors")
    return False


def check_call(robot: Robot, integrator, duration, dt, n_steps, save_every, laws) -> None:
    """Types and shapes of the scalar arguments and the output size of each law.

    ``laws``: (name, value, allowed output sizes, may depend on the state) tuples.
    """
    require(isinstance(integrator, str), "integrator", integrator, f"one of {sorted(integrators.INTEGRATORS)}")
    integrators.get(integrator)
    for name, value in (("duration", duration), ("dt", dt)):
        if (value is not None or name == "duration") and concrete(value):
            require(not isinstance(value, (bool, str, bytes)) and np.ndim(value) == 0
                    and np.issubdtype(np.asarray(value).dtype, np.number), name, value, "a scalar time (s)")
    for name, value in (("n_steps", n_steps), ("save_every", save_every)):
        require(value is None or not isinstance(value, (bool, np.bool_)), name, value, "an int >= 1")
    f64 = jax.dtypes.canonicalize_dtype(jnp.float64)
    t = jax.ShapeDtypeStruct((), f64)
    x = jax.ShapeDtypeStruct((robot.n_dofs,), f64)
    for name, fn, sizes, state_ok in laws:
        if callable(fn):  # abstract evaluation only: catches a wrong output shape without compiling
            state = takes_state(name, fn)
            require(state_ok or not state, name, fn, "a callable of t only (a prescribed motion cannot "
                    "depend on the state it prescribes)")
            out = jax.eval_shape(fn, t, x, x) if state else jax.eval_shape(fn, t)
            size = math.prod(out.shape) if hasattr(out, "shape") else None
            allowed = " or ".join(map(str, sorted(set(sizes))))
            require(size in sizes, name, fn, f"a callable returning {allowed} value(s); "
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


def input_law(name: str, value, size: int, what: str, nonnegative: bool) -> tuple[Law | None, Any]:
    """An input given as None, a constant or a callable: (callable law or None, constant array or None).

    ``size`` inputs exist (tendons, actuated joint coordinates); ``what`` names them in errors.
    """
    if value is None:
        return None, None
    require(size > 0, name, value, f"None: this robot has no {what}")
    if callable(value):
        return Law(value, size, takes_state(name, value)), None
    allowed = f"a finite {'value >= 0' if nonnegative else 'value'} (one per {what[:-1]}), or a callable"
    if concrete(value):
        try:  # numpy would read the string "0" as 0.0: text is not a number here
            ok = not isinstance(value, (str, bytes)) and np.issubdtype(np.asarray(value).dtype, np.number)
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            ok = False
        require(ok, name, value, allowed)
        require(arr.shape in ((), (size,)) and bool(np.all(np.isfinite(arr)))
                and (not nonnegative or bool(np.all(arr >= 0))), name, value, allowed)
    return None, jnp.broadcast_to(jnp.asarray(value, dtype=float), (size,))


def tension_law(robot: Robot, tendon_force) -> tuple[Law | None, Any]:
    """Tendon tensions (N, >= 0): (callable law or None, constant array or None)."""
    return input_law("tendon_force", tendon_force, len(robot.tendons), "tendons", True)


def wrench_law(robot: Robot, wrench) -> tuple[Law | None, Any]:
    """Wrenches (moment, force) at ``robot.wrenches``, (n, 6) or flattened: (law or None, constant or None)."""
    n = len(robot.wrenches)
    if wrench is not None and not callable(wrench) and concrete(wrench) and np.shape(wrench) == (n, 6):
        wrench = np.reshape(np.asarray(wrench, dtype=float), (6 * n,))
    return input_law("wrench", wrench, 6 * n, "wrench points", False)


def joint_force_law(robot: Robot, joint_force) -> tuple[Law | None, Any]:
    """Forces on the actuated joint coordinates: (callable law or None, constant array or None)."""
    return input_law("joint_force", joint_force, len(robot.actuated), "actuated joints", False)


def strain_force_law(robot: Robot, strain_force) -> tuple[Law | None, Any]:
    """A generalized force on every coordinate, (n_dofs,): (callable law or None, constant array or None).

    Unlike the per-actuator inputs no scalar is broadcast: a force on every coordinate at
    once is almost never meant, and a wrong-length vector is a wrong map."""
    n = robot.n_dofs
    if strain_force is not None and not callable(strain_force):
        require(not isinstance(strain_force, (str, bytes)) and np.shape(strain_force) == (n,), "strain_force",
                strain_force, f"an array of shape ({n},) (one generalized force per coordinate), or a callable")
    return input_law("strain_force", strain_force, n, "coordinates", False)


def rest_strain_law(robot: Robot, rest_strain) -> tuple[Law | None, Any]:
    """Rest-strain values at ``robot.rest_strains``, (n_values,) or one entry's (n_segments,
    n_components): (callable law or None, constant array or None)."""
    value = active_strain.check_value(robot, rest_strain)
    return input_law("rest_strain", value, active_strain.size(robot), "rest-strain values", False)


@dataclass(frozen=True)
class Controller:
    """A feedback controller ``(t, q, qd) -> {"tendon_force": (n_t,), "joint_force": (n_j,), "wrench": (n_w, 6),
    "strain_force": (n,), "rest_strain": (n_values,)}`` (any subset of the keys)
    sampled every ``every`` integrator steps and held in between (zero-order hold).

    Hashed by the function's identity (the compiled program is reused)."""

    fn: Callable
    every: int
    keys: tuple[str, ...]

    def __call__(self, t, q, qd) -> dict:
        out = self.fn(t, q, qd)
        return {k: jnp.reshape(jnp.asarray(out[k]).astype(jnp.result_type(t)), (-1,)) for k in self.keys}


CONTROL_KEYS = ("tendon_force", "joint_force", "wrench", "strain_force", "rest_strain")


def controller(robot: Robot, fn, every, tendon_force, joint_force, wrench=None,
               strain_force=None, rest_strain=None) -> Controller | None:
    """The checked zero-order-hold controller, or None."""
    if fn is None:
        require(every is None, "control_every", every, "None without a controller")
        return None
    require(callable(fn), "controller", fn, "a callable (t, q, qd) -> dict of inputs")
    require(isinstance(every, (int, np.integer)) and not isinstance(every, bool) and every >= 1,
            "control_every", every, "an int >= 1: integrator steps per control update")
    f64 = jax.dtypes.canonicalize_dtype(jnp.float64)
    x = jax.ShapeDtypeStruct((robot.n_dofs,), f64)
    out = jax.eval_shape(fn, jax.ShapeDtypeStruct((), f64), x, x)
    require(isinstance(out, dict) and bool(out) and set(out) <= set(CONTROL_KEYS), "controller", fn,
            f"a callable returning a dict with keys among {list(CONTROL_KEYS)}")
    sizes = {"tendon_force": len(robot.tendons), "joint_force": len(robot.actuated),
             "wrench": 6 * len(robot.wrenches), "strain_force": robot.n_dofs,
             "rest_strain": sum(int(np.prod(s.shape)) for s in robot.rest_strains)}
    for key, given in (("tendon_force", tendon_force), ("joint_force", joint_force), ("wrench", wrench),
                       ("strain_force", strain_force), ("rest_strain", rest_strain)):
        if key in out:
            require(given is None, key, given, "None when the controller sets it")
            require(math.prod(out[key].shape) == sizes[key] > 0, "controller", fn,
                    f"{key} of {sizes[key]} value(s); it returns shape {out[key].shape}")
    return Controller(fn, int(every), tuple(k for k in CONTROL_KEYS if k in out))


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
