"""PPO loss pieces as top-level pure functions.

Shapes: ``B`` samples, ``A`` action dims, ``T`` time steps, ``N`` environments.
Every sample carries a ``weight`` (1 = use, 0 = ignore); samples with weight 0
(steps whose physics diverged) are zeroed *before* use, so NaN/inf stored in
them can reach neither the loss nor its gradient.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct

_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


def gaussian_log_prob(mean: jax.Array, log_std: jax.Array, action: jax.Array) -> jax.Array:
    """Log-density of a diagonal Gaussian. ``(..., A) x3 -> (...)``."""
    z = (action - mean) * jnp.exp(-log_std)
    return jnp.sum(-0.5 * z**2 - log_std - _HALF_LOG_2PI, axis=-1)


def clipped_gaussian_log_prob(mean: jax.Array, log_std: jax.Array, action: jax.Array) -> jax.Array:
    """Log-probability of ``clip(action, -1, 1)`` under a diagonal Gaussian. ``(..., A) x3 -> (...)``.

    Clipped action policy gradient (Fujita & Maeda, ICML 2018): an entry at or
    beyond a bound counts with the Gaussian's mass beyond that bound, others
    with the density. Unbiased like the plain density, with less variance: a
    mean far outside the box gives a constant ~0, not noise.
    """
    std = jnp.exp(log_std)
    density = -0.5 * ((action - mean) / std) ** 2 - log_std - _HALF_LOG_2PI
    below = jax.scipy.special.log_ndtr((-1.0 - mean) / std)
    above = jax.scipy.special.log_ndtr((mean - 1.0) / std)
    return jnp.sum(jnp.where(action <= -1.0, below, jnp.where(action >= 1.0, above, density)), axis=-1)


def action_log_prob(clipped: bool, mean: jax.Array, log_std: jax.Array, action: jax.Array) -> jax.Array:
    """``clipped_gaussian_log_prob`` if ``clipped`` else ``gaussian_log_prob``."""
    return (clipped_gaussian_log_prob if clipped else gaussian_log_prob)(mean, log_std, action)


def gaussian_entropy(log_std: jax.Array) -> jax.Array:
    """Entropy of a diagonal Gaussian. ``(..., A) -> (...)``."""
    return jnp.sum(log_std + 0.5 + _HALF_LOG_2PI, axis=-1)


def gae(
    rewards: jax.Array,
    values: jax.Array,
    dones: jax.Array,
    last_value: jax.Array,
    gamma: float,
    lam: float,
) -> tuple[jax.Array, jax.Array]:
    """Generalised advantage estimation over a time-major rollout.

    Args:
        rewards: ``(T, N)`` rewards of each step.
        values: ``(T, N)`` the critic's values of each step's observation.
        dones: ``(T, N)``; ``dones[t]`` is True when step ``t`` ended its
            episode (then nothing is bootstrapped past it).
        last_value: ``(N,)`` value of the observation after step ``T-1``.

    Returns:
        ``(advantages, returns)``, both ``(T, N)``, with
        ``returns = advantages + values`` (the critic's regression target).
        For single-step episodes (all ``dones`` True) ``advantages = r - V``.
    """

    def backward(carry, step):
        next_advantage, next_value = carry
        reward, value, done = step
        not_done = 1.0 - done.astype(values.dtype)
        delta = reward + gamma * next_value * not_done - value
        advantage = delta + gamma * lam * not_done * next_advantage
        return (advantage, value), advantage

    init = (jnp.zeros_like(last_value), last_value)
    _, advantages = jax.lax.scan(backward, init, (rewards, values, dones), reverse=True)
    return advantages, advantages + values


@struct.dataclass
class Batch:
    """Flat training samples (leading axis ``B``) collected by the old policy."""

    obs: jax.Array  # (B, obs_size)
    action: jax.Array  # (B, A) unclipped Gaussian sample
    log_prob: jax.Array  # (B,) log-prob under the old policy
    value: jax.Array  # (B,) old critic value
    advantage: jax.Array  # (B,)
    target: jax.Array  # (B,) value target (GAE return)
    weight: jax.Array  # (B,) 1.0 valid, 0.0 masked out


def weighted_mean(x: jax.Array, weight: jax.Array) -> jax.Array:
    """``sum(w x) / sum(w)`` (0 when every weight is 0)."""
    return jnp.sum(weight * x) / jnp.maximum(jnp.sum(weight), 1e-8)


def ppo_loss(
    params,
    apply_fn: Callable,
    batch: Batch,
    clip_eps: float | jax.Array,
    vf_coef: float,
    ent_coef: float,
    normalize_advantages: bool,
    clip_value_loss: bool = False,
    clipped_actions: bool = False,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """Clipped-surrogate PPO loss ``policy + vf_coef*value - ent_coef*entropy``.

    ``apply_fn(params, obs) -> (mean, log_std, value)``. The value loss is
    ``0.5*(V - target)^2``; with ``clip_value_loss`` it is the elementwise max
    of that and the loss of ``V`` clipped to ``old_value +- clip_eps`` (PPO2
    style; off by default since it couples the value scale to the clip).
    ``approx_kl`` is the low-variance estimator ``E[(r - 1) - log r]``.
    All means are weighted by ``batch.weight``; advantage normalisation uses
    the weighted mean and std of the batch. ``clipped_actions``: log-probs of
    the clipped actions (``clipped_gaussian_log_prob``; ``batch.log_prob`` must
    be the same kind).
    """
    keep = batch.weight > 0
    weight = jnp.where(keep, batch.weight, 0.0)
    batch = jax.tree.map(
        lambda x: jnp.where(keep.reshape(keep.shape + (1,) * (x.ndim - 1)), x, 0), batch
    )
    mean, log_std, value = apply_fn(params, batch.obs)

    advantage = batch.advantage
    if normalize_advantages:
        centred = advantage - weighted_mean(advantage, weight)
        advantage = centred / (jnp.sqrt(weighted_mean(centred**2, weight)) + 1e-8)

    log_ratio = action_log_prob(clipped_actions, mean, log_std, batch.action) - batch.log_prob
    ratio = jnp.exp(log_ratio)
    surrogate = jnp.minimum(
        ratio * advantage, jnp.clip(ratio, 1.0 - clip_eps, 1.0 + clip_eps) * advantage
    )
    policy_loss = -weighted_mean(surrogate, weight)

    value_loss = 0.5 * (value - batch.target) ** 2
    if clip_value_loss:
        clipped = batch.value + jnp.clip(value - batch.value, -clip_eps, clip_eps)
        value_loss = jnp.maximum(value_loss, 0.5 * (clipped - batch.target) ** 2)
    value_loss = weighted_mean(value_loss, weight)

    entropy = weighted_mean(gaussian_entropy(log_std), weight)
    loss = policy_loss + vf_coef * value_loss - ent_coef * entropy
    outside_clip = (jnp.abs(ratio - 1.0) > clip_eps).astype(ratio.dtype)
    metrics = {
        "loss": loss,
        "policy_loss": policy_loss,
        "value_loss": value_loss,
        "entropy": entropy,
        "approx_kl": weighted_mean((ratio - 1.0) - log_ratio, weight),
        "clip_fraction": weighted_mean(outside_clip, weight),
    }
    return loss, metrics
