"""track3d: keep the tip of an upright 3D soft arm on a target moving through a box.

The target moves at 0.5 m/s in x, y in [-0.6, 0.6] m, z in [0.3, 0.9] m, turning
to a new uniformly random direction with probability 0.025 per control step and
bouncing off the box's walls. By default (``targets="reachable"``) it stays in the
part of the box within 3 cm of a tip the arm holds at rest under some action
(``target``): most of the box is beyond what the actuation holds, and
``targets="box"`` (the whole box) keeps it anyway. The arm (``gv.soft_arm``: 1 m,
base at the origin, along +z at rest, gravity along -z) starts at rest; the policy
acts every 0.1 s for 10 s (100 steps) through its two tendon groups (``Track3D``) or
through bending moments at six control points (``Track3DMuscle``;
``gvsjax.tasks.actuation``).

Observation (38,) for the default arm: the tip's position (m) and velocity (m/s),
the strain coordinates and rates (scaled, ``arm3d.arm_features``), the target's
position (m) and velocity / speed, the target minus the tip (m), the fraction of
the episode left and the last action (clipped to [-1, 1]; 0 at the start). Reward
per step exp(-k d) in (0, 1], d the tip-to-target distance (m) at the end of the
step, minus ``action_rate_weight`` x the mean squared change of the action (0.1 by
default; 0 for ``Track3DMuscle``, whose runs were trained without it). A non-finite
or out-of-bound state ends the episode with ``info["valid"] = False`` and reward 0.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.kinematics import tip_state
from gvsjax.tasks import arm3d
from gvsjax.tasks.base import Box, Controller, Environment, EvalResult, Policy, record_episodes, sanitize_action
from gvsjax.tasks.track3d import figures
from gvsjax.tasks.track3d.params import TARGET_SETS, Track3DParams
from gvsjax.tasks.track3d.target import check as check_targets
from gvsjax.tasks.track3d.target import make_params, move, start

SETTLE_S = 2.0  # s: the "tracking" metrics skip the first seconds, when the arm leaves its rest pose


@struct.dataclass
class Track3DState:
    q: jax.Array  # (n,) strain coordinates
    qd: jax.Array  # (n,)
    tip: jax.Array  # (3,) m
    tip_velocity: jax.Array  # (3,) m/s
    target: jax.Array  # (3,) m
    target_velocity: jax.Array  # (3,) m/s
    tension: jax.Array  # (n_tendons,) N, held during the last step (0 under muscle actuation)
    step: jax.Array  # () int32, control steps taken
    action: jax.Array  # (action_size,) the last action, clipped to [-1, 1] (0 before the first)


def observe(state: Track3DState, params: Track3DParams) -> jax.Array:
    """The observation of ``state`` (see the module docstring)."""
    robot = params.arm.robot
    left = 1.0 - state.step / params.episode_steps
    return jnp.concatenate([arm3d.arm_features(robot, state.q, state.qd, state.tip, state.tip_velocity),
                            state.target, state.target_velocity / params.speed, state.target - state.tip,
                            jnp.asarray(left, state.q.dtype)[None], state.action.astype(state.q.dtype)])


def rest_tip(params: Track3DParams) -> jax.Array:
    """The tip of the arm at rest (q = 0), m."""
    q, qd = arm3d.rest(params.arm.robot)
    return tip_state(params.arm.robot, q, qd)[0]


class Track3D(Environment):
    """Closed-loop tracking of a moving 3D target."""

    name = "track3d"
    obs_size = 38  # 6 + 2 x 9 strain coordinates + 10 + the last action
    action_size = 4
    episode_length = 100
    rows_file = "eval_episodes.csv"
    animation_keys = {"seed": 0, "fps": 10, "dpi": 70}
    animates_policy = True
    ppo_defaults = {**arm3d.PPO_DEFAULTS, "total_episodes": 24_000}
    train_variants = TARGET_SETS  # train_targets=box: the whole published box

    def default_params(self) -> Track3DParams:
        """The target in the reachable part of the box (``target.make_params``)."""
        return make_params()

    def train_params(self, variant: str = "") -> Track3DParams:
        """The default params, or those of the target set ``variant`` (one of ``TARGET_SETS``)."""
        if variant and variant not in self.train_variants:
            super().train_params(variant)  # raises, naming the choices
        return self.default_params() if not variant else self._params(variant)

    def _params(self, targets: str) -> Track3DParams:
        return make_params(targets=targets)

    def _check(self, params: Track3DParams) -> None:
        arm3d.check_task(self, params.arm, params.episode_steps, other_obs=10 + self.action_size)
        check_targets(params)
        w = params.action_rate_weight
        if isinstance(w, (int, float)) and not (np.isfinite(w) and w >= 0):
            raise ValueError(f"action_rate_weight={w!r} is invalid for {self.name}; expected a number >= 0")

    def with_sim_dtype(self, params: Track3DParams, sim_dtype: str) -> Track3DParams:
        return dataclasses.replace(params, arm=arm3d.with_sim_dtype(params.arm, sim_dtype))

    def planning_params(self, params: Track3DParams) -> Track3DParams:
        """A planner predicts the target straight on (bouncing off the walls): its turns are random."""
        return dataclasses.replace(params, turn_probability=0.0)

    def observation_space(self, params=None) -> Box:
        low = np.full(self.obs_size, -np.inf)
        high = np.full(self.obs_size, np.inf)
        left = self.obs_size - self.action_size - 1
        low[left], high[left] = 0.0, 1.0
        low[left + 1:], high[left + 1:] = -1.0, 1.0
        return Box(low, high)

    def reset(self, key, params: Track3DParams):
        """The arm at rest, the target at a uniform point of the box heading in a uniform direction."""
        self._check(params)
        robot = params.arm.robot
        q, qd = arm3d.rest(robot)
        target, velocity = start(key, params)
        tip = rest_tip(params)
        state = Track3DState(q=q, qd=qd, tip=tip, tip_velocity=jnp.zeros(3), target=target,
                             target_velocity=velocity, tension=jnp.zeros(len(robot.tendons)),
                             step=jnp.zeros((), jnp.int32), action=jnp.zeros(self.action_size))
        return observe(state, params), state

    def step(self, key, state: Track3DState, action, params: Track3DParams):
        """One control step (the action's input held for ``control_dt``): ``(obs, state, reward, done, info)``."""
        self._check(params)
        action, finite = sanitize_action(action, self.action_size)
        tr, tension, _ = arm3d.control_step(params.arm, state.q, state.qd, action)
        q, qd, tip, tip_velocity = tr.q[-1], tr.qd[-1], tr.tip[-1], tr.tip_velocity[-1]
        target, velocity = move(key, state.target, state.target_velocity, params)
        d = jnp.sqrt(jnp.sum((tip - target) ** 2))
        valid = finite & arm3d.healthy(params.arm.robot, q, qd) & jnp.isfinite(d)
        applied = jnp.clip(action, -1.0, 1.0).astype(state.action.dtype)  # a carried state keeps its dtype
        change = jnp.mean((applied - state.action) ** 2)
        reward = jnp.where(valid, jnp.exp(-params.k * jnp.where(valid, d, 0.0)) - params.action_rate_weight * change,
                           0.0)
        keep = lambda new, old: jnp.where(valid, new, old)  # noqa: E731
        new = Track3DState(q=keep(q, state.q), qd=keep(qd, 0.0 * state.qd), tip=keep(tip, state.tip),
                           tip_velocity=keep(tip_velocity, 0.0 * state.tip_velocity), target=target,
                           target_velocity=velocity, tension=tension, step=state.step + 1, action=applied)
        done = (new.step >= self.episode_length) | ~valid
        info = {"distance": d, "valid": valid, "truncated": jnp.zeros((), bool), "action_change": change}
        return observe(new, params), new, reward, done, info

    # ------------------------------------------------------------------ evaluation

    def evaluate(self, params: Track3DParams, policy: Policy | Controller, n_episodes: int, seed: int) -> EvalResult:
        """``n_episodes`` episodes from ``reset`` keys of ``seed``: the distance at every step."""
        run = jax.jit(lambda keys: rollout(self, params, policy, keys))
        out = {k: np.asarray(v) for k, v in run(jax.random.split(jax.random.PRNGKey(seed), n_episodes)).items()}
        d = np.where(out["valid"], out["distance"], np.inf)  # (n, T)
        rest = np.linalg.norm(out["target"] - np.asarray(rest_tip(params)), axis=-1)
        settle = int(round(SETTLE_S / params.arm.control_dt))
        metrics = {"n_episodes": int(n_episodes), "valid_fraction": float(np.mean(out["valid"][:, -1])),
                   "all_steps": distance_summary(d), f"after_{SETTLE_S:g}s": distance_summary(d[:, settle:]),
                   "rest_arm_after_2s": distance_summary(rest[:, settle:]),
                   # the mean squared change of the action per control step (each entry in [-1, 1])
                   "mean_action_change": float(np.mean(out["action_change"][out["valid"]]))}
        rows = {"mean_distance_m": d.mean(1), f"mean_distance_after_{SETTLE_S:g}s_m": d[:, settle:].mean(1),
                "p95_distance_m": np.percentile(d, 95, axis=1), "within_5cm": np.mean(d < 0.05, 1),
                "within_10cm": np.mean(d < 0.10, 1), "valid": out["valid"][:, -1]}
        return EvalResult(metrics=metrics, rows=rows,
                          extra={"distance": d, "rest_distance": rest, "tip": out["tip"][:4],
                                 "target": out["target"][:4], "dt": params.arm.control_dt})

    def headline(self, metrics) -> tuple[str, float]:
        return f"within 5 cm after {SETTLE_S:g} s", metrics[f"after_{SETTLE_S:g}s"]["within_5cm"]

    def summary(self, metrics) -> str:
        a, b = metrics["all_steps"], metrics[f"after_{SETTLE_S:g}s"]
        return (f"eval on {metrics['n_episodes']} episodes: mean distance {100 * a['mean_m']:.1f} cm "
                f"(p95 {100 * a['p95_m']:.1f}), within 5 cm {100 * a['within_5cm']:.1f}% and 10 cm "
                f"{100 * a['within_10cm']:.1f}% of the time; after {SETTLE_S:g} s: mean {100 * b['mean_m']:.1f} cm, "
                f"within 5 cm {100 * b['within_5cm']:.1f}%, 10 cm {100 * b['within_10cm']:.1f}%; "
                f"mean squared action change per step {metrics.get('mean_action_change', float('nan')):.3f}")

    def figures(self, params: Track3DParams, result: EvalResult, out: Path) -> list[Path]:
        return figures.evaluation_figures(result.extra, out)

    # ------------------------------------------------------------------ drawing

    def render(self, params: Track3DParams, state: Track3DState, last_action) -> np.ndarray:
        return figures.render(params.arm.robot, state.q, state.target)

    def animate(self, path: Path, policy: Policy | None = None, **keys: Any) -> Path:
        """A GIF of one episode (reset key ``seed``) under ``policy`` (default: no tension)."""
        k = {**self.animation_keys, **keys}
        params = self.default_params()
        policy = policy or (lambda obs: jnp.zeros(obs.shape[:-1] + (self.action_size,)))
        out = jax.jit(lambda keys: rollout(self, params, policy, keys, record_q=True))(
            jax.random.PRNGKey(int(k["seed"]))[None])
        return figures.episode_gif(path, params.arm.robot, np.asarray(out["q"][0]), np.asarray(out["target"][0]),
                                   np.asarray(out["distance"][0]), params.arm.control_dt, fps=int(k["fps"]),
                                   dpi=int(k["dpi"]))


class Track3DMuscle(Track3D):
    """track3d actuated by distributed bending moments: 12 actions, six control points x two directions
    (``ArmParams.actuation = "muscle"``, up to ``moment_max`` N m each)."""

    name = "track3d_muscle"
    action_size = 12
    obs_size = 46  # and its 12 last actions

    def default_params(self) -> Track3DParams:
        return self._params("reachable")

    def _params(self, targets: str) -> Track3DParams:
        return make_params("muscle", targets, action_rate_weight=0.0)


def distance_summary(d: np.ndarray) -> dict[str, float]:
    """Statistics of tip-to-target distances (m) over all entries; a diverged step counts as infinite."""
    return {"mean_m": float(np.mean(d)), "median_m": float(np.median(d)), "p95_m": float(np.percentile(d, 95)),
            "within_5cm": float(np.mean(d < 0.05)), "within_10cm": float(np.mean(d < 0.10))}


def rollout(env: Track3D, params: Track3DParams, policy: Policy | Controller, keys: jax.Array,
            record_q: bool = False) -> dict:
    """Episodes from ``reset(keys[i])`` under ``policy(obs (n, k)) -> (n, action_size)``; jittable.

    Returns per step (n, T): ``distance``, ``valid`` (so far), ``tip`` and ``target``
    (n, T, 3), and with ``record_q`` the coordinates ``q`` (n, T + 1, n_dofs), the first
    the rest state.
    """
    def record(state, info):
        rec = {"distance": info["distance"], "tip": state.tip, "target": state.target,
               "action_change": info["action_change"]}
        return {**rec, "q": state.q} if record_q else rec

    first, rec = record_episodes(env, params, policy, keys, record)
    if record_q:
        rec["q"] = jnp.concatenate([first.q[:, None], rec["q"]], 1)
        rec["target"] = jnp.concatenate([first.target[:, None], rec["target"]], 1)
    return rec
