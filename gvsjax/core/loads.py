"""Distributed loads for ``Robot.distributed``: per-metre wrenches in the section's frame.

Each helper returns ``f(X, R, p, eta, t) -> (6,)`` (moment N m/m, force N/m),
with X the material coordinate, R and p the section's world pose and eta its
body twist (angular, linear).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import jax.numpy as jnp


def uniform_force(force_per_length: Sequence[float]) -> Callable:
    """A world-fixed force per metre (e.g. buoyancy: rho_fluid A g upwards)."""
    f = jnp.asarray(force_per_length, dtype=float)

    def load(X, R, p, eta, t):
        return jnp.concatenate([jnp.zeros(3), R.T @ f])

    return load


def viscous_drag(normal: float, tangential: float = 0.0) -> Callable:
    """Linear drag opposing the section's velocity: -c_n v_normal - c_t v_tangential (N s/m^2)."""

    def load(X, R, p, eta, t):
        v = eta[3:]  # body frame; local x is the centreline tangent
        drag = -jnp.array([tangential, normal, normal]) * v
        return jnp.concatenate([jnp.zeros(3), drag])

    return load


def combined(*loads: Callable) -> Callable:
    """The sum of several distributed loads."""

    def load(X, R, p, eta, t):
        return sum(f(X, R, p, eta, t) for f in loads)

    return load
