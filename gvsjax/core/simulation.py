"""The time-stepping driver: robot + controls -> ``Trajectory``, on ``lax.scan``."""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core import active_strain, contact, inputs, integrators, linalg
from gvsjax.core.kinematics import tip_state
from gvsjax.core.model import Robot
from gvsjax.core.stability import stable_step_estimate
from gvsjax.core.system import FreeDynamics
from gvsjax.core.trajectory import Trajectory
from gvsjax.core.validation import check_robot, concrete, require


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
    joint_force: Any = None,
    wrench: Any = None,
    strain_force: Any = None,
    rest_strain: Any = None,
    controller: Callable | None = None,
    control_every: int | None = None,
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
    tendon_force: None, tensions >= 0 (N, one per tendon or one for all), or
    a callable t -> tensions or (t, q, qd) -> tensions.
    joint_force: None, forces on the actuated joint coordinates
    (``robot.actuated``: joint DoFs not prescribed; N m on a rotation, N on a
    translation), or a callable of t or of (t, q, qd). Callables of (t, q, qd)
    get the full coordinate and velocity vectors and are evaluated at every
    integrator stage: continuous feedback.
    wrench: None, (n_wrenches, 6) wrenches (moment N m, force N) at the
    robot's ``wrenches`` points (world or section frame), or a callable of t
    or of (t, q, qd) returning them.
    strain_force: None, an (n,) generalized force added to the right-hand side
    of every coordinate (N m or N; e.g. ``gvsjax.core.muscles.moment_map(robot) @ u``,
    internal moments on the strain coordinates), or a callable of t or of
    (t, q, qd) returning it.
    rest_strain: None, or values of the rest strain's change at the robot's
    ``rest_strains`` segments ((n_values,), or (n_segments, n_components) for a
    single ``RestStrainSegments``; 1/m for curvature and twist), a constant or a
    callable of t or of (t, q, qd): active strain (``gvsjax.core.active_strain``).
    controller, control_every: a sampled feedback controller (t, q, qd) ->
    {"tendon_force": ..., "joint_force": ..., "wrench": ..., "strain_force": ...,
    "rest_strain": ...}
    (any of the keys) evaluated every
    ``control_every`` integrator steps on the current state, its outputs held
    in between (zero-order hold, as a digital controller or an RL policy acts).
    q0, qd0: (n,) initial coordinates/velocities (default: rest); entries of
    prescribed DoFs are replaced by the law at t = 0.
    integrator: "rk4" (default), "midpoint", "euler", "imex" or "ars443"
    (see ``gvsjax.core.integrators``). save_every: keep every k-th state.
    check_stability: with a concrete ``dt``, reject a step beyond the
    integrator's linear stability limit at q0, the contact penalty included
    (``gvsjax.core.stability``). A run that goes non-finite anyway is marked in
    ``Trajectory.finite``, and an eager call warns (RuntimeWarning).

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
    laws = (("base_angle", base_angle, (1,), False), ("joint_motion", joint_motion, (len(robot.prescribed),), False),
            ("tendon_force", tendon_force, (1, len(robot.tendons)), True),
            ("joint_force", joint_force, (1, len(robot.actuated)), True),
            ("wrench", wrench, (6 * len(robot.wrenches),), True), ("strain_force", strain_force, (n,), True),
            ("rest_strain", rest_strain, (active_strain.size(robot),), True))
    inputs.check_call(robot, integrator, duration, dt, n_steps, save_every, laws)
    control = inputs.controller(robot, controller, control_every, tendon_force, joint_force, wrench, strain_force,
                                rest_strain)
    dtype = inputs.float_dtype(dtype)
    n_steps, dt = inputs.steps(duration, dt, n_steps)
    require(isinstance(save_every, int) and save_every >= 1 and n_steps % save_every == 0,
            "save_every", save_every, f"a positive int dividing n_steps={n_steps}")
    q0 = inputs.initial(q0, n, "q0")
    qd0 = inputs.initial(qd0, n, "qd0")
    law = inputs.motion_law(robot, base_angle, joint_motion)
    tension_law, tension_value = inputs.tension_law(robot, tendon_force)
    force_law, force_value = inputs.joint_force_law(robot, joint_force)
    wrench_law, wrench_value = inputs.wrench_law(robot, wrench)
    strain_law, strain_value = inputs.strain_force_law(robot, strain_force)
    rest_law, rest_value = inputs.rest_strain_law(robot, rest_strain)
    if check_stability and concrete(dt) and concrete(q0) and inputs.robot_is_concrete(robot):
        _check_step(robot, integrator, float(dt), np.asarray(q0, dtype=float))
    if control is not None:
        require(n_steps % control.every == 0, "control_every", control.every,
                f"a divisor of n_steps={n_steps} (whole control periods)")
    values = tuple(None if v is None else v.astype(dtype)
                   for v in (tension_value, force_value, wrench_value, strain_value, rest_value))
    if dtype == np.float32:  # float64 array leaves (a traced E, say) would lift the run back to float64
        robot = jax.tree_util.tree_map(
            lambda x: x.astype(dtype) if hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jnp.floating) else x, robot)
    run = _run.__wrapped__ if _building_a_program() else _run  # type: ignore[attr-defined]
    traj = run(robot, jnp.asarray(q0, dtype=dtype), jnp.asarray(qd0, dtype=dtype),
               jnp.asarray(dt, dtype=dtype), values, n_steps=n_steps, save_every=save_every,
               integrator=integrator, law=law, laws=(tension_law, force_law, wrench_law, strain_law, rest_law),
               control=control, stacked_min_dofs=linalg.STACKED_MIN_DOFS)
    _warn_if_diverged(robot, traj, integrator)
    return traj


def _check_step(robot: Robot, integrator: str, dt: float, q0: np.ndarray) -> None:
    """Refuse a dt beyond the integrator's stability limit at q0, naming the contact when its
    penalty is what sets the limit."""
    limit = stable_step_estimate(robot, integrator, q0)
    if dt <= limit:
        return
    if stable_step_estimate(robot, integrator, q0, with_contact=False) >= dt:
        require(False, "dt", dt, f"(0, {limit:.4g}] s: the {integrator} stability limit of the explicit contact "
                "penalty pressed deep (k / (rho A) per soft link; gvsjax.core.stability); lower contact.rod.stiffness, "
                "or pass check_stability=False for a contact known to stay short")
    require(False, "dt", dt, f"(0, {limit:.4g}] s: the {integrator} stability limit estimated at q0 "
            "(or choose integrator='imex' or 'ars443')")


def _warn_if_diverged(robot: Robot, traj: Trajectory, integrator: str) -> None:
    """An eager run that went non-finite says so (under jit or vmap: ``Trajectory.finite``)."""
    if not concrete(traj.finite) or bool(np.all(np.asarray(traj.finite))):
        return
    t = float(np.asarray(traj.t)[np.argmin(np.asarray(traj.finite))])
    cause = ("; with contact an explicit penalty too stiff for the step is the usual cause "
             "(gvsjax.core.stability.stable_step_estimate)" if robot.contact is not None else "")
    warnings.warn(f"simulate ({integrator}): the state is non-finite from t = {t:.6g} s on{cause}",
                  RuntimeWarning, stacklevel=3)


def _building_a_program() -> bool:
    """True when a caller's jit (or scan, eval_shape) is tracing: the simulation is then traced
    straight into that program. Under ``jit(vmap(...))`` a separately jitted run would be traced
    once and then batched in a second pass over its equations, a third of a task step's trace
    time. Eager calls and eager ``vmap`` keep the jitted run, which compiles once and is cached.
    Reads JAX's trace stack (internal API); if that changes, the jitted run is used."""
    try:
        from jax._src import core
        from jax._src.interpreters import partial_eval as pe

        trace = core.unsafe_get_current_trace()
        while trace is not None:
            if isinstance(trace, pe.DynamicJaxprTrace):
                return True
            trace = getattr(trace, "parent_trace", None)
    except (ImportError, AttributeError):
        pass
    return False


def _input(law, value):
    """An input as a callable (t, q, qd), or None (zero)."""
    if law is not None:
        return law
    return None if value is None else (lambda t, q, qd: value)


def _held(system: FreeDynamics, held: dict) -> FreeDynamics:
    """``system`` with the controller's held outputs in place of its own inputs."""
    if not held:
        return system
    value = lambda key: (lambda t, q, qd: held[key])  # noqa: E731
    names = {"tendon_force": "tension", "joint_force": "joint_force", "wrench": "wrench",
             "strain_force": "strain_force", "rest_strain": "rest_strain"}
    return system.with_inputs(**{names[k]: value(k) for k in held})


def _control(system: FreeDynamics, control, t, q_u, qd_u) -> dict:
    q, qd, _ = system.full_state(t, q_u, qd_u)
    return control(t, jnp.stack(q), jnp.stack(qd))


@functools.partial(jax.jit, static_argnames=("n_steps", "save_every", "integrator", "law", "laws", "control",
                                             "stacked_min_dofs"))
def _run(robot, q0, qd0, dt, values, *, n_steps, save_every, integrator, law, laws, control, stacked_min_dofs):
    # the solves' layout (linalg.stacked_solves) is a static argument, so a cached run never
    # serves a call made under another layout
    with linalg.stacked_solves(stacked_min_dofs):
        return _trace_run(robot, q0, qd0, dt, values, n_steps=n_steps, save_every=save_every,
                          integrator=integrator, law=law, laws=laws, control=control)


def _trace_run(robot, q0, qd0, dt, values, *, n_steps, save_every, integrator, law, laws, control):
    if law is None:
        held = q0[jnp.asarray(robot.prescribed, dtype=int)]
        law = lambda t: held + 0.0 * t  # noqa: E731
    system = FreeDynamics(robot, law, *(_input(f, v) for f, v in zip(laws, values)))
    step = integrators.get(integrator)
    u = jnp.asarray(robot.free, dtype=int)
    qu0, qdu0 = _split(q0[u]), _split(qd0[u])
    t0 = jnp.zeros((), dt.dtype)
    u0 = {} if control is None else _control(system, control, t0, qu0, qdu0)

    # Rematerialised under reverse-mode AD: the backward pass recomputes each step from its
    # state rather than storing every intermediate of the unrolled step, so gradients trace
    # and compile much faster. The forward program is unchanged.
    advance = jax.checkpoint(lambda held, t, q, qd: step.step(_held(system, held), t, q, qd, dt),
                             prevent_cse=False)  # CSE across scan steps is impossible anyway

    def one(carry, _):
        k, q, qd, held = carry
        t = k * dt
        if control is not None:  # sample at the period's first step, hold otherwise
            held = jax.lax.cond(k % control.every == 0, lambda: _control(system, control, t, q, qd), lambda: held)
        q, qd = advance(held, t, q, qd)
        return (k + 1, q, qd, held), None

    def chunk(carry, _):
        carry, _ = jax.lax.scan(one, carry, None, length=save_every)
        k, q, qd, held = carry
        return carry, (k, jnp.stack(q), jnp.stack(qd), held)

    carry0 = (jnp.asarray(0, dtype=int), qu0, qdu0, u0)
    _, (ks, qus, qdus, helds) = jax.lax.scan(chunk, carry0, None, length=n_steps // save_every)
    t = jnp.concatenate([jnp.zeros(1, dtype=ks.dtype), ks]) * dt
    qu = jnp.concatenate([jnp.stack(qu0)[None], qus])
    qdu = jnp.concatenate([jnp.stack(qdu0)[None], qdus])
    helds = jax.tree.map(lambda a, b: jnp.concatenate([a[None], b]), u0, helds)
    return _assemble(robot, system, t, qu, qdu, helds)


def _split(x) -> tuple:
    """A vector as a tuple of scalars (the integrators' state layout)."""
    return tuple(x[i] for i in range(x.shape[0]))


def _assemble(robot, system, t, qu, qdu, helds) -> Trajectory:
    """The saved states as a Trajectory; efforts and inputs at each saved state (a held
    control: the value applied over the step that ends there)."""
    m = t.shape[0]
    q = jnp.zeros((m, robot.n_dofs), qu.dtype).at[:, jnp.asarray(robot.free, dtype=int)].set(qu)
    qd = jnp.zeros((m, robot.n_dofs), qu.dtype).at[:, jnp.asarray(robot.free, dtype=int)].set(qdu)
    if robot.prescribed:
        a = jnp.asarray(robot.prescribed, dtype=int)
        qa, qda, _ = jax.vmap(lambda s: tuple(jnp.stack(x) for x in system.prescribed_state(s)))(t)
        q, qd = q.at[:, a].set(qa), qd.at[:, a].set(qda)
        torque = jax.vmap(lambda s, x, v, h: _held(system, h).effort(s, _split(x), _split(v)))(t, qu, qdu, helds)
    else:
        torque = jnp.zeros((m, 0), qu.dtype)

    def applied(s, x, v, h):
        sys = _held(system, h)
        qf, qdf, _ = sys.full_state(s, _split(x), _split(v))
        tension, force, wrench = sys.inputs(s, qf, qdf)
        as_vec = lambda xs, n: jnp.asarray(jnp.stack(xs), qu.dtype) if xs else jnp.zeros(n, qu.dtype)  # noqa: E731
        w6 = jnp.asarray([list(w) for w in wrench], qu.dtype) if wrench else jnp.zeros((len(robot.wrenches), 6),
                                                                                      qu.dtype)
        return as_vec(tension, len(robot.tendons)), as_vec(force, len(robot.actuated)), w6.astype(qu.dtype)

    tension, force, wrench = jax.vmap(applied)(t, qu, qdu, helds)
    tip, tip_vel = jax.vmap(lambda x, v: tip_state(robot, x, v))(q, qd)
    touch, gap = jax.vmap(lambda s, x, v: contact.report(robot, x, v, s))(t, q, qd)
    return Trajectory(t=t, q=q, qd=qd, tip=tip, tip_velocity=tip_vel, joint_torque=torque,
                      tendon_force=tension, joint_force=force, wrench=wrench, contact_force=touch,
                      contact_gap=gap, in_contact=jnp.any(gap < 0, axis=-1),
                      finite=jnp.all(jnp.isfinite(q), axis=-1) & jnp.all(jnp.isfinite(qd), axis=-1))
