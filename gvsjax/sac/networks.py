"""The actor and the twin critics (flax.linen), and the tanh-squashed Gaussian they share.

Computation is float32 whatever ``jax_enable_x64`` says (gvsjax turns it on for the physics):
observations are cast on entry.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


class Trunk(nn.Module):
    """Dense (+ layer norm) + ReLU layers. ``(..., D) -> (..., hidden[-1])``."""

    hidden: Sequence[int]
    layer_norm: bool = True

    @nn.compact
    def __call__(self, x):
        for width in self.hidden:
            x = nn.Dense(width, kernel_init=nn.initializers.orthogonal(math.sqrt(2.0)))(x)
            x = nn.LayerNorm()(x) if self.layer_norm else x
            x = nn.relu(x)
        return x


class Actor(nn.Module):
    """``obs (..., O) -> (mean, log_std)`` of the Gaussian before the tanh, each ``(..., A)``;
    the log std clipped to ``[min_log_std, max_log_std]``."""

    action_size: int
    hidden: Sequence[int] = (256, 256, 256)
    layer_norm: bool = True
    min_log_std: float = -10.0
    max_log_std: float = 2.0

    @nn.compact
    def __call__(self, obs):
        x = Trunk(self.hidden, self.layer_norm)(obs.astype(jnp.float32))
        out = nn.Dense(2 * self.action_size, kernel_init=nn.initializers.orthogonal(0.01))(x)
        mean, log_std = jnp.split(out, 2, axis=-1)
        return mean, jnp.clip(log_std, self.min_log_std, self.max_log_std)


class TwinCritic(nn.Module):
    """``(obs (..., O), action (..., A)) -> Q (2, ...)``: two independent critics."""

    hidden: Sequence[int] = (256, 256, 256)
    layer_norm: bool = True

    @nn.compact
    def __call__(self, obs, action):
        x = jnp.concatenate([obs.astype(jnp.float32), action.astype(jnp.float32)], axis=-1)
        qs = [nn.Dense(1)(Trunk(self.hidden, self.layer_norm)(x))[..., 0] for _ in range(2)]
        return jnp.stack(qs)


def squashed_sample(mean: jax.Array, log_std: jax.Array, key: jax.Array) -> tuple[jax.Array, jax.Array]:
    """A sample ``tanh(mean + std eps)`` and its log-density (with the tanh's Jacobian).

    ``log(1 - tanh(u)^2) = 2 (log 2 - u - softplus(-2u))``: exact and finite for any u, where
    ``log(1 - a^2)`` loses everything once ``|a|`` rounds to 1. ``(..., A) -> (..., A), (...)``.
    """
    eps = jax.random.normal(key, mean.shape, mean.dtype)
    u = mean + jnp.exp(log_std) * eps
    log_prob = jnp.sum(-0.5 * eps**2 - log_std - _HALF_LOG_2PI, axis=-1)
    log_prob -= jnp.sum(2.0 * (math.log(2.0) - u - jax.nn.softplus(-2.0 * u)), axis=-1)
    return jnp.tanh(u), log_prob


def make_actor(config, action_size: int) -> Actor:
    """The actor a ``SACConfig`` describes; use its ``.init``/``.apply``."""
    return Actor(action_size, config.hidden, config.layer_norm, config.min_log_std, config.max_log_std)


def make_critic(config) -> TwinCritic:
    """The twin critics a ``SACConfig`` describes; use their ``.init``/``.apply``."""
    return TwinCritic(config.hidden, config.layer_norm)
