"""The 3D throw: yaw and swing to release (simulated), then the ball's flight.

The arm (``gv.paper_arm_3d(tip_force=5.886)``) swings by the paper's law,
theta(t) = theta_F (t/T)^2, theta_F = 210 deg, and at the same time turns
about the vertical to the yaw psi_R it faces at release t_rel = delta T:
psi(t) = psi_R s(t / t_rel), s(u) = 3u^2 - 2u^3 (the turn starts and ends at
rest). The ball (0.6 kg) is a constant 5.886 N force along -z on the tip
until release; only [0, t_rel] is simulated (``n_steps`` steps of
``integrator``). The turn's acceleration and braking bend the arm out of the
swing plane while it whips the ball up, so the ball does not fly exactly where
the base points at release.
The flight is ``gvsjax.tasks.ballistics``'s, z up, from the tip's release
position p0 and velocity v0 (world, m and m/s).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from gvsjax.core.simulation import simulate
from gvsjax.core.trajectory import Trajectory
from gvsjax.tasks.ballistics import closest_offset, distance, flight_point, floor_time
from gvsjax.tasks.throw3d.params import Throw3DParams

_RANGES = ("T_range", "delta_range", "yaw_range")


def action_to_physical(action: jax.Array, params: Throw3DParams) -> tuple[jax.Array, jax.Array, jax.Array]:
    """(..., 3) action in [-1, 1] (clipped) -> (T s, delta, psi_R rad), affinely."""
    u = (jnp.clip(action, -1.0, 1.0) + 1.0) / 2.0
    lo_hi = [getattr(params, r) for r in _RANGES]
    T, delta, psi = (lo + u[..., i] * (hi - lo) for i, (lo, hi) in enumerate(lo_hi))
    return T, delta, psi


def physical_to_action(T, delta, psi, params: Throw3DParams) -> jax.Array:
    """Inverse of ``action_to_physical``: (T, delta, psi_R) -> (..., 3) action."""
    vals = (T, delta, psi)
    return jnp.stack([2.0 * (v - lo) / (hi - lo) - 1.0
                      for v, (lo, hi) in zip(vals, (getattr(params, r) for r in _RANGES), strict=True)], -1)


def turn(u):
    """The yaw's profile s(u) = 3u^2 - 2u^3 over u = t / t_rel in [0, 1] (clipped): rest to rest."""
    u = jnp.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def swing(params: Throw3DParams, T, delta, psi, *, n_steps: int | None = None, integrator: str | None = None,
          save_every: int | None = None) -> Trajectory:
    """The simulated yaw-and-swing from rest to release at delta T, returned in float64.

    By default with the task's ``n_steps`` and ``integrator``, only the start
    and release states saved; a drawing asks for finer steps and more states.
    """
    n = params.n_steps if n_steps is None else n_steps
    dtype = params.sim_dtype
    T, delta, psi = (jnp.asarray(x).astype(dtype) for x in (T, delta, psi))
    law = lambda t: jnp.stack([psi * turn(t / (delta * T)), params.theta_final * (t / T) ** 2])  # noqa: E731
    traj = simulate(params.arm, delta * T, n_steps=n, joint_motion=law, save_every=save_every or n,
                    integrator=integrator or params.integrator, check_stability=False, dtype=dtype)
    return jax.tree_util.tree_map(lambda x: x.astype(float), traj)


def release_state(params: Throw3DParams, T, delta, psi) -> tuple[jax.Array, jax.Array]:
    """Tip position (3,) m and velocity (3,) m/s at release."""
    traj = swing(params, T, delta, psi)
    return traj.tip[-1], traj.tip_velocity[-1]


def flight_path(p0, v0, params: Throw3DParams, n: int = 200) -> jax.Array:
    """(n, 3) points of the flight from release to the floor, uniform in flight time."""
    tau = jnp.linspace(0.0, floor_time(p0, v0, params.g, params.court[2]), n)
    return flight_point(p0, v0, tau, params.g)


def throw_residual(params: Throw3DParams, action, target):
    """The flight's closest point minus ``target`` (3,) m (``ballistics.closest_offset``: Gauss-Newton's
    residual), plus (T, delta, psi_R, p0, v0) of one throw. Differentiable in ``action``."""
    T, delta, psi = action_to_physical(action, params)
    p0, v0 = release_state(params, T, delta, psi)
    tau_end = floor_time(p0, v0, params.g, params.court[2])
    r, _ = closest_offset(p0, v0, target, params.g, tau_end)
    return r, (T, delta, psi, p0, v0)


def throw_cost(params: Throw3DParams, action, target):
    """Cost (m): the norm of ``throw_residual``, plus its (T, delta, psi_R, p0, v0)."""
    r, aux = throw_residual(params, action, target)
    return distance(r), aux
