"""Domain randomisation: any task with physical parameters redrawn every episode.

    env = Randomized(make("basketball"), parse("E:0.1,damping:0.1,payload:0.1", make("basketball")))
    obs, state = env.reset(key, params)            # draws one factor per named parameter
    obs, state, reward, done, info = env.step(key, state, action, params)

Each episode draws every named parameter's factor uniformly in ``[1 - r, 1 + r]``
and plays the inner task with ``params`` scaled by them (the task's
``Environment.randomizable`` says how); ``auto_reset_step`` then redraws. The
factors are traced values in the state, so a batch of episodes with different
models is one ``vmap`` of one compiled program: nothing recompiles per draw.
The names a task accepts, and what each scales, are its ``randomizable``.

With ``observe`` the policy also sees the factors, as ``(factor - 1) / r`` in
``[-1, 1]`` after the task's own observation (a system-identified policy).

Evaluation is on the nominal model: ``evaluate`` (and ``summary``, ``figures``,
``animate``) are the inner task's, on its own ``reset``/``step`` with the
params as given; a policy that observes the factors is shown them at 1 (zeros).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.tasks.base import Box, Controller, Environment, EvalResult, Policy, PyTree, policy_only

Ranges = tuple[tuple[str, float], ...]  # ((name, r), ...) in the order given


def parse(text: str, env: Environment) -> Ranges:
    """``"E:0.1,damping:0.05"`` -> ``(("E", 0.1), ("damping", 0.05))``; empty text -> ``()``.

    A bad format, a name ``env`` does not list in ``randomizable``, a repeated
    name or a range outside (0, 1) raise ValueError naming ``randomize``.
    """
    allowed = sorted(env.randomizable)
    usage = (f"expected NAME:r[,NAME:r ...] with NAME one of {allowed} (task={env.name!r}) and r in (0, 1), "
             "the half-width of the factor's range [1 - r, 1 + r], e.g. randomize=E:0.1,damping:0.1")
    text = text.strip()
    if not text:
        return ()
    out: list[tuple[str, float]] = []
    for item in text.split(","):
        name, sep, value = (part.strip() for part in item.partition(":"))
        if not sep or not name or not value:
            raise ValueError(f"randomize={text!r} is invalid: {item.strip()!r} is not NAME:r; {usage}")
        if name not in env.randomizable:
            raise ValueError(f"randomize={text!r} is invalid: {name!r} is not a randomizable parameter of "
                             f"task={env.name!r}; choose from {allowed}")
        if name in dict(out):
            raise ValueError(f"randomize={text!r} is invalid: {name!r} is given twice")
        try:
            r = float(value)
        except ValueError:
            raise ValueError(f"randomize={text!r} is invalid: {value!r} is not a number; {usage}") from None
        if not (math.isfinite(r) and 0.0 < r < 1.0):  # r >= 1 would allow a factor <= 0
            raise ValueError(f"randomize={text!r} is invalid: the range of {name!r} is {r!r}; "
                             "expected 0 < r < 1 (factors in [1 - r, 1 + r])")
        out.append((name, r))
    return tuple(out)


def text_of(ranges: Ranges) -> str:
    """The canonical ``randomize=`` text of ``ranges`` (what a run's config.json records)."""
    return ",".join(f"{name}:{r:g}" for name, r in ranges)


@struct.dataclass
class RandomizedState:
    inner: PyTree  # the task's state
    factors: jax.Array  # (k,) this episode's factor of each randomised parameter


class Randomized(Environment):
    """``task`` with the parameters of ``ranges`` drawn per episode (see the module docstring).

    It takes the task's own params; ``name``, ``action_size``, ``episode_length``,
    ``ppo_defaults``, the training distributions and evaluation are the task's.
    """
    accepts_controller = False  # evaluated on the wrapped task with a policy

    def __init__(self, task: Environment, ranges: Ranges, observe: bool = False):
        if isinstance(task, Randomized):
            raise ValueError("randomize: the task is already randomised")
        if not ranges:
            raise ValueError("randomize: no parameter to randomise (e.g. randomize=E:0.1)")
        for name, r in ranges:
            if name not in task.randomizable or not 0.0 < r < 1.0:
                parse(f"{name}:{r}", task)  # raises, naming the allowed names and range
        self.task, self.ranges, self.observe = task, tuple(ranges), bool(observe)
        # instance attributes shadow the task's class attributes: the wrapper is that task
        for key in ("name", "action_size", "episode_length", "ppo_defaults", "train_variants", "rows_file",
                    "animation_keys", "animates_policy", "randomizable", "train_sim_dtype", "failure_reward",
                    "return_discount"):
            setattr(self, key, getattr(task, key))
        self.obs_size = task.obs_size + (len(ranges) if observe else 0)  # type: ignore[misc]
        self._half = np.array([r for _, r in ranges])

    def __repr__(self) -> str:
        return f"Randomized({type(self.task).__name__}, randomize={text_of(self.ranges)!r}, observe={self.observe})"

    # ------------------------------------------------------------------ the model of an episode

    def scaled(self, params: PyTree, factors: jax.Array) -> PyTree:
        """``params`` with each randomised parameter multiplied by its entry of ``factors`` (k,)."""
        for i, (name, _) in enumerate(self.ranges):
            params = self.task.randomizable[name](params, factors[i])
        return params

    def _obs(self, obs: jax.Array, factors: jax.Array) -> jax.Array:
        if not self.observe:
            return obs
        seen = (factors - 1.0) / jnp.asarray(self._half)
        return jnp.concatenate([obs, seen.astype(obs.dtype)])

    # ------------------------------------------------------------------ the functional API

    def default_params(self) -> PyTree:
        return self.task.default_params()

    def train_params(self, variant: str = "") -> PyTree:
        return self.task.train_params(variant)

    def with_sim_dtype(self, params: PyTree, sim_dtype: str) -> PyTree:
        return self.task.with_sim_dtype(params, sim_dtype)

    def reset(self, key: jax.Array, params: PyTree) -> tuple[jax.Array, RandomizedState]:
        """Draw the episode's factors, then the task's reset on the scaled params."""
        key_factors, key_task = jax.random.split(key)
        half = jnp.asarray(self._half)
        factors = 1.0 + half * jax.random.uniform(key_factors, half.shape, minval=-1.0, maxval=1.0)
        obs, state = self.task.reset(key_task, self.scaled(params, factors))
        return self._obs(obs, factors), RandomizedState(inner=state, factors=factors)

    def step(self, key, state: RandomizedState, action, params):
        """The task's step on the episode's params; ``info`` gains ``randomize_<name>`` (the factor)."""
        obs, inner, reward, done, info = self.task.step(key, state.inner, action,
                                                        self.scaled(params, state.factors))
        info = {**info, **{f"randomize_{name}": state.factors[i] for i, (name, _) in enumerate(self.ranges)}}
        return self._obs(obs, state.factors), dataclasses.replace(state, inner=inner), reward, done, info

    def observation_space(self, params: PyTree | None = None) -> Box:
        box = self.task.observation_space(params)
        if not self.observe:
            return box
        one = np.ones(len(self.ranges))
        return Box(np.concatenate([box.low, -one]), np.concatenate([box.high, one]))

    # ------------------------------------------------------------------ nominal evaluation

    def nominal_policy(self, policy: Policy) -> Policy:
        """``policy`` as a policy of the task's observations: the factors shown at 1 (nominal)."""
        if not self.observe:
            return policy
        k = len(self.ranges)
        return lambda obs: policy(jnp.concatenate([obs, jnp.zeros(obs.shape[:-1] + (k,), obs.dtype)], -1))

    def evaluate(self, params: PyTree, policy: Policy | Controller, n_episodes: int, seed: int) -> EvalResult:
        """The task's evaluation on the nominal model (``params`` as given)."""
        policy = policy_only(self, policy)
        return self.task.evaluate(params, self.nominal_policy(policy), n_episodes, seed)

    def summary(self, metrics: Mapping[str, Any]) -> str:
        return self.task.summary(metrics)

    def figures(self, params: PyTree, result: EvalResult, out: Path) -> list[Path]:
        return self.task.figures(params, result, out)

    def render(self, params: PyTree, state: PyTree, last_action: np.ndarray | None) -> np.ndarray | None:
        return self.task.render(params, state.inner if isinstance(state, RandomizedState) else state, last_action)

    def animate(self, path: Path, **keys: Any) -> Path:
        if "policy" in keys:
            keys = {**keys, "policy": self.nominal_policy(keys["policy"])}
        return self.task.animate(path, **keys)


def wrap(task: Environment, randomize: str, observe: bool = False) -> Environment:
    """``task`` randomised by the ``randomize=`` text (``parse``); the task itself when it is empty."""
    ranges = parse(randomize, task)
    if not ranges:
        if observe:
            raise ValueError("randomize_observe=true needs randomize=NAME:r,... (the factors to observe)")
        return task
    return Randomized(task, ranges, observe)


def nominal(env: Environment, policy: Policy) -> tuple[Environment, Policy]:
    """``(task, policy of the task's observations)`` of a possibly randomised ``env``: for evaluating
    a trained policy with the task's own ``reset``/``step`` on a model of one's choice."""
    if isinstance(env, Randomized):
        return env.task, env.nominal_policy(policy)
    return env, policy
