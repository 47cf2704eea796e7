"""PPO training as flat pure functions over explicit state pytrees.

    state = init(config, env, env_params, jax.random.PRNGKey(config.seed))
    state, metrics = update(config, env, env_params, state)   # one PPO update
    run = make_update(config, env, env_params, updates_per_call=K)
    state, metrics = run(state)                              # K updates, one jit call
    state, metrics = make_train(config, env, env_params)(key)  # whole run, vmappable

Budget: one update collects ``num_envs * num_steps`` env steps, i.e.
``num_envs * num_steps / episode_length`` episodes, so
``num_updates = ceil(total_episodes * episode_length / (num_envs * num_steps))``.
The last ``round(finetune_fraction * num_updates)`` updates are phase 2
(fine-tuning). Learning rate and clip are *traced* functions of the update
index, so the phase switch never recompiles.

Numerics are float32 (observations and rewards are cast), whatever the
physics uses.

Scale-out (``gvsjax.utils.sharding``): with several JAX devices the ``num_envs``
axis of the env state, observations and rollout is split over a mesh of the
devices (as many as divide ``num_envs``) and the network is replicated; the
rollout batch is gathered onto every device before the minibatch shuffle, so
the PPO update itself is the single-device computation. One device: no-op.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import optax

from gvsjax.ppo.config import PPOConfig
from gvsjax.ppo.losses import Batch, gae, ppo_loss
from gvsjax.ppo.networks import make_network
from gvsjax.ppo.rollout import TrainState, collect, env_keys, episode_metrics, pair_up, shardings
from gvsjax.utils import episode_returns, sharding

PyTree = Any


def num_updates(config: PPOConfig, episode_length: int) -> int:
    """Updates needed to spend ``total_episodes`` (rounded up)."""
    steps_per_update = config.num_envs * config.num_steps
    return max(1, math.ceil(config.total_episodes * episode_length / steps_per_update))


def finetune_start(config: PPOConfig, episode_length: int) -> int:
    """Index of the first phase-2 update (== num_updates when there is no phase 2)."""
    n = num_updates(config, episode_length)
    return n - round(config.finetune_fraction * n)


def phase_hyperparams(
    config: PPOConfig, episode_length: int, update: jax.Array,
    learning_rate: jax.Array | None = None,
) -> tuple[jax.Array, jax.Array]:
    """Traced ``(learning_rate, clip_eps)`` for update index ``update``.

    Phase 1 uses ``learning_rate``/``clip_eps``, phase 2 the ``finetune_``
    values; with ``anneal_lr`` the phase's rate is scaled by
    ``1 - update / num_updates`` (linear to 0 over the whole run).
    A given ``learning_rate`` (may be traced, e.g. vmapped in a sweep)
    replaces ``config.learning_rate`` for phase 1.
    """
    finetune = update >= finetune_start(config, episode_length)
    base = config.learning_rate if learning_rate is None else learning_rate
    lr = jnp.where(finetune, config.finetune_learning_rate, base)
    if config.anneal_lr:
        lr = lr * (1.0 - update / num_updates(config, episode_length))
    clip_eps = jnp.where(finetune, config.finetune_clip_eps, config.clip_eps)
    return lr.astype(jnp.float32), clip_eps.astype(jnp.float32)


def adapt_learning_rate(lr: jax.Array, kl: jax.Array, target: float) -> jax.Array:
    """The next update's rate: / 1.5 after KL > 2 target, x 1.5 after KL < target / 2 (>= 1e-7)."""
    factor = jnp.where(kl > 2.0 * target, 1.0 / 1.5, jnp.where(kl < 0.5 * target, 1.5, 1.0))
    return jnp.maximum(lr * factor, 1e-7).astype(jnp.float32)


def make_optimizer(config: PPOConfig) -> optax.GradientTransformation:
    """Global-norm clip, optional L2, Adam; the learning rate is an injected hyperparameter."""

    def chain(learning_rate):
        parts = [optax.clip_by_global_norm(config.max_grad_norm)]
        if config.l2_coef:
            parts.append(optax.add_decayed_weights(config.l2_coef))
        parts.append(optax.adam(learning_rate, eps=1e-5))
        return optax.chain(*parts)

    return optax.inject_hyperparams(chain, hyperparam_dtype=jnp.float32)(
        learning_rate=config.learning_rate
    )


def init(config: PPOConfig, env, env_params: PyTree, key: jax.Array) -> TrainState:
    """Fresh network, optimizer and ``num_envs`` freshly reset environments."""
    envs, everywhere = shardings(config)
    key, key_net, key_reset = jax.random.split(key, 3)
    network = make_network(config, env.action_size)
    params = network.init(key_net, jnp.zeros((env.obs_size,), jnp.float32))
    params = sharding.constrain(params, everywhere)
    obs, env_state = jax.vmap(env.reset, in_axes=(0, None))(
        env_keys(config, key_reset), env_params
    )
    # the cut of each env's first episode: a step in [1, episode_length] (-1: none)
    cut_at = jnp.full((config.num_envs,), -1, jnp.int32)
    if config.stagger_starts:
        cut_at = jax.random.randint(jax.random.fold_in(key_reset, 1), (config.num_envs,), 1,
                                    env.episode_length + 1)
        cut_at = pair_up(cut_at[:config.num_envs // 2]) if config.antithetic else cut_at
    return TrainState(
        params=params,
        opt_state=make_optimizer(config).init(params),
        env_state=sharding.constrain(env_state, envs),
        last_obs=sharding.constrain(obs.astype(jnp.float32), envs),
        key=key,
        update=jnp.zeros((), jnp.int32),
        episodes=jnp.zeros((), jnp.int32),
        episode_return=sharding.constrain(jnp.zeros((config.num_envs,), jnp.float32), envs),
        cut_at=sharding.constrain(cut_at, envs),
        running=sharding.constrain(episode_returns.running(config.num_envs), envs),
        window=sharding.constrain(episode_returns.window(), everywhere),
    )


def update(
    config: PPOConfig, env, env_params: PyTree, state: TrainState,
    learning_rate: jax.Array | None = None,
) -> tuple[TrainState, dict[str, jax.Array]]:
    """One PPO update: collect, GAE, ``update_epochs`` x ``num_minibatches`` Adam steps.

    Returns scalar metrics: loss terms, ``approx_kl``, ``clip_fraction``,
    ``grad_norm`` (means over all minibatch steps), episode metrics of the
    rollout (see ``episode_metrics``), the discounted returns of the last
    finished episodes (``train_*``, ``gvsjax.utils.episode_returns``), ``learning_rate``, ``clip_eps``,
    ``update`` (index of this update) and ``episodes`` (total so far).
    ``learning_rate``: see ``phase_hyperparams``.
    """
    apply_fn: Callable[..., Any] = make_network(config, env.action_size).apply  # see collect
    optimizer = make_optimizer(config)
    lr, clip_eps = phase_hyperparams(config, env.episode_length, state.update, learning_rate)

    index = state.update
    state, trajectory = collect(config, env, env_params, state)
    _, _, last_value = apply_fn(state.params, state.last_obs)
    advantage, target = gae(
        trajectory.reward, trajectory.value, trajectory.done, last_value,
        config.gamma, config.gae_lambda,
    )
    flat = lambda x: x.reshape((-1,) + x.shape[2:])  # (T, N, ...) -> (T*N, ...)
    batch = Batch(
        obs=flat(trajectory.obs),
        action=flat(trajectory.action),
        log_prob=flat(trajectory.log_prob),
        value=flat(trajectory.value),
        advantage=flat(advantage),
        target=flat(target),
        weight=flat(trajectory.learn).astype(jnp.float32),
    )
    # every device gets the whole rollout: the shuffle and the Adam steps are then
    # the single-device computation (small next to the physics of the rollout)
    batch = sharding.constrain(batch, shardings(config)[1])

    def minibatch_step(carry, minibatch):
        params, opt_state, stopped = carry
        grads, metrics = jax.grad(ppo_loss, has_aux=True)(
            params, apply_fn, minibatch, clip_eps, config.vf_coef, config.ent_coef,
            config.normalize_advantages, config.clip_value_loss, config.clipped_log_prob,
        )
        updates, new_opt_state = optimizer.update(grads, opt_state, params)
        metrics["grad_norm"] = optax.tree.norm(grads)
        # after a KL stop the remaining steps leave params and Adam's moments untouched
        keep = lambda new, old: jax.tree.map(lambda n, o: jnp.where(stopped, o, n), new, old)
        params = keep(optax.apply_updates(params, updates), params)
        return (params, keep(new_opt_state, opt_state), stopped), metrics

    def epoch(carry, key):
        minibatches = jax.tree.map(partial(_shuffle, config, key), batch)
        ran = ~carry[2]
        (params, opt_state, stopped), metrics = jax.lax.scan(minibatch_step, carry, minibatches)
        # early stop (SB3/CleanRL's target_kl): no further epochs on this batch once the
        # policy moved too far from the one that collected it
        stopped = stopped | (jnp.mean(metrics["approx_kl"]) > 1.5 * config.target_kl)
        return (params, opt_state, stopped), (metrics, ran)

    opt_state = state.opt_state
    if math.isfinite(config.adaptive_kl):  # the rate the last update chose, capped by the phase's
        lr = jnp.minimum(opt_state.hyperparams["learning_rate"], lr)
    opt_state = opt_state._replace(hyperparams={**opt_state.hyperparams, "learning_rate": lr})
    key, key_epochs = jax.random.split(state.key)
    (params, opt_state, _), (loss_metrics, ran) = jax.lax.scan(
        epoch, (state.params, opt_state, jnp.zeros((), bool)),
        jax.random.split(key_epochs, config.update_epochs),
    )
    # loss metrics: means over the epochs that updated the parameters
    w = ran.astype(jnp.float32)[:, None]
    metrics = {k: jnp.sum(v * w) / (jnp.sum(w) * v.shape[1]) for k, v in loss_metrics.items()}
    if math.isfinite(config.adaptive_kl):
        opt_state = opt_state._replace(hyperparams={
            **opt_state.hyperparams,
            "learning_rate": adapt_learning_rate(lr, metrics["approx_kl"], config.adaptive_kl)})
    state = dataclasses.replace(state, params=params, opt_state=opt_state, key=key, update=index + 1)
    metrics["epochs_run"] = jnp.sum(ran, dtype=jnp.int32)
    metrics.update(episode_metrics(trajectory))
    metrics.update(episode_returns.window_metrics(state.window))
    metrics.update(
        learning_rate=lr, clip_eps=clip_eps, update=index, episodes=state.episodes
    )
    return state, metrics


def _shuffle(config: PPOConfig, key: jax.Array, x: jax.Array) -> jax.Array:
    """Shuffled ``(T*N, ...)`` -> ``(num_minibatches, T*N/num_minibatches, ...)``.

    With ``antithetic`` the mirrored pairs (env i, env i + N/2 of one step) are
    shuffled as units and land in the same minibatch, so the critic's error
    cancels within each gradient step, not only over the epoch.
    """
    if not config.antithetic:
        order = jax.random.permutation(key, x.shape[0])
        return x[order].reshape((config.num_minibatches, -1) + x.shape[1:])
    half = config.num_envs // 2
    pairs = x.reshape((config.num_steps, 2, half) + x.shape[1:])
    pairs = jnp.swapaxes(pairs, 0, 1).reshape((2, config.num_steps * half) + x.shape[1:])
    pairs = pairs[:, jax.random.permutation(key, config.num_steps * half)]
    pairs = pairs.reshape((2, config.num_minibatches, -1) + x.shape[1:])
    return jnp.swapaxes(pairs, 0, 1).reshape((config.num_minibatches, -1) + x.shape[1:])


def make_update(
    config: PPOConfig, env, env_params: PyTree, updates_per_call: int = 1
) -> Callable[[TrainState], tuple[TrainState, dict[str, jax.Array]]]:
    """A jitted ``state -> (state, metrics)`` running ``updates_per_call`` updates in one scan.

    Metrics are stacked with leading axis ``updates_per_call``. Updates past
    ``num_updates`` are skipped (state unchanged; their metrics are NaN for
    floats and -1 for integers), so the caller may call it
    ``ceil(num_updates / updates_per_call)`` times without overshooting.
    """
    total = num_updates(config, env.episode_length)
    # jitted so that eval_shape's trace below is reused by the cond: tracing a task's step
    # (the unrolled simulator) costs seconds
    one = jax.jit(lambda s: update(config, env, env_params, s))

    def skipped(s):
        shapes = jax.eval_shape(one, s)[1]
        fill = lambda x: jnp.full(
            x.shape, jnp.nan if jnp.issubdtype(x.dtype, jnp.floating) else -1, x.dtype
        )
        return s, jax.tree.map(fill, shapes)

    def body(s, _):
        return jax.lax.cond(s.update < total, one, skipped, s)

    @jax.jit
    def run(state):
        return jax.lax.scan(body, state, None, length=updates_per_call)

    return run


def make_train(
    config: PPOConfig, env, env_params: PyTree
) -> Callable[[jax.Array], tuple[TrainState, dict[str, jax.Array]]]:
    """A jitted pure ``train(key, learning_rate=None) -> (final_state, metrics)`` doing
    the whole run.

    Metrics are stacked over ``num_updates``. ``jax.vmap(train)(keys)`` trains
    one agent per key in parallel; ``jax.vmap(train)(keys, learning_rates)``
    sweeps the phase-1 learning rate too (``None``: ``config.learning_rate``),
    all in one compiled call. ``config.seed`` is not read here: callers
    pass ``jax.random.PRNGKey(config.seed)``.
    """
    total = num_updates(config, env.episode_length)

    @jax.jit
    def train(key, learning_rate=None):
        state = init(config, env, env_params, key)
        return jax.lax.scan(
            lambda s, _: update(config, env, env_params, s, learning_rate), state, None,
            length=total,
        )

    return train


