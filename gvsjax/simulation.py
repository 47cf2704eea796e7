"""The time-stepping driver: robot + controls -> ``Trajectory``, on ``lax.scan``."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax import inputs, integrators
from gvsjax.kinematics import tip_state
from gvsjax.model import Robot
from gvsjax.stability import stable_step_estimate
from gvsjax.system import FreeDynamics
from gvsjax.trajectory import Trajectory
from gvsjax.validation import check_robot, concrete, require


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
    concrete Python or numpy numbers) or ``n_steps`` (then dt = duration /
    n_steps, and ``duration`` may be traced, e.g. batched with ``vmap``).
    Either way ``simulate`` works inside ``jit``, ``vmap`` and ``grad``.

    base_angle: None (prescribed joints held at their q0 value) or a
    JAX-traceable t -> angle for the robot's single prescribed joint;
    joint_motion: the same for several prescribed DoFs, t -> (n_a,).
    tendon_force: None, a tension >= 0 (N) or a callable t -> tension(s).
    q0, qd0: (n,) initial coordinates/velocities (default: rest); entries of
    prescribed DoFs are replaced by the law at t = 0.
    integrator: "rk4" (default), "midpoint", "euler", "imex" or "ars443"
    (see ``gvsjax.integrators``). save_every: keep every k-th state.
    check_stability: with a concrete ``dt``, reject a step beyond the
    integrator's linear stability limit at q0 (``gvsjax.stability``).

    dtype: jnp.float64 (default) or jnp.float32, the precision of the whole
    computation. float32 runs ~2.5x the throws/s of a batch on a CPU (twice
    the SIMD lanes); fine steps or long horizons accumulate its rounding, so
    check a new use against float64.

    The compiled program is cached per robot structure, step count and
    control functions: calling again with new numbers does not recompile.
    Bad input raises ValueError naming the parameter, before any compilation.
    """
    check_robot(robot)
    n = robot.n_dofs
    laws = (("base_angle", base_angle, (1,)), ("joint_motion", joint_motion, (len(robot.prescribed),)),
            ("tendon_force", tendon_force, (1, len(robot.tendons))))
    inputs.check_call(robot, integrator, duration, dt, n_steps, save_every, laws)
    dtype = inputs.float_dtype(dtype)
    n_steps, dt = inputs.steps(duration, dt, n_steps)
    require(isinstance(save_every, int) and save_every >= 1 and n_steps % save_every == 0,
            "save_every", save_every, f"a positive int dividing n_steps={n_steps}")
    q0 = inputs.initial(q0, n, "q0")
    qd0 = inputs.initial(qd0, n, "qd0")
    law = inputs.motion_law(robot, base_angle, joint_motion)
    tension_law, tension_value = inputs.tension_law(robot, tendon_force)
    if check_stability and concrete(dt) and concrete(q0) and inputs.robot_is_concrete(robot):
        limit = stable_step_estimate(robot, integrator, np.asarray(q0, dtype=float))
        require(float(dt) <= limit, "dt", float(dt),
                f"(0, {limit:.4g}] s: the {integrator} stability limit estimated at q0 "
                "(or choose integrator='imex' or 'ars443')")
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

    carry0 = (jnp.asarray(0, dtype=int), _split(qu0), _split(qdu0))
    _, (ks, qus, qdus) = jax.lax.scan(chunk, carry0, None, length=n_steps // save_every)
    t = jnp.concatenate([jnp.zeros(1, dtype=ks.dtype), ks]) * dt
    qu = jnp.concatenate([qu0[None], qus])
    qdu = jnp.concatenate([qdu0[None], qdus])
    return _assemble(robot, system, t, qu, qdu)


def _split(x) -> tuple:
    """A vector as a tuple of scalars (the integrators' state layout)."""
    return tuple(x[i] for i in range(x.shape[0]))


def _assemble(robot, system, t, qu, qdu) -> Trajectory:
    m = t.shape[0]
    q = jnp.zeros((m, robot.n_dofs), qu.dtype).at[:, jnp.asarray(robot.free, dtype=int)].set(qu)
    qd = jnp.zeros((m, robot.n_dofs), qu.dtype).at[:, jnp.asarray(robot.free, dtype=int)].set(qdu)
    if robot.prescribed:
        a = jnp.asarray(robot.prescribed, dtype=int)
        qa, qda, _ = jax.vmap(lambda s: tuple(jnp.stack(x) for x in system.prescribed_state(s)))(t)
        q, qd = q.at[:, a].set(qa), qd.at[:, a].set(qda)
        torque = jax.vmap(lambda s, x, v: system.effort(s, _split(x), _split(v)))(t, qu, qdu)
    else:
        torque = jnp.zeros((m, 0), qu.dtype)
    tip, tip_vel = jax.vmap(lambda x, v: tip_state(robot, x, v))(q, qd)
    return Trajectory(t=t, q=q, qd=qd, tip=tip, tip_velocity=tip_vel, joint_torque=torque)
