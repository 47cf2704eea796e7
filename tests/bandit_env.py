"""Test-only contextual bandit: a ``gvsjax.tasks.Environment`` without physics.

Each step shows a random target ``t`` in [-1, 1]^2; the best action is
``M t`` (inside [-1, 1]^2 since each row of ``M`` has absolute sum < 1) and
the reward is ``exp(-3 |a - M t|)`` with ``info["cost"] = |a - M t|``.
With ``episode_length=2`` the observation also carries the step index
(0 or 1) and a fresh target is drawn after the first step.
With ``invalid_prob > 0`` a step "diverges" at random: ``info["valid"]`` is
False, the episode ends and reward and cost are NaN, like a blown-up physics
step.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from gvsjax.tasks import Environment

MATRIX = ((0.6, -0.3), (0.2, 0.5))


@struct.dataclass
class BanditState:
    target: jax.Array  # (2,)
    step: jax.Array  # int32


class BanditEnv(Environment):
    name = "bandit"
    action_size = 2

    def __init__(self, episode_length: int = 1, invalid_prob: float = 0.0):
        self.episode_length = episode_length
        self.invalid_prob = invalid_prob
        self.obs_size = 2 if episode_length == 1 else 3

    def default_params(self):
        return {"matrix": jnp.asarray(MATRIX, jnp.float32)}

    def _obs(self, state):
        if self.episode_length == 1:
            return state.target
        return jnp.append(state.target, state.step.astype(jnp.float32))

    def reset(self, key, params):
        state = BanditState(
            target=jax.random.uniform(key, (2,), jnp.float32, -1.0, 1.0),
            step=jnp.zeros((), jnp.int32),
        )
        return self._obs(state), state

    def step(self, key, state, action, params):
        key_target, key_valid = jax.random.split(key)
        action = jnp.clip(action, -1.0, 1.0)
        cost = jnp.linalg.norm(action - params["matrix"] @ state.target)
        valid = jax.random.uniform(key_valid) >= self.invalid_prob
        reward = jnp.where(valid, jnp.exp(-3.0 * cost), jnp.nan)
        cost = jnp.where(valid, cost, jnp.nan)
        step = state.step + 1
        done = (step >= self.episode_length) | ~valid
        state = BanditState(
            target=jax.random.uniform(key_target, (2,), jnp.float32, -1.0, 1.0), step=step
        )
        info = {"cost": cost, "valid": valid, "truncated": jnp.zeros((), bool)}
        return self._obs(state), state, reward, done, info
