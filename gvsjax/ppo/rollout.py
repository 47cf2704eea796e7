"""Collecting experience: the training state, the rollout of the stochastic policy over
``num_envs`` auto-resetting environments, its episode metrics, and the policy's action.

With ``antithetic`` env i and i + num_envs/2 share their reset keys and play mirrored
action noise; with several devices the env axis is split over them (``gvsjax.utils.sharding``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import chex
import jax
import jax.numpy as jnp
import optax
from flax import struct

from gvsjax.ppo.config import PPOConfig
from gvsjax.ppo.losses import action_log_prob
from gvsjax.ppo.networks import make_network, obs_size
from gvsjax.tasks.base import auto_reset_step
from gvsjax.utils import episode_returns, sharding

PyTree = Any


@struct.dataclass
class TrainState:
    """Everything that changes during training (a pytree; save it to resume)."""

    params: PyTree
    opt_state: optax.OptState
    env_state: PyTree  # batched over num_envs
    last_obs: jax.Array  # (N, obs_size) float32
    key: jax.Array
    update: jax.Array  # int32, number of updates done
    episodes: jax.Array  # int32, episodes finished (diverged ones included)
    episode_return: jax.Array  # (N,) float32, return so far of each running episode
    cut_at: jax.Array  # (N,) int32, steps left before the running episode is cut (< 0: never)
    running: episode_returns.Running  # (N,) discounted returns of the running episodes
    window: episode_returns.Window  # those of the last finished episodes


@struct.dataclass
class Rollout:
    """A rollout, time-major ``(T, N, ...)``."""

    obs: jax.Array  # (T, N, obs_size) observation the action was taken from
    action: jax.Array  # (T, N, A) unclipped sample
    log_prob: jax.Array  # (T, N)
    value: jax.Array  # (T, N)
    reward: jax.Array  # (T, N), the task's failure_reward (or 0) where invalid
    done: jax.Array  # (T, N) bool, episode ended (True also where invalid or cut)
    cut: jax.Array  # (T, N) bool, the episode was cut short by ``stagger_starts``
    valid: jax.Array  # (T, N) bool, physics did not diverge
    learn: jax.Array  # (T, N) bool, the step weighs in the loss (valid, or a scored failure)
    episode_return: jax.Array  # (T, N) return of the episode ending here, else 0
    info: dict[str, jax.Array]  # float (T, N) entries of the env's info


def env_keys(config: PPOConfig, key: jax.Array) -> jax.Array:
    """One key per env; with ``antithetic`` env i and i + num_envs/2 get the same key."""
    if not config.antithetic:
        return jax.random.split(key, config.num_envs)
    return pair_up(jax.random.split(key, config.num_envs // 2))


def pair_up(half: jax.Array) -> jax.Array:
    """``(N/2, ...)`` -> ``(N, ...)``: env i and i + N/2 get the same entry (antithetic pairs)."""
    return jnp.concatenate([half, half])


def _noise(config: PPOConfig, key: jax.Array, shape: tuple, dtype) -> jax.Array:
    """Standard normal action noise (N, A); with ``antithetic`` the second half is -(first half)."""
    if not config.antithetic:
        return jax.random.normal(key, shape, dtype)
    eps = jax.random.normal(key, (shape[0] // 2,) + shape[1:], dtype)
    return jnp.concatenate([eps, -eps])


def shardings(config: PPOConfig):
    """(env-batch sharding, replicated sharding); both None on one device."""
    mesh = sharding.mesh_for(config.num_envs)
    return sharding.batch_spec(mesh), sharding.replicated(mesh)


# TrainState fields batched over num_envs; the others are the same on every device
_ENV_FIELDS = ("env_state", "last_obs", "episode_return", "cut_at", "running")


def place(config: PPOConfig, state: TrainState) -> TrainState:
    """A whole process-local ``state`` (from ``init`` under ``sharding.unsharded()``, or a
    checkpoint) laid out for training: env axis split over the mesh, the rest replicated.

    With several processes each keeps its own devices' envs. One device: ``state``.
    """
    envs, everywhere = shardings(config)
    return dataclasses.replace(state, **{
        f.name: sharding.put(getattr(state, f.name), envs if f.name in _ENV_FIELDS else everywhere)
        for f in dataclasses.fields(state)})


def collect(
    config: PPOConfig, env, env_params: PyTree, state: TrainState
) -> tuple[TrainState, Rollout]:
    """Roll the stochastic policy for ``num_steps`` steps in every env (auto-reset).

    A step with ``info["valid"] == False`` is terminal with the task's
    ``failure_reward`` and learned from; with ``failure_reward`` None its reward
    is 0 (the raw reward may be NaN) and it is masked out of the loss downstream.
    The env must itself report ``done`` on such a step (base.py's contract) so
    that ``auto_reset_step`` replaces the diverged state. Every step also feeds
    the discounted returns of the finished episodes (``state.window``).
    """
    # flax types apply() as maybe returning (output, mutated variables) too; without
    # mutable= it returns the output: (mean, log_std, value)
    apply_fn: Callable[..., Any] = make_network(config, env.action_size).apply
    n = config.num_envs
    envs, _ = shardings(config)
    # each device steps its own slice of the envs (no-op on one device)
    env_step = sharding.split_batch(jax.vmap(auto_reset_step(env), in_axes=(0, 0, 0, None, 0)),
                                    envs and envs.mesh, (0, 0, 0, None, 0))

    learn_failures = env.failure_reward is not None

    def one_step(carry, keys):  # keys: (n + 1,) = action key, one key per env
        per_env, window = carry
        env_state, obs, episode_return, cut_at, running = sharding.constrain(per_env, envs)  # env axis split
        mean, log_std, value = apply_fn(state.params, obs)
        action = mean + jnp.exp(log_std) * _noise(config, keys[0], mean.shape, mean.dtype)
        env_keys = pair_up(keys[1:n // 2 + 1]) if config.antithetic else keys[1:]
        cut = cut_at == 1
        next_obs, env_state, reward, done, info = env_step(env_keys, env_state, action, env_params, cut)
        valid = jnp.asarray(info.get("valid", jnp.ones((n,), bool)), bool)
        ended = jnp.asarray(done, bool) | ~valid
        cut = cut & ~ended
        done = ended | cut
        cut_at = jnp.where(done | (cut_at < 0), -1, cut_at - 1)
        reward = jnp.where(valid, reward, env.failure_reward if learn_failures else 0.0).astype(jnp.float32)
        episode_return = episode_return + reward
        running, window = episode_returns.track(running, window, reward, ended, ~valid, cut, env.return_discount)
        floats = {
            k: v.astype(jnp.float32)
            for k, v in info.items()
            if jnp.issubdtype(v.dtype, jnp.floating) and v.shape == (n,)
        }
        step = Rollout(
            obs=obs,
            action=action,
            log_prob=action_log_prob(config.clipped_log_prob, mean, log_std, action),
            value=value,
            reward=reward,
            done=done,
            cut=cut,
            valid=valid,
            learn=valid | learn_failures,
            episode_return=jnp.where(ended, episode_return, 0.0),
            info=floats,
        )
        carry = (env_state, next_obs.astype(jnp.float32), jnp.where(done, 0.0, episode_return), cut_at, running)
        return (carry, window), step

    key, key_steps = jax.random.split(state.key)
    ((env_state, obs, episode_return, cut_at, running), window), trajectory = jax.lax.scan(
        one_step,
        ((state.env_state, state.last_obs, state.episode_return, state.cut_at, state.running), state.window),
        # all keys split up front: each random call inside the scan costs compile time
        jax.random.split(key_steps, (config.num_steps, n + 1)),
    )
    state = dataclasses.replace(
        state,
        env_state=env_state,
        last_obs=obs,
        key=key,
        episode_return=episode_return,
        cut_at=cut_at,
        running=running,
        window=window,
        episodes=state.episodes + jnp.sum(trajectory.done & ~trajectory.cut, dtype=jnp.int32),
    )
    return state, trajectory


def episode_metrics(trajectory: Rollout) -> dict[str, jax.Array]:
    """Means over episodes that *completed* in this rollout (NaN if none): validly, or by a
    failure the task scores (``failure_reward``); an episode cut short by ``stagger_starts``
    does not count.

    ``episode_reward`` is the undiscounted return; ``episode_<k>`` is scalar
    float info entry ``k`` at the episode's last step (e.g. ``episode_cost``;
    an info entry named ``reward`` would be shadowed by the return).
    ``episodes_completed`` counts those episodes, ``invalid_steps`` the
    diverged steps (each also ended an episode).
    """
    completed = trajectory.done & trajectory.learn & ~trajectory.cut
    count = jnp.sum(completed)

    def mean_over_completed(x):
        total = jnp.sum(jnp.where(completed, x, 0.0))
        return jnp.where(count > 0, total / jnp.maximum(count, 1), jnp.nan)

    metrics = {f"episode_{k}": mean_over_completed(v) for k, v in trajectory.info.items()}
    metrics["episode_reward"] = mean_over_completed(trajectory.episode_return)
    metrics["episodes_completed"] = count.astype(jnp.int32)
    metrics["invalid_steps"] = jnp.sum(~trajectory.valid, dtype=jnp.int32)
    return metrics


def policy_action(
    params: PyTree,
    apply_fn: Callable,
    obs: jax.Array,
    deterministic: bool = True,
    key: jax.Array | None = None,
) -> jax.Array:
    """Action in [-1, 1] for ``obs`` ``(..., obs_size)``: the clipped mean, or a clipped sample.

    ``apply_fn`` is ``make_network(config, env.action_size).apply``; ``key`` is
    required when ``deterministic`` is False.
    """
    if not deterministic and key is None:
        raise ValueError("key=None is invalid: expected a PRNG key when deterministic=False")
    width = obs_size(params)
    if width is not None:  # trace-time check: an obs of another task names both widths
        chex.assert_shape(obs, (..., width), custom_message=f"obs must be (..., obs_size={width}), "
                          "the width the policy params were initialised for")
    mean, log_std, _ = apply_fn(params, obs)
    if not deterministic and key is not None:
        mean = mean + jnp.exp(log_std) * jax.random.normal(key, mean.shape, mean.dtype)
    return jnp.clip(mean, -1.0, 1.0)
