"""The functional environment API shared by every task (gymnax style).

An environment is a small immutable object whose methods are pure functions:

    obs, state = env.reset(key, params)
    obs, state, reward, done, info = env.step(key, state, action, params)

``params`` is an immutable pytree of the task's parameters (physics, ranges,
reward scale); ``state`` is a pytree; both ``vmap`` over a batch of episodes.

Conventions (fixed for all gvsjax tasks):

* ``step`` returns five values, like gymnax 0.x. ``done`` is a *termination*
  flag: every gvsjax task has a fixed, known episode length, so an episode
  never ends by truncation. ``info["truncated"]`` is always present (and
  always False) so that code written for the 6-value gymnax 1.0 convention can
  build ``terminated, truncated = done, info["truncated"]`` explicitly.
* Actions live in ``[-1, 1]^action_size``; a task maps them affinely to
  physical quantities and clips out-of-range values.
* ``info["valid"]`` is False when the physics diverged (NaN/inf, or a state
  beyond the task's documented magnitude bound, see ``bounded``); such a step
  ends the episode and its reward must not be used for learning.
* Non-finite actions (policy: ``sanitize_action``): an action with any NaN or
  inf entry is replaced by 0, the centre of the action box, the step is
  simulated with it and flagged ``info["valid"] = False`` (so it ends the
  episode and PPO masks it out). Inside ``jit`` nothing can be raised on a
  value, and a flag keeps a batch of episodes running. A wrong action *shape*
  is known while tracing and raises ``ValueError`` before anything compiles.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import jax
import jax.numpy as jnp

PyTree = Any


class Environment(Protocol):
    """What a task provides. See the module docstring for the conventions."""

    name: str
    obs_size: int
    action_size: int
    episode_length: int  # number of steps after which ``done`` is True

    def default_params(self) -> PyTree:
        """The task's parameters as the paper sets them (an immutable pytree)."""
        ...

    # Optional: ``train_params(targets: str = "")``, the params training uses when they
    # differ from ``default_params()`` (e.g. another target distribution); evaluation
    # always uses ``default_params()``. ``gvsjax.train.training_params`` reads it.

    def reset(self, key: jax.Array, params: PyTree) -> tuple[jax.Array, PyTree]:
        """A new episode: ``(obs, state)``."""
        ...

    def step(
        self, key: jax.Array, state: PyTree, action: jax.Array, params: PyTree
    ) -> tuple[jax.Array, PyTree, jax.Array, jax.Array, dict[str, jax.Array]]:
        """Apply ``action``: ``(obs, state, reward, done, info)`` (see the module docstring)."""
        ...


def sanitize_action(action: jax.Array, size: int | None = None) -> tuple[jax.Array, jax.Array]:
    """``(action, finite)``: the action with every entry replaced by 0 when any is NaN/inf.

    ``finite`` is a bool scalar; a task ANDs it into ``info["valid"]``. ``size``
    (the task's ``action_size``) checks the shape at trace time: ``(size,)``.
    """
    action = jnp.asarray(action)
    if size is not None and action.shape != (size,):
        raise ValueError(f"action has shape {action.shape} (dtype {action.dtype}); expected ({size},) "
                         "per environment (vmap over a batch)")
    if not jnp.issubdtype(action.dtype, jnp.floating):
        action = action.astype(float)
    finite = jnp.all(jnp.isfinite(action))
    return jnp.where(finite, action, jnp.zeros_like(action)), finite


def bounded(x: jax.Array, bound: float) -> jax.Array:
    """True when every entry of ``x`` is finite and ``|x| <= bound`` (NaN compares False)."""
    return jnp.all(jnp.abs(x) <= bound)


def auto_reset_step(env: Environment) -> Callable:
    """A ``step`` that starts a fresh episode whenever one ends.

    The returned observation is the first observation of the new episode when
    ``done``; reward, done and info still describe the step that was taken.
    """

    def step(key, state, action, params):
        key_step, key_reset = jax.random.split(key)
        obs, state, reward, done, info = env.step(key_step, state, action, params)
        obs_reset, state_reset = env.reset(key_reset, params)
        obs = jnp.where(done, obs_reset, obs)
        state = jax.tree.map(lambda r, s: jnp.where(done, r, s), state_reset, state)
        return obs, state, reward, done, info

    return step


_REGISTRY: dict[str, Callable[[], Environment]] = {}


def register(name: str, factory: Callable[[], Environment]) -> None:
    """Make ``make(name)`` return ``factory()``."""
    _REGISTRY[name] = factory


def make(name: str) -> Environment:
    """The environment registered under ``name``."""
    if name not in _REGISTRY:
        raise ValueError(f"task={name!r} is unknown; choose one of {sorted(_REGISTRY)}")
    return _REGISTRY[name]()


def registered() -> list[str]:
    """The names ``make`` accepts, sorted."""
    return sorted(_REGISTRY)
