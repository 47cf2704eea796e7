"""What the four benchmark tasks share: the episode state, one control step, the observation of
the arm, and evaluation by the benchmark's discounted returns.

The observation of the arm is the benchmark's: the current turning angles (and twists),
then the positions and velocities (m, m/s, world frame; x and z only when planar) of the
nodes 0.1, 0.2, ..., 1.0 m along the arm. Each task appends its target (and obstacles).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.tasks.base import Controller, Environment, EvalResult, Policy, record_episodes, sanitize_action
from gvsjax.tasks.curvature import control, figures
from gvsjax.tasks.curvature.control import N_POINTS, ArmControl

PPO_DEFAULTS: dict[str, Any] = dict(
    network="separate", actor_hidden=(256, 256), critic_hidden=(256, 256), activation="tanh",
    num_envs=512, num_steps=32, num_minibatches=8, update_epochs=4, gamma=0.99, gae_lambda=0.95,
    learning_rate=3e-4, clip_eps=0.2, ent_coef=0.0, init_log_std=-0.5, anneal_lr=True,
    finetune_fraction=0.0, max_grad_norm=0.5,
)
# SAC (``algo=sac``): the published algorithm, with fewer envs and a smaller network and batch than
# theirs (500 envs, 3 x 256, batch 1024) so that the gradient steps do not dominate two CPU cores
SAC_DEFAULTS: dict[str, Any] = dict(num_envs=128, hidden=(256, 256), batch_size=256, updates_per_iteration=2)
# Their network and batch, with their gradient steps per env step (4 per 500): slower per env step on
# two cores, but it learns more from each; a task takes it where it reached the higher return
SAC_PUBLISHED_NETWORK: dict[str, Any] = dict(hidden=(256, 256, 256), batch_size=1024, updates_per_iteration=1)


@struct.dataclass
class EpisodeState:
    q: jax.Array  # (n,) strain coordinates
    qd: jax.Array  # (n,)
    kappa: jax.Array  # (5, directions) rad, the turning angles
    twist: jax.Array  # (5,) rad (0 without twist control)
    node_p: jax.Array  # (10, 3) m
    node_v: jax.Array  # (10, 3) m/s
    tip_R: jax.Array  # (3, 3) the tip section's world rotation (columns: tangent, local y, local z)
    target: jax.Array  # (3,) m
    target_velocity: jax.Array  # (3,) m/s (0 for a fixed target)
    goal: jax.Array  # () rad, the target's yaw (IK) or 0
    obstacles: jax.Array  # (m, 2, 3) m, capsule ends (m = 0 without obstacles)
    deepest: jax.Array  # () m, the deepest penetration into an obstacle so far
    step: jax.Array  # () int32


class CurvatureTask(Environment):
    """A benchmark task: subclasses set the layout, ``default_params`` (with an ``arm``:
    ``ArmControl``), ``start`` (the target part of a new episode), ``after`` (the target's
    step and the reward) and ``task_obs``."""

    directions: ClassVar[int] = 2
    twist: ClassVar[bool] = False
    planar: ClassVar[bool] = False
    rows_file = "eval_episodes.csv"
    animation_keys = {"seed": 0, "fps": 10, "dpi": 70}
    animates_policy = True
    ppo_defaults = PPO_DEFAULTS
    sac_defaults = SAC_DEFAULTS
    time_limit = True  # the published episodes end by a timeout; their SAC bootstraps through it
    failure_reward = -10.0  # theirs: a failed simulation (or a reward below -10) ends the episode with -10
    return_discount = control.GAMMA
    # the published SAC's final discounted return (averaged over start steps), read from their results figure
    published_return: ClassVar[float]
    # append the tip-to-target vector to the observation (the benchmark's observation leaves it out)
    relative_obs: ClassVar[bool] = False
    # training simulates in float32 (1.5x the steps/s, the same tip error at 2 substeps:
    # experiments/studies/curvature_substeps.py); evaluation in float64
    train_sim_dtype = "float32"

    # ------------------------------------------------------------------ hooks

    def start(self, key, params) -> dict:
        """Fields of ``EpisodeState`` for a new episode's target (and obstacles)."""
        raise NotImplementedError

    def after(self, key, state: EpisodeState, params) -> tuple[EpisodeState, jax.Array, dict]:
        """After the arm's step: the state with the target moved, the reward, and info entries."""
        raise NotImplementedError

    def task_obs(self, state: EpisodeState, params) -> jax.Array:
        raise NotImplementedError

    def robot_for(self, state: EpisodeState, params):
        """The robot simulated in ``state`` (default: the params'; random obstacles are set here)."""
        return params.arm.robot

    # ------------------------------------------------------------------ the functional API

    def _check(self, params) -> None:
        control.check(params.arm, self.directions, self.twist, self.name)
        if params.episode_steps != self.episode_length:
            raise ValueError(f"{self.name}'s episode_steps is {self.episode_length}; got {params.episode_steps}")

    def with_sim_dtype(self, params, sim_dtype: str):
        return dataclasses.replace(params, arm=control.with_sim_dtype(params.arm, sim_dtype))

    def arm_obs(self, state: EpisodeState) -> jax.Array:
        p, v = state.node_p, state.node_v
        if self.planar:
            p, v = p[:, ::2], v[:, ::2]
        parts = [state.kappa.reshape(-1)] + ([state.twist] if self.twist else []) + [p.reshape(-1), v.reshape(-1)]
        return jnp.concatenate(parts)

    def observe(self, state: EpisodeState, params) -> jax.Array:
        parts = [self.arm_obs(state), self.task_obs(state, params)]
        if self.relative_obs:
            error = state.target - state.node_p[-1]
            parts.append(error[::2] if self.planar else error)
        return jnp.concatenate(parts)

    def reset(self, key, params):
        """The arm straight and at rest, upright, with zero rest curvature; the task's target."""
        self._check(params)
        robot = params.arm.robot
        q = jnp.zeros(robot.n_dofs)
        blank = EpisodeState(**_blank(q, self.directions, self.start(key, params)))
        p, v, R = control.nodes(self.robot_for(blank, params), q, q)
        state = dataclasses.replace(blank, node_p=p, node_v=v, tip_R=R)
        return self.observe(state, params), state

    def step(self, key, state: EpisodeState, action, params):
        """One control step: ``(obs, state, reward, done, info)``."""
        self._check(params)
        action, finite = sanitize_action(action, self.action_size)
        arm: ArmControl = params.arm
        robot = self.robot_for(state, params)
        kappa, twist = control.apply(arm, state.kappa, state.twist, action)
        sim_arm = dataclasses.replace(arm, robot=robot)
        tr = control.advance(sim_arm, state.q, state.qd, control.rest_values(robot, state.kappa, state.twist),
                             control.rest_values(robot, kappa, twist))
        q, qd = tr.q[-1], tr.qd[-1]
        p, v, R = control.nodes(robot, q, qd)
        depth = jnp.maximum(-jnp.min(tr.contact_gap), 0.0) if tr.contact_gap.size else jnp.zeros(())
        valid = finite & control.healthy(q, qd) & jnp.all(jnp.isfinite(p))
        keep = lambda new, old: jnp.where(valid, new, old)  # noqa: E731
        moved = dataclasses.replace(state, q=keep(q, state.q), qd=keep(qd, 0.0 * state.qd), kappa=kappa, twist=twist,
                              node_p=keep(p, state.node_p), node_v=keep(v, 0.0 * state.node_v),
                              tip_R=keep(R, state.tip_R), deepest=jnp.maximum(state.deepest, depth),
                              step=state.step + 1)
        new, reward, info = self.after(key, moved, params)
        valid = valid & (reward >= self.failure_reward)  # NaN fails too
        reward = jnp.where(valid, reward, self.failure_reward)
        done = (new.step >= self.episode_length) | ~valid
        info = {**info, "valid": valid, "truncated": jnp.zeros((), bool), "depth": depth, "reward": reward}
        return self.observe(new, params), new, reward, done, info

    # ------------------------------------------------------------------ evaluation

    def rollout(self, params, policy: Policy | Controller, keys: jax.Array, record_q: bool = False) -> dict:
        """Episodes from ``reset(keys[i])``: per step (n, T) reward, distance, and the task's info."""
        def record(state, info):
            rec = {k: info[k] for k in ("reward", "distance", "orientation", "depth") if k in info}
            rec.update(tip=state.node_p[..., -1, :], target=state.target, deepest=state.deepest)
            return {**rec, "q": state.q, "kappa": state.kappa} if record_q else rec

        first, rec = record_episodes(self, params, policy, keys, record)
        rec["first"] = first
        return rec

    def evaluate(self, params, policy: Policy | Controller, n_episodes: int, seed: int) -> EvalResult:
        keys = jax.random.split(jax.random.PRNGKey(seed), n_episodes)
        out = jax.jit(lambda k: self.rollout(params, policy, k))(keys)
        out = {k: np.asarray(v) for k, v in out.items() if k != "first"}
        returns = control.discounted_returns(out["reward"], out["valid"])
        metrics: dict[str, Any] = {
            "n_episodes": int(n_episodes), "valid_fraction": float(np.mean(out["valid"][:, -1])),
            "failed_fraction": float(np.mean(~out["valid"][:, -1])),
            "actions": "deterministic (the policy's mean)", "gamma": control.GAMMA,
            "discounted_return_average": _stats(returns["average"]),
            "discounted_return_start": _stats(returns["start"]),
            "return": _stats(returns["undiscounted"]),
        }
        metrics.update(self.physical_metrics(out, params))
        rows = {"discounted_return_average": returns["average"], "discounted_return_start": returns["start"],
                "return": returns["undiscounted"], **self.episode_rows(out, params), "valid": out["valid"][:, -1]}
        extra = {"out": {k: v[:8] for k, v in out.items()}, "rows": rows, "dt": params.arm.control_dt,
                 "distance": np.where(out["valid"], out["distance"], np.inf)}
        return EvalResult(metrics=metrics, rows=rows, extra=extra)

    def physical_metrics(self, out: dict, params) -> dict:
        return {}

    def episode_rows(self, out: dict, params) -> dict:
        return {}

    def headline(self, metrics) -> tuple[str, float]:
        return "discounted return", metrics["discounted_return_average"]["mean"]

    def figures(self, params, result: EvalResult, out: Path) -> list[Path]:
        return figures.evaluation_figures(self, result.extra, out)

    # ------------------------------------------------------------------ drawing

    def render(self, params, state: EpisodeState, last_action) -> np.ndarray:
        return figures.render(self, params, state)

    def animate(self, path: Path, policy: Policy | None = None, **keys: Any) -> Path:
        """A GIF of one episode (reset key ``seed``) under ``policy`` (default: no action)."""
        k = {**self.animation_keys, **keys}
        params = self.default_params()
        policy = policy or (lambda obs: jnp.zeros(obs.shape[:-1] + (self.action_size,)))
        out = jax.jit(lambda keys: self.rollout(params, policy, keys, record_q=True))(
            jax.random.PRNGKey(int(k["seed"]))[None])
        return figures.episode_gif(self, params, path, out, fps=int(k["fps"]), dpi=int(k["dpi"]))


def _blank(q: jax.Array, directions: int, fields: dict) -> dict:
    """An episode state at rest with the given target fields (node fields as zeros)."""
    base = dict(q=q, qd=jnp.zeros_like(q), kappa=jnp.zeros((N_POINTS, directions)),
                twist=jnp.zeros(N_POINTS), node_p=jnp.zeros((10, 3)), node_v=jnp.zeros((10, 3)),
                tip_R=jnp.eye(3), target=jnp.zeros(3), target_velocity=jnp.zeros(3), goal=jnp.zeros(()),
                obstacles=jnp.zeros((0, 2, 3)), deepest=jnp.zeros(()), step=jnp.zeros((), jnp.int32))
    return {**base, **fields}


def _stats(x: np.ndarray) -> dict[str, float]:
    return {"mean": float(np.mean(x)), "median": float(np.median(x)), "std": float(np.std(x)),
            "p05": float(np.percentile(x, 5)), "p95": float(np.percentile(x, 95))}
