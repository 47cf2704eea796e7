"""A uniform replay buffer as a pytree of fixed-size arrays (jit-friendly, checkpointable)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class Transitions:
    """A batch of transitions ``(..., ...)``. ``discount`` is 0 where the episode terminated
    (1 where it goes on, or was stopped by a time limit); ``valid`` is 0 where the physics
    diverged in a task without a ``failure_reward``: such a transition is stored but weighs nothing
    in a loss (with one, it is a terminal transition with that reward, and valid)."""

    obs: jax.Array  # (..., O) float32
    action: jax.Array  # (..., A) float32, in [-1, 1]
    reward: jax.Array  # (...,) float32
    discount: jax.Array  # (...,) float32
    next_obs: jax.Array  # (..., O) float32, the step's own observation (before any reset)
    valid: jax.Array  # (...,) float32


@struct.dataclass
class Buffer:
    """Transitions in a ring of fixed capacity: ``position`` is the next slot, ``count`` how many
    slots hold data."""

    data: Transitions  # leading axis: capacity
    position: jax.Array  # int32, where the next transition goes
    count: jax.Array  # int32, transitions held (<= capacity)


def empty(capacity: int, obs_size: int, action_size: int) -> Buffer:
    z = lambda *s: jnp.zeros((capacity, *s), jnp.float32)  # noqa: E731
    data = Transitions(z(obs_size), z(action_size), z(), z(), z(obs_size), z())
    return Buffer(data, jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32))


def add(buffer: Buffer, batch: Transitions) -> Buffer:
    """Append ``batch`` (leading axis n <= capacity), overwriting the oldest transitions."""
    capacity = buffer.data.reward.shape[0]
    n = batch.reward.shape[0]
    index = (buffer.position + jnp.arange(n)) % capacity
    data = jax.tree.map(lambda store, x: store.at[index].set(x.astype(store.dtype)), buffer.data, batch)
    return Buffer(data, (buffer.position + n) % capacity, jnp.minimum(buffer.count + n, capacity))


def sample(buffer: Buffer, key: jax.Array, n: int) -> Transitions:
    """``n`` transitions drawn uniformly, with replacement, from those held."""
    index = jax.random.randint(key, (n,), 0, jnp.maximum(buffer.count, 1))
    return jax.tree.map(lambda x: x[index], buffer.data)
