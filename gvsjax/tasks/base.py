"""The environment base class every task derives from (gymnax style) and the registry.

An environment is a small immutable object whose methods are pure functions:

    obs, state = env.reset(key, params)
    obs, state, reward, done, info = env.step(key, state, action, params)

``params`` is an immutable pytree of the task's parameters (physics, ranges,
reward scale); ``state`` is a pytree; both ``vmap`` over a batch of episodes.
A task subclasses ``Environment``, implements ``default_params``, ``reset`` and
``step``, and overrides the extras below where its defaults do not fit. The
command line (``train``, ``evaluate``, ``animate``) and ``gvsjax.gym`` reach a
task only through this class, so adding a task is its module plus one
``register`` line in ``gvsjax/tasks/__init__.py``.

Conventions (fixed for all tasks):

* ``step`` returns five values, like gymnax 0.x. ``done`` is a *termination*
  flag: every task has a fixed, known episode length, so an episode never ends
  by truncation. ``info["truncated"]`` is always present (and False), so code
  written for the 6-value gymnax 1.0 convention can build
  ``terminated, truncated = done, info["truncated"]``.
* Actions live in ``[-1, 1]^action_size``; a task maps them affinely to
  physical quantities and clips out-of-range values.
* ``info["valid"]`` is False when the physics diverged (NaN/inf, or a state
  beyond the task's documented magnitude bound, see ``bounded``); such a step
  ends the episode. Its reward is the task's ``failure_reward`` when that is a
  number (a terminal transition the learners learn from); with None it must
  not be used for learning (the learners mask it out).
* A non-finite action (``sanitize_action``) is replaced by 0, the centre of
  the box, simulated, and flagged ``info["valid"] = False``: inside ``jit``
  nothing can be raised on a value, and a flag keeps a batch running. A wrong
  action *shape* is known while tracing and raises ``ValueError``.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, ClassVar, Protocol, runtime_checkable

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core.model import PointLoad, PointMass, Robot, SoftLink

PyTree = Any
Policy = Callable[[jax.Array], jax.Array]  # (batch, obs_size) -> (batch, action_size), jittable


@runtime_checkable
class Controller(Protocol):
    """A controller that sees the environment's state and keeps a memory (``carry``), such as
    ``gvsjax.mpc.MPC``; ``evaluate`` accepts one wherever it accepts a ``Policy``. All batched."""

    def init(self, obs: jax.Array, state: Any) -> Any:
        """The memory at an episode's start."""
        ...

    def act(self, carry: Any, obs: jax.Array, state: Any, t: jax.Array) -> tuple[jax.Array, Any]:
        """``(actions (batch, action_size), next carry)`` at step ``t``."""
        ...


# (params, factor) -> params with one physical parameter multiplied by factor (a traced scalar)
Scale = Callable[[PyTree, jax.Array], PyTree]


def _map_robots(params: PyTree, fn: Callable[[Robot], Robot], what: str) -> PyTree:
    """``params`` with ``fn`` applied to every ``gv.Robot`` inside (a ValueError if none)."""
    found = []

    def visit(x):
        if isinstance(x, Robot):
            found.append(x)
            return fn(x)
        return x

    out = jax.tree.map(visit, params, is_leaf=lambda x: isinstance(x, Robot))
    if not found:
        raise ValueError(f"randomize: {what} scales the gv.Robot in the task's params, but its params hold "
                         "none; the task must override Environment.randomizable")
    return out


def scale_material(field: str) -> Scale:
    """A ``Scale`` multiplying ``Material.<field>`` of every soft link of every robot in the params.

    The section's stiffness, damping and inertia are assembled from the material inside the
    dynamics (``gvsjax.core.dynamics.section``) at every call, so scaling the leaf is all it takes.
    """

    def scale(params, factor):
        def robot(r: Robot) -> Robot:
            links = tuple(dataclasses.replace(link, material=dataclasses.replace(
                link.material, **{field: getattr(link.material, field) * factor}))
                if isinstance(link, SoftLink) else link for link in r.links)
            return dataclasses.replace(r, links=links)

        return _map_robots(params, robot, field)

    return scale


def scale_payload(params: PyTree, factor: jax.Array) -> PyTree:
    """Every point load's magnitude and every point mass of every robot in the params x ``factor``
    (a task's payload when it is carried that way, e.g. basketball's ball, a tip force)."""

    def robot(r: Robot) -> Robot:
        loads = tuple(dataclasses.replace(load, magnitude=load.magnitude * factor)
                      if isinstance(load, PointLoad) else load for load in r.loads)
        masses = tuple(dataclasses.replace(m, mass=m.mass * factor) if isinstance(m, PointMass) else m
                       for m in r.masses)
        return dataclasses.replace(r, loads=loads, masses=masses)

    return _map_robots(params, robot, "payload")


# The default ``Environment.randomizable``: the soft material of the task's robot(s)
ROBOT_MATERIAL: Mapping[str, Scale] = {
    "E": scale_material("youngs_modulus"),
    "damping": scale_material("damping"),
    "density": scale_material("density"),
}


@dataclasses.dataclass(frozen=True)
class Box:
    """A box of real vectors (like ``gymnax.spaces.Box``); infinite bounds allowed."""

    low: np.ndarray
    high: np.ndarray

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(np.shape(self.low))


@dataclasses.dataclass
class EvalResult:
    """What ``Environment.evaluate`` returns.

    ``metrics``: JSON-able summary (written to eval.json); ``rows``: one entry per
    episode for each column (written to the task's ``rows_file``); ``extra``:
    whatever the task's ``figures`` need (e.g. the actions taken), and optionally ``"who"``: the
    name the figures give what was evaluated (default "policy"; the MPC's evaluation sets "MPC").
    """

    metrics: dict[str, Any]
    rows: dict[str, np.ndarray]
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)


class Environment:
    """A task: the functional env API plus the extras the command line uses.

    Subclasses set ``name``, ``obs_size``, ``action_size``, ``episode_length``
    and implement ``default_params``, ``reset`` and ``step``.
    """

    name: ClassVar[str]
    obs_size: ClassVar[int]
    action_size: ClassVar[int]
    episode_length: ClassVar[int]  # steps after which ``done`` is True
    # PPOConfig overrides that suit this task (``python -m gvsjax.train`` applies them first)
    ppo_defaults: ClassVar[Mapping[str, Any]] = {}
    # SACConfig overrides that suit this task (``python -m gvsjax.train algo=sac``)
    sac_defaults: ClassVar[Mapping[str, Any]] = {}
    # names accepted by ``train_params(variant)``; the CLI key ``train_targets`` picks one
    train_variants: ClassVar[tuple[str, ...]] = ()
    rows_file: ClassVar[str] = "eval_episodes.csv"  # per-episode evaluation table
    # CLI keys of ``animate`` with their defaults (empty: the task has no animation)
    animation_keys: ClassVar[Mapping[str, Any]] = {}
    # True: ``animate`` takes ``policy=`` (closed-loop tasks; the CLI's ``checkpoint=`` key loads one)
    animates_policy: ClassVar[bool] = False
    # physical parameters training may randomise (``randomize=NAME:r,...``, gvsjax.tasks.randomized):
    # name -> (params, factor) -> params with that parameter x factor. Default: the soft material
    # (E, damping eta, density) of every gv.Robot in the params; a task adds its payload, if any.
    randomizable: ClassVar[Mapping[str, Scale]] = ROBOT_MATERIAL
    # True: ``evaluate`` also takes a ``Controller`` (the closed-loop tasks; ``gvsjax.mpc``)
    accepts_controller: ClassVar[bool] = True
    # the reward of a step whose simulation failed (``info["valid"]`` False), learned from as a terminal
    # transition; None: such a step is masked out of the losses
    failure_reward: ClassVar[float | None] = None
    # the discount of the discounted returns training logs (gvsjax.utils.episode_returns)
    return_discount: ClassVar[float] = 0.99
    # True: ``episode_length`` is a time limit on a task that would go on (nothing in the state
    # ends it), so an off-policy learner (``gvsjax.sac``) bootstraps through the last step
    time_limit: ClassVar[bool] = False
    # the simulator precision training uses when the run leaves ``sim_dtype`` empty; evaluation
    # always simulates with ``default_params()`` (float64). "float32" needs a params ``sim_dtype``.
    train_sim_dtype: ClassVar[str] = "float64"

    # ------------------------------------------------------------------ the functional API

    def default_params(self) -> PyTree:
        """The task's parameters as published (an immutable pytree); evaluation uses them."""
        raise NotImplementedError

    def reset(self, key: jax.Array, params: PyTree) -> tuple[jax.Array, PyTree]:
        """A new episode: ``(obs, state)``."""
        raise NotImplementedError

    def step(self, key: jax.Array, state: PyTree, action: jax.Array,
             params: PyTree) -> tuple[jax.Array, PyTree, jax.Array, jax.Array, dict[str, jax.Array]]:
        """Apply ``action``: ``(obs, state, reward, done, info)`` (see the module docstring)."""
        raise NotImplementedError

    def observation_space(self, params: PyTree | None = None) -> Box:
        """Bounds of the observation (default: unbounded)."""
        inf = np.full(self.obs_size, np.inf)
        return Box(-inf, inf)

    def action_space(self, params: PyTree | None = None) -> Box:
        """``[-1, 1]^action_size`` for every task."""
        one = np.ones(self.action_size)
        return Box(-one, one)

    # ------------------------------------------------------------------ training

    def train_params(self, variant: str = "") -> PyTree:
        """The params training uses (default: ``default_params()``); ``variant`` picks
        one of ``train_variants``, e.g. another target distribution."""
        if variant:
            allowed = (f"choose one of {list(self.train_variants)} or leave it empty" if self.train_variants
                       else "this task has a single training distribution: leave it empty")
            raise ValueError(f"train_targets={variant!r} is invalid for task={self.name!r}; {allowed}")
        return self.default_params()

    def with_sim_dtype(self, params: PyTree, sim_dtype: str) -> PyTree:
        """``params`` simulating in ``sim_dtype`` ("float64" or "float32")."""
        sim_dtype = sim_dtype or "float64"
        if sim_dtype == "float64" and not hasattr(params, "sim_dtype"):
            return params
        if not hasattr(params, "sim_dtype"):
            raise ValueError(f"sim_dtype={sim_dtype!r} is invalid for task={self.name!r}: it simulates in "
                             "float64 only")
        return params.replace(sim_dtype=sim_dtype)

    def planning_params(self, params: PyTree) -> PyTree:
        """The params a model-based controller (``gvsjax.mpc``) predicts with: ``params`` without
        what it cannot know ahead, e.g. a moving target's random turns (default: ``params``)."""
        return params

    # ------------------------------------------------------------------ evaluation

    def evaluate(self, params: PyTree, policy: Policy | Controller, n_episodes: int, seed: int) -> EvalResult:
        """Run ``n_episodes`` episodes with ``policy`` (or a ``Controller``) from ``reset`` keys of ``seed``.

        The default reports the return (sum of rewards until ``done``) and the
        share of valid episodes; tasks override it with their own metrics.
        """
        ret, valid = _rollout_returns(self, params, policy, n_episodes, seed)
        ret = np.where(valid, ret, np.nan)
        metrics = {"n_episodes": int(n_episodes), "valid_fraction": float(np.mean(valid)),
                   "mean_return": float(np.nanmean(ret)) if valid.any() else float("nan"),
                   "median_return": float(np.nanmedian(ret)) if valid.any() else float("nan")}
        return EvalResult(metrics=metrics, rows={"return": ret, "valid": valid})

    def headline(self, metrics: Mapping[str, Any]) -> tuple[str, float] | None:
        """The one number of an evaluation's metrics that ranks two controllers of this task
        (higher is better), with its name; None: the task names none."""
        return None

    def summary(self, metrics: Mapping[str, Any]) -> str:
        """One or a few lines describing an evaluation's metrics (``metrics["who"]``, when present,
        names what was evaluated: "MPC" for a controller; default "policy")."""
        shown = {k: v for k, v in metrics.items() if k not in ("task", "checkpoint", "what", "training")}
        return "eval: " + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in shown.items())

    def figures(self, params: PyTree, result: EvalResult, out: Path) -> list[Path]:
        """Figures of an evaluation written into ``out`` (default: none)."""
        return []

    # ------------------------------------------------------------------ drawing

    def render(self, params: PyTree, state: PyTree, last_action: np.ndarray | None) -> np.ndarray | None:
        """An RGB image (H, W, 3) uint8 of ``state`` (None: the task does not draw)."""
        return None

    def animate(self, path: Path, **keys: Any) -> Path:
        """Write a GIF to ``path`` from the ``animation_keys`` values (and ``policy=`` when
        ``animates_policy``)."""
        raise ValueError(f"task={self.name!r} has no animation")


def record_episodes(env: Environment, params, policy: Policy | Controller, keys: jax.Array,
                    record: Callable[[PyTree, dict], dict]) -> tuple[PyTree, dict]:
    """Episodes from ``reset(keys[i])`` under ``policy`` (or a ``Controller``) for
    ``episode_length`` steps; jittable.

    Step t's key of episode i is ``fold_in(keys[i], t)``. Returns the first state (batched) and,
    per step, ``record(state, info)``'s arrays plus ``valid`` (no invalid step so far), each
    (n, T, ...). Episodes are not reset when ``done``: closed-loop tasks run a fixed length.
    """
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))
    control = as_controller(policy)

    def one(carry, t):
        obs, s, memory, alive = carry
        action, memory = control.act(memory, obs, s, t)
        obs, s, _, _, info = step(jax.vmap(lambda k: jax.random.fold_in(k, t))(keys), s, action, params)
        alive = alive & info["valid"]
        return (obs, s, memory, alive), {**record(s, info), "valid": alive}

    init = (obs, state, control.init(obs, state), jnp.ones(keys.shape[0], bool))
    _, rec = jax.lax.scan(one, init, jnp.arange(env.episode_length))
    return state, {k: jnp.swapaxes(v, 0, 1) for k, v in rec.items()}


def as_controller(policy: Policy | Controller) -> Controller:
    """``policy`` as a ``Controller`` (a policy has no memory and sees the observation only)."""
    return policy if isinstance(policy, Controller) else _Stateless(policy)


@dataclasses.dataclass(frozen=True)
class _Stateless:
    """A ``Policy`` as a ``Controller`` without memory."""

    policy: Policy

    def init(self, obs, state):
        return ()

    def act(self, carry, obs, state, t):
        return self.policy(obs), carry


def _rollout_returns(env: Environment, params, policy: Policy | Controller, n: int, seed: int):
    keys = jax.random.split(jax.random.PRNGKey(seed), n)
    control = as_controller(policy)

    @jax.jit
    def run(keys):
        obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)

        def one(carry, t):
            obs, state, memory, ret, alive, valid = carry
            step_keys = jax.vmap(lambda k: jax.random.fold_in(k, t))(keys)
            action, memory = control.act(memory, obs, state, t)
            obs, state, reward, done, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
                step_keys, state, action, params)
            ok = jnp.asarray(info.get("valid", True), bool)
            ret = ret + jnp.where(alive, reward, 0.0)
            valid = valid & (ok | ~alive)
            return (obs, state, memory, ret, alive & ~done & ok, valid), None

        init = (obs, state, control.init(obs, state), jnp.zeros(n), jnp.ones(n, bool), jnp.ones(n, bool))
        (_, _, _, ret, _, valid), _ = jax.lax.scan(one, init, jnp.arange(env.episode_length))
        return ret, valid

    ret, valid = run(keys)
    return np.asarray(ret, float), np.asarray(valid, bool)


def policy_only(env: Environment, policy: Policy | Controller) -> Policy:
    """``policy``, or a ValueError if it is a ``Controller``: for tasks whose evaluation takes a policy only."""
    if isinstance(policy, Controller):
        raise ValueError(f"task={env.name!r} evaluates policies (obs -> action) only; a Controller (e.g. "
                         "controller=mpc) runs on the closed-loop tasks")
    return policy


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


def draw_index(key: jax.Array, cdf: jax.Array) -> jax.Array:
    """An index drawn with probabilities given by ``cdf`` (P,), a non-decreasing cumulative
    weight (its last entry the total). Inverse CDF: O(log P) per draw, where a categorical
    over P logits costs O(P) random numbers."""
    index = jnp.searchsorted(cdf, jax.random.uniform(key, dtype=cdf.dtype) * cdf[-1], side="right")
    return jnp.minimum(index, cdf.shape[0] - 1)


def auto_reset_step(env: Environment) -> Callable:
    """A ``step`` that starts a fresh episode whenever one ends.

    The returned observation is the first observation of the new episode when
    ``done`` (or when ``cut``: the caller ends the episode early); reward, done and
    info still describe the step that was taken.
    """

    def step(key, state, action, params, cut=False):
        key_step, key_reset = jax.random.split(key)
        obs, state, reward, done, info = env.step(key_step, state, action, params)
        obs_reset, state_reset = env.reset(key_reset, params)
        restart = done | cut
        obs = jnp.where(restart, obs_reset, obs)
        state = jax.tree.map(lambda r, s: jnp.where(restart, r, s), state_reset, state)
        return obs, state, reward, done, info

    return step


# ----------------------------------------------------------------------------- registry

_REGISTRY: dict[str, Callable[[], Environment] | str] = {}


def register(name: str, factory: Callable[[], Environment] | str) -> None:
    """Make ``make(name)`` return ``factory()``.

    ``factory`` is a callable (e.g. the class) or ``"module:attr"``, imported on
    first use so that listing tasks does not import (or build) every one.
    """
    _REGISTRY[name] = factory


def make(name: str) -> Environment:
    """The environment registered under ``name``."""
    if name not in _REGISTRY:
        raise ValueError(f"task={name!r} is unknown; choose one of {registered()}")
    factory = _REGISTRY[name]
    if isinstance(factory, str):
        module, _, attr = factory.partition(":")
        factory = getattr(importlib.import_module(module), attr)
        _REGISTRY[name] = factory
    env = factory()
    if not isinstance(env, Environment):
        raise TypeError(f"task {name!r}: {factory!r} made a {type(env).__name__}, not an Environment")
    return env


def registered() -> list[str]:
    """The names ``make`` accepts, sorted."""
    return sorted(_REGISTRY)
