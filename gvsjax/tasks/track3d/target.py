"""The moving target: constant speed, random direction changes, reflected by the box's walls."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from gvsjax.tasks.track3d.params import Track3DParams


def random_direction(key: jax.Array) -> jax.Array:
    """A unit 3-vector uniform on the sphere."""
    v = jax.random.normal(key, (3,))
    return v / jnp.linalg.norm(v)


def start(key: jax.Array, params: Track3DParams) -> tuple[jax.Array, jax.Array]:
    """(position uniform in the box, velocity of ``speed`` in a uniform direction)."""
    k_pos, k_dir = jax.random.split(key)
    low, high = jnp.asarray(params.box_low), jnp.asarray(params.box_high)
    return jax.random.uniform(k_pos, (3,), minval=low, maxval=high), params.speed * random_direction(k_dir)


def move(key: jax.Array, position: jax.Array, velocity: jax.Array, params: Track3DParams):
    """One control step: maybe turn (probability ``turn_probability``), then move ``velocity * control_dt``,
    reflecting off the walls (each wall flips its velocity component). Returns (position, velocity)."""
    k_turn, k_dir = jax.random.split(key)
    turn = jax.random.uniform(k_turn) < params.turn_probability
    velocity = jnp.where(turn, params.speed * random_direction(k_dir), velocity)
    low, high = jnp.asarray(params.box_low), jnp.asarray(params.box_high)
    p = position + velocity * params.arm.control_dt
    below, above = p < low, p > high
    p = jnp.where(below, 2 * low - p, jnp.where(above, 2 * high - p, p))
    velocity = jnp.where(below | above, -velocity, velocity)
    return jnp.clip(p, low, high), velocity
