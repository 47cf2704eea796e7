"""SAC training as pure functions over an explicit state pytree.

    state = init(config, env, env_params, jax.random.PRNGKey(config.seed))
    state, metrics = iteration(config, env, env_params, state)   # num_envs env steps + gradient steps
    run = make_update(config, env, env_params, updates_per_call=K)
    state, metrics = run(state)                                 # K iterations, one jit call

One iteration steps every environment once (uniform random actions for the first
``learning_starts`` env steps, then samples of the policy), stores the transitions and takes
``updates_per_iteration`` gradient steps on minibatches drawn from the replay buffer. An episode
that ends by the task's time limit (``Environment.time_limit``) is bootstrapped through its last
step; one that terminates, or whose physics diverged, is not. A diverged step carries the task's
``failure_reward`` and is learned from (with ``failure_reward`` None it is stored but masked).
Every step also feeds the discounted returns of the last finished episodes
(``gvsjax.utils.episode_returns``), logged as ``train_*``.

The state's ``update`` counts iterations, as PPO's counts updates, so the command line drives both
alike. Numerics are float32, whatever the physics uses.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import optax
from flax import struct

from gvsjax.sac import losses, replay
from gvsjax.sac.config import SACConfig
from gvsjax.sac.networks import make_actor, make_critic, squashed_sample
from gvsjax.utils import episode_returns

PyTree = Any


@struct.dataclass
class SACState:
    """Everything that changes during training (a pytree; save it to resume)."""

    params: dict  # actor, critic, target (the critics' slow copy), log_alpha
    opt_state: dict  # actor, critic, alpha
    buffer: replay.Buffer
    env_state: PyTree  # batched over num_envs
    last_obs: jax.Array  # (N, obs_size) float32
    key: jax.Array
    update: jax.Array  # int32, iterations done
    episodes: jax.Array  # int32, episodes finished (diverged ones included)
    episode_return: jax.Array  # (N,) float32, return so far of each running episode
    gradient_steps: jax.Array  # int32
    running: episode_returns.Running  # (N,) discounted returns of the running episodes
    window: episode_returns.Window  # those of the last finished episodes


def num_updates(config: SACConfig, episode_length: int) -> int:
    """Iterations that spend ``total_episodes`` x ``episode_length`` env steps (rounded up)."""
    return max(1, math.ceil(config.total_episodes * episode_length / config.num_envs))


def _optimizer(config: SACConfig) -> optax.GradientTransformation:
    parts = [optax.clip_by_global_norm(config.max_grad_norm)] if math.isfinite(config.max_grad_norm) else []
    return optax.chain(*parts, optax.adam(config.learning_rate))


def init(config: SACConfig, env, env_params: PyTree, key: jax.Array) -> SACState:
    """Fresh networks, optimizers, an empty buffer and ``num_envs`` freshly reset environments."""
    key, k_actor, k_critic, k_reset = jax.random.split(key, 4)
    obs0 = jnp.zeros((env.obs_size,), jnp.float32)
    critic = make_critic(config).init(k_critic, obs0, jnp.zeros((env.action_size,), jnp.float32))
    params = {"actor": make_actor(config, env.action_size).init(k_actor, obs0), "critic": critic,
              "target": critic, "log_alpha": jnp.asarray(config.init_log_alpha, jnp.float32)}
    opt = _optimizer(config)
    obs, env_state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(k_reset, config.num_envs), env_params)
    return SACState(
        params=params,
        opt_state={"actor": opt.init(params["actor"]), "critic": opt.init(params["critic"]),
                   "alpha": opt.init(params["log_alpha"])},
        buffer=replay.empty(config.buffer_size, env.obs_size, env.action_size),
        env_state=env_state, last_obs=obs.astype(jnp.float32), key=key,
        update=jnp.zeros((), jnp.int32), episodes=jnp.zeros((), jnp.int32),
        episode_return=jnp.zeros((config.num_envs,), jnp.float32), gradient_steps=jnp.zeros((), jnp.int32),
        running=episode_returns.running(config.num_envs), window=episode_returns.window())


def _act_and_step(config: SACConfig, env, env_params, state: SACState, key: jax.Array):
    """Every env steps once: ``(state, transitions, episode metrics)``."""
    n = config.num_envs
    k_noise, k_uniform, k_env = jax.random.split(key, 3)
    out: Any = make_actor(config, env.action_size).apply(state.params["actor"], state.last_obs)
    mean, log_std = out
    action, _ = squashed_sample(mean, log_std, k_noise)
    explore = state.update * n < config.learning_starts
    action = jnp.where(explore, jax.random.uniform(k_uniform, action.shape, action.dtype, -1.0, 1.0), action)
    keys = jax.random.split(k_env, (n, 2))
    obs, env_state, reward, done, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
        keys[:, 0], state.env_state, action, env_params)
    obs_reset, state_reset = jax.vmap(env.reset, in_axes=(0, None))(keys[:, 1], env_params)
    valid = jnp.asarray(info.get("valid", jnp.ones((n,), bool)), bool)
    done = jnp.asarray(done, bool)
    ended = done | ~valid
    terminal = ~valid | (done & (not env.time_limit))
    learn_failures = env.failure_reward is not None
    reward = jnp.where(valid, reward, env.failure_reward if learn_failures else 0.0).astype(jnp.float32)
    obs = obs.astype(jnp.float32)
    batch = replay.Transitions(obs=state.last_obs, action=action, reward=reward,
                               discount=1.0 - terminal.astype(jnp.float32),
                               next_obs=jnp.where(valid[:, None], obs, 0.0),
                               valid=(valid | learn_failures).astype(jnp.float32))
    running, window = episode_returns.track(state.running, state.window, reward, ended, ~valid,
                                            jnp.zeros_like(ended), env.return_discount)
    episode_return = state.episode_return + reward
    completed = ended & (valid | learn_failures)  # a failed episode counts when its failure is scored
    count = jnp.sum(completed)
    mean_done = lambda x: jnp.where(count > 0, jnp.sum(jnp.where(completed, x, 0.0)) / jnp.maximum(count, 1),  # noqa: E731
                                    jnp.nan)
    metrics = {f"episode_{k}": mean_done(v.astype(jnp.float32)) for k, v in info.items()
               if jnp.issubdtype(v.dtype, jnp.floating) and v.shape == (n,)}
    metrics.update(episode_reward=mean_done(episode_return), episodes_completed=count.astype(jnp.int32),
                   invalid_steps=jnp.sum(~valid, dtype=jnp.int32), **episode_returns.window_metrics(window))
    restart = lambda r, s: jnp.where(ended.reshape((n,) + (1,) * (s.ndim - 1)), r, s)  # noqa: E731
    state = dataclasses.replace(
        state, env_state=jax.tree.map(restart, state_reset, env_state), last_obs=restart(obs_reset.astype(jnp.float32),
                                                                                         obs),
        episode_return=jnp.where(ended, 0.0, episode_return),
        episodes=state.episodes + jnp.sum(ended, dtype=jnp.int32), running=running, window=window)
    return state, batch, metrics


def gradient_step(config: SACConfig, action_size: int, params: dict, opt_state: dict, step: jax.Array,
                  batch: replay.Transitions, key: jax.Array) -> tuple[dict, dict, dict[str, jax.Array]]:
    """One step on each loss: the critics, then the actor against the updated critics, then the
    temperature; every ``target_update_period``-th step also moves the target critics."""
    actor, critic = make_actor(config, action_size).apply, make_critic(config).apply
    opt = _optimizer(config)
    k_target, k_actor = jax.random.split(key)
    alpha = jnp.exp(params["log_alpha"])
    target = losses.td_target(actor, critic, params["actor"], params["target"], alpha, batch, k_target,
                              config.gamma, config.entropy_reward)
    (c_loss, q_mean), grads = jax.value_and_grad(losses.critic_loss, has_aux=True)(
        params["critic"], critic, batch, target)
    updates, c_opt = opt.update(grads, opt_state["critic"], params["critic"])
    critic_params = optax.apply_updates(params["critic"], updates)
    (a_loss, log_prob), grads = jax.value_and_grad(losses.actor_loss, has_aux=True)(
        params["actor"], actor, critic, critic_params, alpha, batch, k_actor)
    updates, a_opt = opt.update(grads, opt_state["actor"], params["actor"])
    actor_params = optax.apply_updates(params["actor"], updates)
    entropy_target = config.target_entropy_per_dim * action_size
    al_loss, grad = jax.value_and_grad(losses.alpha_loss)(params["log_alpha"], log_prob, batch.valid, entropy_target)
    updates, al_opt = opt.update(grad, opt_state["alpha"], params["log_alpha"])
    move = (step + 1) % config.target_update_period == 0
    target_params = jax.tree.map(lambda t, c: jnp.where(move, t + config.tau * (c - t), t),
                                 params["target"], critic_params)
    params = {"actor": actor_params, "critic": critic_params, "target": target_params,
              "log_alpha": optax.apply_updates(params["log_alpha"], updates)}
    metrics = {"critic_loss": c_loss, "actor_loss": a_loss, "alpha_loss": al_loss, "q": q_mean,
               "entropy": -losses.weighted_mean(log_prob, batch.valid), "alpha": alpha}
    return params, {"actor": a_opt, "critic": c_opt, "alpha": al_opt}, metrics


_LOSS_KEYS = ("critic_loss", "actor_loss", "alpha_loss", "q", "entropy", "alpha")


def iteration(config: SACConfig, env, env_params: PyTree, state: SACState) -> tuple[SACState, dict[str, jax.Array]]:
    """``num_envs`` env steps, then ``updates_per_iteration`` gradient steps once ``learning_starts``
    env steps are stored. Returns scalar metrics: the loss terms (means over this iteration's
    gradient steps; 0 before learning starts), the episode metrics of the steps, ``update`` (this
    iteration's index), ``episodes`` (total so far), ``gradient_steps`` (total so far)."""
    index = state.update
    key, k_step, k_updates = jax.random.split(state.key, 3)
    state, batch, metrics = _act_and_step(config, env, env_params, state, k_step)
    buffer = replay.add(state.buffer, batch)
    ready = ((index + 1) * config.num_envs >= config.learning_starts) & (config.updates_per_iteration > 0)

    def learn(carry):
        def one(c, k):
            params, opt_state, step = c
            k_sample, k_step = jax.random.split(k)
            params, opt_state, m = gradient_step(config, env.action_size, params, opt_state, step,
                                                 replay.sample(buffer, k_sample, config.batch_size), k_step)
            return (params, opt_state, step + 1), m

        carry, m = jax.lax.scan(one, carry, jax.random.split(k_updates, max(config.updates_per_iteration, 1)))
        return carry, {k: jnp.mean(m[k]) for k in _LOSS_KEYS}

    def wait(carry):
        return carry, {k: jnp.zeros((), jnp.float32) for k in _LOSS_KEYS}

    (params, opt_state, steps), loss_metrics = jax.lax.cond(
        ready, learn, wait, (state.params, state.opt_state, state.gradient_steps))
    state = dataclasses.replace(state, params=params, opt_state=opt_state, buffer=buffer, key=key,
                                update=index + 1, gradient_steps=steps)
    metrics.update(loss_metrics, update=index, episodes=state.episodes, gradient_steps=steps)
    return state, metrics


def make_update(config: SACConfig, env, env_params: PyTree,
                updates_per_call: int = 1) -> Callable[[SACState], tuple[SACState, dict[str, jax.Array]]]:
    """A jitted ``state -> (state, metrics)`` running ``updates_per_call`` iterations in one scan.

    Metrics are stacked with leading axis ``updates_per_call``; iterations past ``num_updates``
    are skipped (state unchanged, float metrics NaN, integer ones -1), as in ``gvsjax.ppo``.
    """
    total = num_updates(config, env.episode_length)
    one = jax.jit(lambda s: iteration(config, env, env_params, s))

    def skipped(s):
        fill = lambda x: jnp.full(x.shape, jnp.nan if jnp.issubdtype(x.dtype, jnp.floating) else -1, x.dtype)  # noqa: E731
        return s, jax.tree.map(fill, jax.eval_shape(one, s)[1])

    @jax.jit
    def run(state):
        return jax.lax.scan(lambda s, _: jax.lax.cond(s.update < total, one, skipped, s), state, None,
                            length=updates_per_call)

    return run


def policy_action(actor_params: PyTree, apply_fn: Callable, obs: jax.Array) -> jax.Array:
    """The deterministic policy: ``tanh`` of the Gaussian's mean. ``(..., O) -> (..., A)``."""
    mean, _ = apply_fn(actor_params, obs.astype(jnp.float32))
    return jnp.tanh(mean)
