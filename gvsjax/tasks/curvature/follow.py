"""follow_target: keep the tip of the benchmark arm on a target moving through a box.

As published (Choi & Tong, arXiv 2511.06667): the target starts uniform in x, y in
[-0.6, 0.6] m, z in [0.3, 0.9] m, moving at 0.5 m/s with the benchmark's random
heading; each step, a velocity component whose coordinate has left the box flips, and
otherwise the heading changes with probability 0.025; then the target moves by v dt.
The arm acts every 0.1 s for 501 steps (their episode: 500 steps after the first
observation, the last one included), through 10 natural-curvature actions.
Reward per step -d^2 + 0.5 [5 cm < d < 10 cm] + 2 [d < 5 cm], d the tip-to-target
distance after the step (m). Observation (76,): turning angles (10), node positions
and velocities (60), the target's position and velocity (6).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.tasks.curvature import rewards
from gvsjax.tasks.curvature.base import SAC_PUBLISHED_NETWORK, CurvatureTask, EpisodeState
from gvsjax.tasks.curvature.control import ArmControl

SETTLE_S = 2.0  # s: the tracking metrics skip the first seconds, when the arm leaves its rest pose


@struct.dataclass
class FollowParams:
    arm: ArmControl = struct.field(default_factory=ArmControl)
    box_low: tuple = (-0.6, -0.6, 0.3)  # m
    box_high: tuple = (0.6, 0.6, 0.9)  # m
    speed: float = 0.5  # m/s
    turn_probability: float = 0.025  # per control step
    episode_steps: int = struct.field(pytree_node=False, default=501)


class FollowTarget(CurvatureTask):
    """Closed-loop tracking of a moving 3D target by natural-curvature control."""

    name = "follow_target"
    obs_size = 76
    action_size = 10
    episode_length = 501
    published_return = 100.0
    ppo_defaults = {**CurvatureTask.ppo_defaults, "total_episodes": 4_000}
    sac_defaults = {**CurvatureTask.sac_defaults, **SAC_PUBLISHED_NETWORK, "total_episodes": 10_000}

    def default_params(self) -> FollowParams:
        return FollowParams()

    def start(self, key, params: FollowParams) -> dict:
        k_pos, k_dir = jax.random.split(key)
        low, high = jnp.asarray(params.box_low), jnp.asarray(params.box_high)
        return {"target": jax.random.uniform(k_pos, (3,), minval=low, maxval=high),
                "target_velocity": rewards.target_direction(k_dir, params.speed)}

    def after(self, key, state: EpisodeState, params: FollowParams):
        target, velocity = rewards.move_target(key, state.target, state.target_velocity,
                                               jnp.asarray(params.box_low), jnp.asarray(params.box_high),
                                               params.speed, params.turn_probability, params.arm.control_dt)
        d = jnp.linalg.norm(state.node_p[-1] - target)
        moved = dataclasses.replace(state, target=target, target_velocity=velocity)
        return moved, rewards.reach_reward(d), {"distance": d}

    def planning_params(self, params: FollowParams) -> FollowParams:
        """A planner predicts the target straight on (bouncing off the walls): its turns are random."""
        return dataclasses.replace(params, turn_probability=0.0)

    def task_obs(self, state: EpisodeState, params: FollowParams) -> jax.Array:
        return jnp.concatenate([state.target, state.target_velocity])

    def physical_metrics(self, out: dict, params: FollowParams) -> dict:
        d = np.where(out["valid"], out["distance"], np.inf)
        settle = int(round(SETTLE_S / params.arm.control_dt))
        late = d[:, settle:]
        return {"mean_distance_m": float(np.mean(late)), "median_distance_m": float(np.median(late)),
                "within_5cm": float(np.mean(late < 0.05)), "within_10cm": float(np.mean(late < 0.10)),
                "settle_s": SETTLE_S}

    def episode_rows(self, out: dict, params: FollowParams) -> dict:
        settle = int(round(SETTLE_S / params.arm.control_dt))
        d = np.where(out["valid"], out["distance"], np.inf)[:, settle:]
        return {"mean_distance_m": d.mean(1), "within_5cm": np.mean(d < 0.05, 1), "within_10cm": np.mean(d < 0.1, 1)}

    def summary(self, metrics) -> str:
        r = metrics["discounted_return_average"]["mean"]
        return (f"eval on {metrics['n_episodes']} episodes: discounted return (gamma {metrics['gamma']}, averaged "
                f"over start steps) {r:.1f}; after {metrics['settle_s']:g} s the tip is within 5 cm "
                f"{100 * metrics['within_5cm']:.1f}% and 10 cm {100 * metrics['within_10cm']:.1f}% of the time, "
                f"mean distance {100 * metrics['mean_distance_m']:.1f} cm")
