"""The time-stepping driver: robot + controls -> Trajectory, on ``lax.scan``."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax import dynamics, integrators, lie
from gvsjax.kinematics import tip_state
from gvsjax.model import Robot
from gvsjax.validation import check_robot, concrete, require


@struct.dataclass
class Trajectory:
    """Saved states of a simulation (SI units).

    t (m,), q (m, n), qd (m, n), tip (m, 3) world tip position, tip_velocity
    (m, 3), joint_torque (m, n_prescribed): the effort the prescribed joints
    exert (by inverse dynamics), N m for revolute joints. ``m = n_steps /
    save_every + 1``.
    """

    t: jax.Array
    q: jax.Array
    qd: jax.Array
    tip: jax.Array
    tip_velocity: jax.Array
    joint_torque: jax.Array


class FreeDynamics:
    """The free DoFs' equations with the prescribed ones following ``motion``."""

    def __init__(self, robot: Robot, motion: Callable, tension: Callable | None):
        self.robot, self.motion, self.tension = robot, motion, tension
        self.a, self.u = robot.prescribed, robot.free

    def prescribed_state(self, t):
        """q_a, qd_a, qdd_a at time t (derivatives of the law by autodiff)."""
        if not self.a:
            return (), (), ()
        first = lambda s: jax.jvp(self.motion, (s,), (jnp.ones_like(s),))  # noqa: E731
        (qa, qda), (_, qdda) = jax.jvp(first, (t,), (jnp.ones_like(t),))
        return [qa[i] for i in range(len(self.a))], [qda[i] for i in range(len(self.a))], [
            qdda[i] for i in range(len(self.a))
        ]

    def _full(self, t, q_u, qd_u):
        qa, qda, qdda = self.prescribed_state(t)
        n = self.robot.n_dofs
        q, qd = [None] * n, [None] * n
        for k, i in enumerate(self.a):
            q[i], qd[i] = qa[k], qda[k]
        for k, i in enumerate(self.u):
            q[i], qd[i] = q_u[k], qd_u[k]
        return q, qd, qdda

    def _tension(self, t):
        if not self.robot.tendons:
            return ()
        T = jnp.atleast_1d(self.tension(t)) if self.tension is not None else jnp.zeros(len(self.robot.tendons))
        return [T[i] for i in range(len(self.robot.tendons))]

    def _mf(self, t, q_u, qd_u):
        q, qd, qdda = self._full(t, q_u, qd_u)
        M, F = dynamics.mass_and_forces(self.robot, q, qd, self._tension(t))
        return q, qd, qdda, M, F

    def accel(self, t, q_u, qd_u):
        _, _, qdda, M, F = self._mf(t, q_u, qd_u)
        return tuple(lie.as_array(x) for x in dynamics.split_solve(self.robot, M, F, qdda))

    def parts(self, t, q_u, qd_u):
        """M_uu (lower triangle), f_u = F_u - M_ua qdd_a, K_uu, D_uu for IMEX."""
        _, _, qdda, M, F = self._mf(t, q_u, qd_u)
        a, u = self.a, self.u
        Mf = lambda i, j: M[i][j] if i >= j else M[j][i]  # noqa: E731
        f = [lie.sub(F[i], lie.total([lie.mul(Mf(i, k), x) for k, x in zip(a, qdda)])) for i in u]
        K, D = dynamics.stiffness_and_damping(self.robot)
        pick = lambda A: [[A[i][j] for j in u] for i in u]  # noqa: E731
        return [[Mf(i, j) for j in u] for i in u], f, pick(K), pick(D)

    def effort(self, t, q_u, qd_u):
        """Prescribed joints' effort (n_a,) by inverse dynamics."""
        q, qd, qdda, M, F = self._mf(t, q_u, qd_u)
        qdd_u = dynamics.split_solve(self.robot, M, F, qdda)
        qdd = [None] * self.robot.n_dofs
        for k, i in enumerate(self.a):
            qdd[i] = qdda[k]
        for k, i in enumerate(self.u):
            qdd[i] = qdd_u[k]
        tau = dynamics.prescribed_effort(self.robot, M, F, qdd)
        return jnp.stack([lie.as_array(x) for x in tau]) if tau else jnp.zeros((0,))


@dataclass(frozen=True)
class _Law:
    """A user's t -> values callable, hashed by identity so that repeated
    simulations with the same function reuse the compiled program."""

    fn: Callable
    size: int

    def __call__(self, t):
        # in the simulation's dtype (that of t): a float64 law must not lift a float32 run
        return jnp.reshape(jnp.asarray(self.fn(t)).astype(jnp.result_type(t)), (self.size,))


def _motion_law(robot: Robot, base_angle, joint_motion) -> _Law | None:
    n_a = len(robot.prescribed)
    if base_angle is not None and joint_motion is not None:
        raise ValueError("give base_angle or joint_motion, not both")
    if base_angle is not None:
        require(callable(base_angle), "base_angle", base_angle, "None or a callable t -> angle (rad)")
        require(n_a == 1, "base_angle", base_angle, "only for robots with exactly one prescribed joint")
        return _Law(base_angle, 1)
    if joint_motion is not None:
        require(callable(joint_motion), "joint_motion", joint_motion, f"a callable t -> ({n_a},) array")
        return _Law(joint_motion, n_a)
    return None  # held at the initial value


def _tension_law(robot: Robot, tendon_force) -> tuple[_Law | None, Any]:
    """(callable law or None, constant tension array or None)."""
    if tendon_force is None:
        return None, None
    require(bool(robot.tendons), "tendon_force", tendon_force, "None: this robot has no tendon")
    if callable(tendon_force):
        return _Law(tendon_force, len(robot.tendons)), None
    if concrete(tendon_force):
        value = np.asarray(tendon_force, dtype=float)
        require(
            value.shape in ((), (len(robot.tendons),)) and np.all(np.isfinite(value)) and np.all(value >= 0),
            "tendon_force", tendon_force, "a finite tension >= 0 N (one per tendon), or a callable",
        )
    return None, jnp.broadcast_to(jnp.asarray(tendon_force, dtype=float), (len(robot.tendons),))


def simulate(
    robot: Robot,
    duration: Any,
    dt: Any = None,
    base_angle: Callable | None = None,
    tendon_force: Any = None,
    q0: Any = None,
    qd0: Any = None,
    *,
    n_steps: int | None = None,
    integrator: str = "rk4",
    save_every: int = 1,
    joint_motion: Callable | None = None,
    check_stability: bool = True,
    dtype: Any = jnp.float64,
) -> Trajectory:
    """Integrate the robot from t = 0 to ``duration`` with a fixed step.

    Give either ``dt`` (then n_steps = round(duration / dt), and both must be
    concrete) or ``n_steps`` (then dt = duration / n_steps, and ``duration``
    may be traced, e.g. batched with ``vmap``).

    base_angle: None (prescribed joints held at their q0 value) or a
    JAX-traceable t -> angle for the robot's single prescribed joint;
    joint_motion: the same for several prescribed DoFs, t -> (n_a,).
    tendon_force: None, a tension >= 0 (N) or a callable t -> tension(s).
    q0, qd0: (n,) initial coordinates/velocities (default: rest); entries of
    prescribed DoFs are replaced by the law at t = 0.
    integrator: "rk4" (default), "midpoint", "euler", "imex" or "ars443"
    (see ``gvsjax.integrators``). save_every: keep every k-th state.

    dtype: jnp.float64 (default) or jnp.float32, the precision of the whole
    computation. float32 runs 2.5-2.7x the throws/s of a batch on a CPU
    (twice the SIMD lanes); at the basketball task's 40 ars443 steps its
    releases are within 0.05 mm of float64's, so 0.37 mm from a converged
    run like float64's (tests/test_precision.py, issue 4 notes). Fine steps
    or long horizons accumulate fp32 rounding: check against float64.

    The compiled program is cached per robot structure, step count and
    control functions: calling again with new numbers does not recompile.
    Bad input raises ValueError naming the parameter, before any compilation.
    Checks that need concrete numbers are skipped for traced arguments.
    """
    check_robot(robot)
    n = robot.n_dofs
    # --- argument checks (reliability, issue 6): types and shapes, before any tracing ---
    require(isinstance(integrator, str), "integrator", integrator,
            f"one of {sorted(integrators.INTEGRATORS)}")
    for name, value in (("duration", duration), ("dt", dt)):
        if (value is not None or name == "duration") and concrete(value):
            require(not isinstance(value, (bool, str, bytes)) and np.ndim(value) == 0
                    and np.issubdtype(np.asarray(value).dtype, np.number), name, value, "a scalar time (s)")
    for name, value in (("n_steps", n_steps), ("save_every", save_every)):
        require(value is None or not isinstance(value, (bool, np.bool_)), name, value, "an int >= 1")
    laws = (("base_angle", base_angle, (1,)), ("joint_motion", joint_motion, (len(robot.prescribed),)),
            ("tendon_force", tendon_force, (1, len(robot.tendons))))
    for name, fn, sizes in laws:
        if callable(fn):  # abstract evaluation only: catches a wrong output shape without compiling
            out = jax.eval_shape(fn, jax.ShapeDtypeStruct((), jax.dtypes.canonicalize_dtype(jnp.float64)))
            size = math.prod(out.shape) if hasattr(out, "shape") else None
            allowed = " or ".join(map(str, sorted(set(sizes))))
            require(size in sizes, name, fn, f"a callable t -> {allowed} value(s); "
                    f"it returns shape {getattr(out, 'shape', type(out).__name__)}")
    if tendon_force is not None and not callable(tendon_force) and concrete(tendon_force):
        try:  # numpy would read the string "0" as 0.0: text is not a tension
            ok = (not isinstance(tendon_force, (str, bytes))
                  and np.issubdtype(np.asarray(tendon_force).dtype, np.number))
            np.asarray(tendon_force, dtype=float)
        except (TypeError, ValueError):
            ok = False
        require(ok, "tendon_force", tendon_force, "a tension >= 0 N (one per tendon), or a callable")
    # --- end argument checks ---
    integrators.get(integrator)
    dtype = _float_dtype(dtype)
    n_steps, dt = _steps(duration, dt, n_steps)
    require(isinstance(save_every, int) and save_every >= 1 and n_steps % save_every == 0,
            "save_every", save_every, f"a positive int dividing n_steps={n_steps}")
    q0 = _initial(q0, n, "q0")
    qd0 = _initial(qd0, n, "qd0")
    law = _motion_law(robot, base_angle, joint_motion)
    tension_law, tension_value = _tension_law(robot, tendon_force)
    if check_stability and concrete(dt) and concrete(q0) and robot_is_concrete(robot):
        limit = stable_step_estimate(robot, integrator, np.asarray(q0, dtype=float))
        require(float(dt) <= limit, "dt", float(dt),
                f"(0, {limit:.4g}] s: the {integrator} stability limit estimated at q0 "
                "(or choose integrator='imex')")
    if tension_value is not None:
        tension_value = tension_value.astype(dtype)
    if dtype == np.float32:  # float64 array leaves (a traced E, say) would lift the run back to float64
        robot = jax.tree_util.tree_map(
            lambda x: x.astype(dtype) if hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jnp.floating) else x, robot)
    return _run(robot, jnp.asarray(q0, dtype=dtype), jnp.asarray(qd0, dtype=dtype),
                jnp.asarray(dt, dtype=dtype), tension_value, n_steps=n_steps, save_every=save_every,
                integrator=integrator, law=law, tension_law=tension_law)


@functools.partial(jax.jit, static_argnames=("n_steps", "save_every", "integrator", "law", "tension_law"))
def _run(robot, q0, qd0, dt, tension_value, *, n_steps, save_every, integrator, law, tension_law):
    if law is None:
        held = q0[jnp.asarray(robot.prescribed, dtype=int)]
        law = lambda t: held + 0.0 * t  # noqa: E731
    tension = tension_law if tension_law is not None else (
        None if tension_value is None else (lambda t: tension_value))
    system = FreeDynamics(robot, law, tension)
    step = integrators.get(integrator)
    u = jnp.asarray(robot.free, dtype=int)
    qu0, qdu0 = q0[u], qd0[u]

    def one(carry, _):
        k, q, qd = carry
        q, qd = step.step(system, k * dt, q, qd, dt)
        return (k + 1, q, qd), None

    def chunk(carry, _):
        carry, _ = jax.lax.scan(one, carry, None, length=save_every)
        k, q, qd = carry
        return carry, (k, jnp.stack(q), jnp.stack(qd))

    split = lambda x: tuple(x[i] for i in range(x.shape[0]))  # noqa: E731
    carry0 = (jnp.asarray(0, dtype=int), split(qu0), split(qdu0))
    _, (ks, qus, qdus) = jax.lax.scan(chunk, carry0, None, length=n_steps // save_every)
    t = jnp.concatenate([jnp.zeros(1, dtype=ks.dtype), ks]) * dt
    qu = jnp.concatenate([qu0[None], qus])
    qdu = jnp.concatenate([qdu0[None], qdus])
    return _assemble(robot, system, t, qu, qdu)


def _assemble(robot, system, t, qu, qdu) -> Trajectory:
    m = t.shape[0]
    q = jnp.zeros((m, robot.n_dofs), qu.dtype).at[:, jnp.asarray(robot.free, dtype=int)].set(qu)
    qd = jnp.zeros((m, robot.n_dofs), qu.dtype).at[:, jnp.asarray(robot.free, dtype=int)].set(qdu)
    if robot.prescribed:
        a = jnp.asarray(robot.prescribed, dtype=int)
        qa, qda, _ = jax.vmap(lambda s: tuple(jnp.stack(x) for x in system.prescribed_state(s)))(t)
        q, qd = q.at[:, a].set(qa), qd.at[:, a].set(qda)
        split = lambda x: tuple(x[i] for i in range(x.shape[0]))  # noqa: E731
        torque = jax.vmap(lambda s, x, v: system.effort(s, split(x), split(v)))(t, qu, qdu)
    else:
        torque = jnp.zeros((m, 0), qu.dtype)
    tip, tip_vel = jax.vmap(lambda x, v: tip_state(robot, x, v))(q, qd)
    return Trajectory(t=t, q=q, qd=qd, tip=tip, tip_velocity=tip_vel, joint_torque=torque)


def _steps(duration, dt, n_steps) -> tuple[int, Any]:
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


def _float_dtype(dtype) -> np.dtype:
    """float64 or float32 as a numpy dtype, from any of their spellings (jnp/np types, names)."""
    try:
        parsed = None if dtype is None or isinstance(dtype, (bool, int, float)) else np.dtype(dtype)
    except TypeError:
        parsed = None
    require(parsed in (np.float64, np.float32), "dtype", dtype, "jnp.float64 (default) or jnp.float32")
    assert parsed is not None  # for mypy: require raised otherwise
    return parsed


def _initial(x, n: int, name: str):
    if x is None:
        return np.zeros(n)
    if concrete(x):
        try:  # (issue 6) a ragged or non-numeric q0/qd0 is named, not a numpy error
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


# ----------------------------------------------------------------------------
# linear stability estimate (numpy, before compilation)


def linear_matrices(robot: Robot, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M_uu(q0), K_uu, D_uu as numpy arrays (evaluated eagerly)."""
    n = robot.n_dofs
    qs = [jnp.asarray(float(x)) for x in q0]
    M, _ = dynamics.mass_and_forces(robot, qs, [0] * n, [0] * len(robot.tendons))
    K, D = dynamics.stiffness_and_damping(robot)
    u = robot.free
    full = lambda A, sym: np.array(  # noqa: E731
        [[float(lie.as_array(A[i][j] if (i >= j or not sym) else A[j][i])) for j in u] for i in u]
    )
    return full(M, True), full(K, False), full(D, False)


def stable_step_estimate(robot: Robot, integrator: str, q0: np.ndarray) -> float:
    """Largest stable dt of the linearised free dynamics at q0 (gravity and
    centrifugal stiffening left out: they move the estimate by a few %)."""
    if integrator in ("imex", "ars443") or not robot.free:
        return math.inf
    M, K, D = linear_matrices(robot, q0)
    Minv = np.linalg.inv(M)
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ D]])
    lam = np.linalg.eigvals(A)

    def stable(dt):
        if integrator == "rk4":
            z = lam * dt
            return np.all(np.abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24) <= 1 + 1e-12)
        if integrator == "midpoint":  # fixed-point iterations must contract
            return np.max(np.abs(lam)) * dt / 2 < 1
        # semi-implicit Euler on the linear system
        I = np.eye(n)
        G = np.block([[I - dt * dt * Minv @ K, dt * (I - dt * Minv @ D)], [-dt * Minv @ K, I - dt * Minv @ D]])
        return np.max(np.abs(np.linalg.eigvals(G))) <= 1 + 1e-9

    lo, hi = 0.0, 10.0
    if stable(hi):
        return math.inf
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo
