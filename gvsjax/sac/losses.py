"""SAC's three losses as pure functions (Haarnoja et al. 2018, "Soft Actor-Critic Algorithms
and Applications"): the twin critics' TD error, the actor's entropy-regularised value and the
temperature's entropy constraint.

Every transition carries ``valid`` (1 = use; 0 = the physics diverged in a task without a
``failure_reward``): invalid ones are zeroed before use, so NaN stored in them reaches neither a
loss nor its gradient.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from gvsjax.sac.networks import squashed_sample
from gvsjax.sac.replay import Transitions


def weighted_mean(x: jax.Array, weight: jax.Array) -> jax.Array:
    return jnp.sum(jnp.where(weight > 0, x, 0.0) * weight) / jnp.maximum(jnp.sum(weight), 1.0)


def td_target(actor: Callable, critic: Callable, actor_params, target_params, alpha: jax.Array,
              batch: Transitions, key: jax.Array, gamma: float, entropy_reward: bool) -> jax.Array:
    """``r + gamma d min_i Q'_i(s', a')`` with ``a' ~ pi(s')`` (minus ``alpha log pi(a'|s')``
    inside with ``entropy_reward``); no gradient flows through it."""
    next_obs = jnp.where(batch.valid[..., None] > 0, batch.next_obs, 0.0)
    mean, log_std = actor(actor_params, next_obs)
    next_action, next_log_prob = squashed_sample(mean, log_std, key)
    next_q = jnp.min(critic(target_params, next_obs, next_action), axis=0)
    if entropy_reward:
        next_q = next_q - alpha * next_log_prob
    reward = jnp.where(batch.valid > 0, batch.reward, 0.0)
    return jax.lax.stop_gradient(reward + gamma * batch.discount * next_q)


def critic_loss(critic_params, critic: Callable, batch: Transitions, target: jax.Array):
    """Both critics' squared TD errors, summed over the critics; aux: the mean Q."""
    obs = jnp.where(batch.valid[..., None] > 0, batch.obs, 0.0)
    q = critic(critic_params, obs, batch.action)  # (2, B)
    loss = weighted_mean(jnp.sum((q - target) ** 2, axis=0), batch.valid)
    return loss, weighted_mean(jnp.mean(q, axis=0), batch.valid)


def actor_loss(actor_params, actor: Callable, critic: Callable, critic_params, alpha: jax.Array,
               batch: Transitions, key: jax.Array):
    """``E[alpha log pi(a|s) - min_i Q_i(s, a)]``, ``a ~ pi(s)`` reparameterised; aux: log pi."""
    obs = jnp.where(batch.valid[..., None] > 0, batch.obs, 0.0)
    mean, log_std = actor(actor_params, obs)
    action, log_prob = squashed_sample(mean, log_std, key)
    q = jnp.min(critic(critic_params, obs, action), axis=0)
    return weighted_mean(alpha * log_prob - q, batch.valid), log_prob


def alpha_loss(log_alpha: jax.Array, log_prob: jax.Array, valid: jax.Array, target_entropy: float) -> jax.Array:
    """The temperature rises while the policy's entropy is below ``target_entropy``."""
    return -log_alpha * weighted_mean(jax.lax.stop_gradient(log_prob) + target_entropy, valid)
