"""The motion of one step: base angle and tendon tension on smooth ramps, simulated.

The paper's arm with one tendon at 2.5 cm from the midline
(``paper_arm(tendon_offset=0.025)``, q = (theta, q1, q2)), gravity on, no
ball. In each step of ``step_time`` = 5 s (``n_steps`` = 60 ``ars443`` steps:
both steps' end tips within 0.2 mm of 5000 RK4 steps; RK4 needs ~360 for
stability) the base angle moves from its current value theta_0 to the
commanded theta_F on a cycloidal profile,

    theta(t) = theta_0 + (theta_F - theta_0) s(t / T_s),
    s(u) = u - sin(2 pi u) / (2 pi),

whose velocity (theta_F - theta_0)(1 - cos 2 pi u) / T_s is a sinusoid, with
zero velocity and acceleration at both ends. The tendon tension follows the
same ramp from its value at the start of the step (0 N in step 1) to the
commanded one, so neither control jumps at a step boundary. Step 2 starts from
step 1's end state (q, qd and the tension).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from gvsjax.core.simulation import simulate
from gvsjax.tasks.pickplace.params import PickPlaceParams


def action_to_physical(action, params: PickPlaceParams):
    """(..., 2) action in [-1, 1] (clipped) -> (theta_F rad, tension N)."""
    a = jnp.clip(action, -1.0, 1.0)
    return params.angle_max * a[..., 0], params.tension_max * (a[..., 1] + 1.0) / 2.0


def physical_to_action(theta_final, tension, params: PickPlaceParams):
    """Inverse of ``action_to_physical`` (no clipping)."""
    return jnp.stack([theta_final / params.angle_max,
                      2.0 * tension / params.tension_max - 1.0], axis=-1)


def cycloid(u):
    """s(u) = u - sin(2 pi u) / (2 pi): 0 -> 1 with s' = s'' = 0 at u = 0 and 1."""
    return u - jnp.sin(2.0 * jnp.pi * u) / (2.0 * jnp.pi)


def controls(theta0, theta_final, tension0, tension, step_time):
    """The step's laws t -> theta (rad) and t -> tension (N), t in [0, step_time]."""
    angle = lambda t: theta0 + (theta_final - theta0) * cycloid(t / step_time)
    pull = lambda t: tension0 + (tension - tension0) * cycloid(t / step_time)
    return angle, pull


def run_step(params: PickPlaceParams, q, qd, tension0, theta_final, tension, save_every=None):
    """Simulate one step from (q, qd, tension0): the ``Trajectory`` (end state last).

    ``save_every`` defaults to ``n_steps`` (start and end states only).
    """
    dtype = params.sim_dtype
    cast = lambda x: jnp.asarray(x).astype(dtype)  # noqa: E731
    angle, pull = controls(cast(q[0]), cast(theta_final), cast(tension0), cast(tension), params.step_time)
    traj = simulate(params.arm, params.step_time, n_steps=params.n_steps, base_angle=angle,
                       tendon_force=pull, q0=q, qd0=qd, save_every=save_every or params.n_steps,
                       integrator=params.integrator, check_stability=False, dtype=dtype)
    # back to float64: the env's state and tables stay float64 whatever the simulation ran in
    return jax.tree_util.tree_map(lambda x: x.astype(float), traj)


def episode(params: PickPlaceParams, actions, save_every=None):
    """Both steps from rest for actions (2, 2): the two trajectories (any ``params.arm`` whose
    first coordinate is the base angle)."""
    theta1, t1 = action_to_physical(actions[0], params)
    theta2, t2 = action_to_physical(actions[1], params)
    zero = jnp.zeros(params.arm.n_dofs)
    tr1 = run_step(params, zero, zero, 0.0, theta1, t1, save_every)
    tr2 = run_step(params, tr1.q[-1], tr1.qd[-1], t1, theta2, t2, save_every)
    return tr1, tr2


def episode_distances(params: PickPlaceParams, actions, targets):
    """(2,) tip-to-target distances (m) of both steps; differentiable in ``actions``."""
    tr1, tr2 = episode(params, actions)
    tips = jnp.stack([tr1.tip[-1, :2], tr2.tip[-1, :2]])
    return jnp.sqrt(jnp.sum((tips - targets) ** 2, -1) + 1e-30), tips


def reward_of(distance, params: PickPlaceParams):
    """Reward exp(-k d) of a tip-to-target distance d (m)."""
    return jnp.exp(-params.k * distance)
