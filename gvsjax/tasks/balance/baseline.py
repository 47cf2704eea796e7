"""A hand-designed controller for balance, as a baseline for the learnt policy: pump energy, then catch.

Far from upright it pumps: full torque along the base's rate (bang-bang) until the
energy of the arm taken as a rigid rod, 1/2 (m L^2 / 3) omega^2 - m g (L/2) cos(theta),
reaches ``energy_fraction`` of its upright value m g L / 2, then no torque. Within
``catch_deg`` of upright it balances with a PD law on the *tip*: torque = -(kp tilt -
kv v_x), the signed tilt of the base-to-tip line and the tip's horizontal velocity.
Feedback on the base angle and rate does not hold the soft arm: the base moves the
light first section of the rod, which the 0.05 s zero-order hold makes a derivative on
the base rate destabilise, while the tip carries the arm's weight.

It reads only the task's observation (``Balance.observe``), so it runs wherever a
policy does (``rollout``, ``evaluate``).
"""

from __future__ import annotations

import jax.numpy as jnp

from gvsjax.tasks.balance.params import BalanceParams


def energy_pd_policy(params: BalanceParams, kp: float = 60.0, kv: float = 15.0, catch_deg: float = 35.0,
                     energy_fraction: float = 0.95, mass: float | None = None):
    """``policy(obs (n, 14)) -> (n, 1)`` actions in [-1, 1]. ``mass``: the arm's mass (kg,
    default rho pi r^2 L of the paper's arm). Gains in N m per rad and N m per (m/s)."""
    link = params.arm.links[0]
    length = link.length
    m = mass if mass is not None else link.material.density * jnp.pi * link.radius**2 * length
    g = params.arm.gravity
    inertia, weight = m * length**2 / 3.0, m * g * length / 2.0

    def policy(obs):
        cos, omega = obs[:, 0], 10.0 * obs[:, 2]
        x, y, vx = obs[:, 7], obs[:, 8], 5.0 * obs[:, 9]
        energy = 0.5 * inertia * omega**2 - weight * cos
        pump = jnp.where(energy < energy_fraction * weight, jnp.where(omega >= 0, 1.0, -1.0), 0.0)
        signed_tilt = jnp.arctan2(-x, y)  # > 0 when the base angle is beyond pi
        catch = -(kp * signed_tilt - kv * vx) / params.torque_max
        near = 180.0 * obs[:, 11] < catch_deg
        return jnp.clip(jnp.where(near, catch, pump), -1.0, 1.0)[:, None]

    return policy
