"""The throw: the arm's swing to release (simulated), then the ball's ballistic flight.

The paper's arm (``gv.paper_arm(tip_force=5.886)``) has its revolute base
driven by theta(t) = theta_F (t/T)^2, theta_F = 210 deg. The ball (0.6 kg) is
a constant 5.886 N force along -y on the tip until release at t_rel = delta T;
only [0, t_rel] is simulated (``n_steps`` = 40 steps of the ``ars443`` IMEX
integrator: every release within 0.5 mm of a converged run; RK4 would need
>= 217 steps for stability alone). The ball then flies from the tip's release
position p0 and velocity v0 (world x-y, m and m/s):
p(tau) = p0 + v0 tau + (0, -g) tau^2 / 2, until it reaches ``y_floor``
(``gvsjax.tasks.ballistics``).
Every figure and animation of the task draws its arm from ``swing`` below.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from gvsjax.core.simulation import simulate
from gvsjax.core.trajectory import Trajectory
from gvsjax.tasks.ballistics import closest_approach, flight_point, floor_time
from gvsjax.tasks.basketball.params import BasketballParams


def action_to_physical(action: jax.Array, params: BasketballParams) -> tuple[jax.Array, jax.Array]:
    """(..., 2) action in [-1, 1] (clipped) -> (T s, delta), affinely."""
    a = jnp.clip(action, -1.0, 1.0)
    u = (a + 1.0) / 2.0
    T = params.T_range[0] + u[..., 0] * (params.T_range[1] - params.T_range[0])
    delta = params.delta_range[0] + u[..., 1] * (params.delta_range[1] - params.delta_range[0])
    return T, delta


def physical_to_action(T, delta, params: BasketballParams) -> jax.Array:
    """Inverse of ``action_to_physical``: (T, delta) -> (..., 2) action."""
    uT = (T - params.T_range[0]) / (params.T_range[1] - params.T_range[0])
    ud = (delta - params.delta_range[0]) / (params.delta_range[1] - params.delta_range[0])
    return jnp.stack([2.0 * uT - 1.0, 2.0 * ud - 1.0], axis=-1)


def swing(params: BasketballParams, T, delta, *, n_steps: int | None = None, integrator: str | None = None,
          save_every: int | None = None) -> Trajectory:
    """The simulated swing from rest to release at delta T, in float64.

    By default with the task's own ``n_steps`` and ``integrator`` and only the
    start and release states saved; a drawing asks for finer steps and more
    saved states (e.g. ``n_steps=300, integrator="rk4", save_every=5``).
    """
    n = params.n_steps if n_steps is None else n_steps
    dtype = params.sim_dtype
    T, delta = jnp.asarray(T).astype(dtype), jnp.asarray(delta).astype(dtype)
    law = lambda t: params.theta_final * (t / T) ** 2  # noqa: E731
    traj = simulate(params.arm, delta * T, n_steps=n, base_angle=law, save_every=save_every or n,
                    integrator=integrator or params.integrator, check_stability=False, dtype=dtype)
    return jax.tree_util.tree_map(lambda x: x.astype(float), traj)


def release(params: BasketballParams, T, delta) -> tuple[jax.Array, jax.Array, jax.Array]:
    """(q (n,), tip position p0 (2,) m, tip velocity v0 (2,) m/s) at release."""
    traj = swing(params, T, delta)
    return traj.q[-1], traj.tip[-1, :2], traj.tip_velocity[-1, :2]


def release_state(params: BasketballParams, T, delta) -> tuple[jax.Array, jax.Array]:
    """Tip position (2,) m and velocity (2,) m/s at release."""
    _, p0, v0 = release(params, T, delta)
    return p0, v0


def flight_path(p0, v0, params: BasketballParams, n: int = 200) -> jax.Array:
    """(n, 2) points of the flight from release to the floor, uniform in flight time."""
    tau = jnp.linspace(0.0, floor_time(p0, v0, params.g, params.y_floor), n)
    return flight_point(p0, v0, tau, params.g)


def throw_cost(params: BasketballParams, action, target):
    """Cost (m), plus (T, delta, p0, v0) of one throw. Differentiable in ``action``."""
    T, delta = action_to_physical(action, params)
    p0, v0 = release_state(params, T, delta)
    tau_end = floor_time(p0, v0, params.g, params.y_floor)
    cost, _ = closest_approach(p0, v0, target, params.g, tau_end)
    return cost, (T, delta, p0, v0)
