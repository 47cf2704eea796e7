"""Gaussian actor-critic networks (flax.linen).

Both networks map observations ``(..., obs_size)`` to ``(mean, log_std, value)``
with shapes ``(..., A)``, ``(..., A)``, ``(...)``. The mean is *linear* (not
tanh-squashed): the environment clips actions to [-1, 1], and the log-prob is
that of the unclipped Gaussian sample, as in PureJaxRL/CleanRL.

Computation is float32 regardless of ``jax_enable_x64`` (which gvsjax turns on
for the physics): observations are cast on entry.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import flax.linen as nn
import jax.numpy as jnp

from gvsjax.ppo.config import PPOConfig

_ACTIVATIONS = {"relu": nn.relu, "tanh": nn.tanh}


def _dense(features: int, scale: float, bias: float = 0.0) -> nn.Dense:
    return nn.Dense(
        features,
        kernel_init=nn.initializers.orthogonal(scale),
        bias_init=nn.initializers.constant(bias),
    )


class MLP(nn.Module):
    """Dense + activation layers, orthogonal(sqrt 2) init. ``(..., D) -> (..., hidden[-1])``."""

    hidden: Sequence[int]
    activation: str = "relu"

    @nn.compact
    def __call__(self, x):
        act = _ACTIVATIONS[self.activation]
        for width in self.hidden:
            x = act(_dense(width, math.sqrt(2.0))(x))
        return x


class GaussianHead(nn.Module):
    """Mean (orthogonal 0.01 init) and log-std per action dimension.

    ``std_mode="learned"``: one state-independent log-std parameter per action
    dim; ``"network"``: a dense head (state-dependent std, as MATLAB). Either
    way the log-std starts at ``init_log_std`` and is floored at ``min_log_std``.
    """

    action_size: int
    std_mode: str = "learned"
    init_log_std: float = -0.5
    min_log_std: float = -5.0

    @nn.compact
    def __call__(self, x):
        mean = _dense(self.action_size, 0.01)(x)
        if self.std_mode == "learned":
            log_std = self.param(
                "log_std",
                nn.initializers.constant(self.init_log_std),
                (self.action_size,),
                jnp.float32,
            )
            log_std = jnp.broadcast_to(log_std, mean.shape)
        else:
            log_std = _dense(self.action_size, 0.01, self.init_log_std)(x)
        return mean, jnp.maximum(log_std, self.min_log_std)


def _value_head(x):
    return _dense(1, 1.0)(x)[..., 0]


class SharedActorCritic(nn.Module):
    """One trunk feeding a Gaussian actor head and a linear critic head."""

    action_size: int
    hidden: Sequence[int] = (128, 32, 16)
    activation: str = "relu"
    std_mode: str = "learned"
    init_log_std: float = -0.5
    min_log_std: float = -5.0

    @nn.compact
    def __call__(self, obs):
        x = MLP(self.hidden, self.activation)(obs.astype(jnp.float32))
        mean, log_std = GaussianHead(
            self.action_size, self.std_mode, self.init_log_std, self.min_log_std
        )(x)
        return mean, log_std, _value_head(x)


class SeparateActorCritic(nn.Module):
    """Independent actor and critic MLPs (no shared features)."""

    action_size: int
    actor_hidden: Sequence[int] = (128, 32)
    critic_hidden: Sequence[int] = (128, 32)
    activation: str = "relu"
    std_mode: str = "learned"
    init_log_std: float = -0.5
    min_log_std: float = -5.0

    @nn.compact
    def __call__(self, obs):
        obs = obs.astype(jnp.float32)
        actor = MLP(self.actor_hidden, self.activation)(obs)
        mean, log_std = GaussianHead(
            self.action_size, self.std_mode, self.init_log_std, self.min_log_std
        )(actor)
        critic = MLP(self.critic_hidden, self.activation)(obs)
        return mean, log_std, _value_head(critic)


def obs_size(params: Any) -> int | None:
    """The observation width ``params`` of either network were initialised for, read
    from the first trunk layer's kernel; None for a parameter tree of another shape."""
    try:
        return int(params["params"]["MLP_0"]["Dense_0"]["kernel"].shape[0])
    except (KeyError, TypeError, AttributeError, IndexError):
        return None


def make_network(config: PPOConfig, action_size: int) -> nn.Module:
    """The actor-critic selected by ``config.network``; use its ``.init``/``.apply``."""
    common: dict[str, Any] = dict(
        action_size=action_size,
        activation=config.activation,
        std_mode=config.std_mode,
        init_log_std=config.init_log_std,
        min_log_std=config.min_log_std,
    )
    if config.network == "shared":
        return SharedActorCritic(hidden=config.shared_hidden, **common)
    return SeparateActorCritic(
        actor_hidden=config.actor_hidden, critic_hidden=config.critic_hidden, **common
    )
