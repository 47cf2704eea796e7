"""Gymnasium environments over the functional gvsjax tasks (optional extra: ``pip install gvsjax[gym]``).

    import gymnasium as gym
    import gvsjax.gym  # registers the ids below

    env = gym.make("gvsjax/Basketball-v0")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

    envs = gym.make_vec("gvsjax/Basketball-v0", num_envs=256)  # one jitted, vmapped call per step

Every registered task gets the id ``gvsjax/<ClassName>-v0`` (``gym_id``):
``gvsjax/Basketball-v0``, ``gvsjax/PickPlace-v0``, ...; a task registered
after this import is added by ``register_all()``. Keyword arguments:
``env_params`` (the task's params pytree; default ``env.default_params()``,
e.g. ``pickplace.make_params(split="test")`` for held-out targets),
``render_mode`` (``None`` or ``"rgb_array"``), and ``randomize`` /
``randomize_observe`` (domain randomisation, as ``python -m gvsjax.train``'s keys:
e.g. ``randomize="E:0.1,damping:0.1"`` draws a new model every episode).

Conventions. Actions are float32 ``Box(-1, 1)``; out-of-range values are
clipped by the task (its documented convention), a wrong shape or a NaN/inf
raises ``ValueError``. Observations are float32 (the physics runs in
float64). ``terminated`` is the task's ``done`` (every task has a fixed
episode length, so ``truncated`` is always False); ``info`` holds the task's
info as NumPy scalars (``valid`` is False when the physics diverged; such a
step terminates with reward 0).

Randomness. ``reset(seed=s)`` starts a JAX key stream at ``PRNGKey(s)``;
every ``reset`` and ``step`` takes the next key of the stream
(``key, sub = split(key)``), so a seeded run is reproducible. Without a
seed the stream starts from a draw of Gymnasium's ``np_random``. Sub-env i
of the vector env seeded with s follows exactly the stream of a single env
seeded with s + i (Gymnasium's convention), so both give the same episodes.

Devices. With several JAX devices the vector env splits its batch over them
(``gvsjax.utils.sharding``; as many devices as divide ``num_envs``).

Compilation. The jitted reset/step (and their vmapped batch versions) are
cached per task at module level and take the params as an argument: making
more envs of a task, or changing a params' numbers, does not recompile.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
from gymnasium import spaces
from gymnasium.vector.utils import batch_space

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax.tasks import DEFAULT_TASK, Environment, make, randomized, registered
from gvsjax.utils import sharding


def gym_id(task: str) -> str:
    """The Gymnasium id of a registered task: ``gvsjax/<its class name>-v0``."""
    return f"gvsjax/{type(make(task)).__name__}-v0"


def _box(box) -> spaces.Box:
    return spaces.Box(np.asarray(box.low, np.float32), np.asarray(box.high, np.float32), dtype=np.float32)


def _spaces(env: Environment, params) -> tuple[spaces.Box, spaces.Box]:
    return _box(env.observation_space(params)), _box(env.action_space(params))


def _to_obs(obs, space: spaces.Box) -> np.ndarray:
    # float64 -> float32 can round a bound-hugging value (e.g. a target on the window's
    # edge) one ulp outside the box; clip only that rounding
    return np.clip(np.asarray(obs, np.float32), space.low, space.high)


def _check_action(action, shape: tuple[int, ...]) -> jax.Array:
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action={action!r} is invalid; expected a float array of shape "
                         f"{shape} in [-1, 1]") from None
    if a.shape != shape:
        raise ValueError(f"action has shape {a.shape}; expected {shape} (values in [-1, 1])")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action={a.tolist()} is invalid; it must be finite (values in [-1, 1], "
                         "out-of-range values are clipped)")
    return jnp.asarray(a)


# ----------------------------------------------------------------------------- compiled functions

_COMPILED: dict[tuple, Any] = {}  # jitted functions per (task, kind)


def _split(key):
    key, sub = jax.random.split(key)
    return key, sub


def _raw_fns(env) -> tuple[Callable, Callable]:
    """Un-jitted ``reset(key, params)`` and ``step(key, state, action, params)`` that
    take the next key of the stream and return the advanced key first."""

    def reset(key, params):
        key, sub = _split(key)
        return (key, *env.reset(sub, params))

    def step(key, state, action, params):
        key, sub = _split(key)
        return (key, *env.step(sub, state, action, params))

    return reset, step


def _program(env) -> tuple:
    """What fixes an env's compiled functions: its task and, randomised, the ranges drawn."""
    if isinstance(env, randomized.Randomized):
        return (env.name, env.ranges, env.observe)
    return (env.name,)


def _single_fns(env) -> tuple[Callable, Callable]:
    """The jitted ``_raw_fns``, compiled once per task."""
    if (_program(env), "single") not in _COMPILED:
        _COMPILED[_program(env), "single"] = tuple(jax.jit(f) for f in _raw_fns(env))
    return _COMPILED[_program(env), "single"]


def _vector_fns(env, num_envs: int) -> tuple[Callable, Callable]:
    """Batched reset and same-step-autoreset step: one jitted vmapped call each.

    Each sub-env consumes its key stream exactly like a single env whose user
    calls ``reset()`` after every episode end: one key for the step, then one
    for the reset where the episode ended. With several devices the batch is
    split over them (``gvsjax.utils.sharding``).
    """
    mesh = sharding.mesh_for(num_envs)
    tag = ("vector", None if mesh is None else mesh.size)
    if (_program(env), tag) not in _COMPILED:
        reset1, step1 = _raw_fns(env)

        def step_autoreset(key, state, action, params):
            key, obs, state, reward, done, info = step1(key, state, action, params)
            key_after_reset, obs0, state0 = reset1(key, params)
            done = jnp.asarray(done, bool) | ~jnp.asarray(info.get("valid", True), bool)
            pick = lambda new, old: jnp.where(done, new, old)  # noqa: E731
            return (pick(key_after_reset, key), pick(obs0, obs),
                    jax.tree.map(pick, state0, state), reward, done, info, obs)

        reset = jax.vmap(reset1, in_axes=(0, None))
        step = jax.vmap(step_autoreset, in_axes=(0, 0, 0, None))
        _COMPILED[_program(env), tag] = (jax.jit(sharding.split_batch(reset, mesh, (0, None))),
                                         jax.jit(sharding.split_batch(step, mesh, (0, 0, 0, None))))
    return _COMPILED[_program(env), tag]


def _info(info: dict, valid_default=True) -> dict[str, Any]:
    out = {k: np.asarray(v) for k, v in info.items()}
    out.setdefault("valid", np.asarray(valid_default))
    return out


def _seed_key(seed: int | None, rng: np.random.Generator) -> jax.Array:
    if seed is None:
        seed = int(rng.integers(0, 2**63 - 1))
    return jax.random.PRNGKey(seed)


# ----------------------------------------------------------------------------- single env


class GvsjaxEnv(gym.Env):
    """A gvsjax task as a ``gymnasium.Env`` (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}
    # set in __init__; gymnasium types them as any Space
    observation_space: spaces.Box
    action_space: spaces.Box

    def __init__(self, task: str = DEFAULT_TASK, env_params=None, render_mode: str | None = None,
                 randomize: str = "", randomize_observe: bool = False):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode={render_mode!r} is invalid; choose None or 'rgb_array'")
        self.task = randomized.wrap(make(task), randomize, randomize_observe)
        self.env_params = self.task.default_params() if env_params is None else env_params
        self.observation_space, self.action_space = _spaces(self.task, self.env_params)
        self.render_mode = render_mode
        self._reset, self._step = _single_fns(self.task)
        self._key: jax.Array | None = None
        self._state: Any = None  # the task's state pytree
        self._done = True
        self._last: tuple | None = None  # (state before, action, info) of the last step, for render

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None or self._key is None:
            self._key = _seed_key(seed, self.np_random)
        self._key, obs, self._state = self._reset(self._key, self.env_params)
        self._done, self._last = False, None
        return _to_obs(obs, self.observation_space), {}

    def step(self, action):
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        if self._done:
            raise RuntimeError("the episode has ended (terminated); call reset() before step()")
        a = _check_action(action, self.action_space.shape)
        before = self._state
        self._key, obs, self._state, reward, done, info = self._step(
            self._key, self._state, a, self.env_params)
        info = _info(info)
        terminated = bool(done) or not bool(info["valid"])
        self._done = terminated
        self._last = (before, np.asarray(a), info)
        return (_to_obs(obs, self.observation_space), float(reward), terminated,
                bool(info.get("truncated", False)), info)

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        image = self.task.render(self.env_params, self._state, None if self._last is None else self._last[1])
        if image is None:
            raise NotImplementedError(f"task={self.task.name!r} does not render")
        return image


# ----------------------------------------------------------------------------- vector env


class GvsjaxVectorEnv(gym.vector.VectorEnv):
    """``num_envs`` copies of a task stepped in one jitted, vmapped call.

    Autoreset is same-step (``metadata["autoreset_mode"]``, like the task's
    ``auto_reset_step``): where an episode ends, the returned observation is
    the new episode's first one, and ``info["final_obs"]`` (float32,
    ``(num_envs, obs_size)``) holds the terminal observation of every sub-env
    (meaningful where ``terminated | truncated``).
    """

    metadata = {"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP, "render_modes": []}
    # set in __init__; gymnasium types them as any Space
    single_observation_space: spaces.Box
    single_action_space: spaces.Box

    def __init__(self, num_envs: int = 1, task: str = DEFAULT_TASK, env_params=None,
                 render_mode: str | None = None, randomize: str = "", randomize_observe: bool = False):
        if not (isinstance(num_envs, (int, np.integer)) and num_envs >= 1):
            raise ValueError(f"num_envs={num_envs!r} is invalid; expected an integer >= 1")
        if render_mode is not None:
            raise ValueError(f"render_mode={render_mode!r} is invalid; the vector env does not render")
        self.task = randomized.wrap(make(task), randomize, randomize_observe)
        self.env_params = self.task.default_params() if env_params is None else env_params
        self.num_envs = int(num_envs)
        self.single_observation_space, self.single_action_space = _spaces(self.task, self.env_params)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = None
        self._reset, self._step = _vector_fns(self.task, self.num_envs)
        self._keys: jax.Array | None = None
        self._state: Any = None  # the task's state pytree, batched

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None):
        if seed is not None or self._keys is None:
            if seed is None:
                self._np_random, _ = gym.utils.seeding.np_random(None)
                seed = int(self._np_random.integers(0, 2**63 - self.num_envs - 1))
            if isinstance(seed, (list, tuple, np.ndarray)):
                seeds = list(seed)
            else:
                seeds = [seed + i for i in range(self.num_envs)]
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed has {len(seeds)} entries; expected num_envs={self.num_envs}")
            self._keys = jax.vmap(jax.random.PRNGKey)(jnp.asarray(seeds, jnp.int64))
        self._keys, obs, self._state = self._reset(self._keys, self.env_params)
        return _to_obs(obs, self.single_observation_space), {}

    def step(self, actions):
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        a = _check_action(actions, (self.num_envs, *self.single_action_space.shape))
        self._keys, obs, self._state, reward, done, info, final_obs = self._step(
            self._keys, self._state, a, self.env_params)
        info = _info(info)
        info["final_obs"] = _to_obs(final_obs, self.single_observation_space)
        truncated = np.asarray(info.get("truncated", np.zeros(self.num_envs, bool)), bool)
        return (_to_obs(obs, self.single_observation_space), np.asarray(reward, np.float64),
                np.asarray(done, bool), truncated, info)


# ----------------------------------------------------------------------------- registration


def register_all() -> list[str]:
    """Register every task of ``gvsjax.tasks`` with Gymnasium; returns their ids."""
    ids = []
    for task in registered():
        env_id = gym_id(task)
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="gvsjax.gym:GvsjaxEnv",
                         vector_entry_point="gvsjax.gym:GvsjaxVectorEnv", kwargs={"task": task})
        ids.append(env_id)
    return ids


register_all()
