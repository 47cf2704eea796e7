"""ik_4d: bring the benchmark arm's tip to a position and a yaw, by natural curvature and twist.

As published (Choi & Tong, arXiv 2511.06667): a fixed target uniform in x, y in
[-0.6, 0.6] m, z in [0.3, 0.9] m, and a tip orientation of yaw psi uniform in
[-pi/2, pi/2] about the vertical (roll = pitch = 0), for the benchmark's tip frame
[m1, m2, t] (``rewards.benchmark_frame``; at rest a yaw of pi). 101 steps of 0.1 s,
15 actions: the 10 bending ones, then a rest twist per control point. Reward
-d^2 - 0.5 o^2 with the distance and orientation bonuses (``rewards.pose_reward``),
o = 1 - <q_tip, q_target>^2.

Observation (86,), the published one: turning angles (10) and twists (5), node
positions and velocities (60), the target position (3), then the target's and the
tip frame's quaternions (x, y, z, w), 4 each, with SciPy's sign (``rewards.quaternion``;
their fields, concatenated in alphabetical order). ``orientation_obs="frame"``
(``ik_4d_frame``, 89 values) gives instead (cos psi, sin psi) and the tip frame's
rotation matrix (9), which has no sign flip: SciPy's quaternion changes sign where its
largest component changes.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.curvature_arm import curvature_arm
from gvsjax.tasks.curvature import rewards
from gvsjax.tasks.curvature.base import CurvatureTask, EpisodeState
from gvsjax.tasks.curvature.control import ArmControl


@struct.dataclass
class IKParams:
    arm: ArmControl = struct.field(default_factory=lambda: ArmControl(robot=curvature_arm(twist=True)))
    box_low: tuple = (-0.6, -0.6, 0.3)  # m
    box_high: tuple = (0.6, 0.6, 0.9)  # m
    yaw_range: float = float(np.pi / 2)  # rad, the target's yaw is uniform in [-yaw_range, yaw_range]
    episode_steps: int = struct.field(pytree_node=False, default=101)
    # the orientations observed: "quaternion" (the published 86 values) or "frame" (89: cos, sin, R)
    orientation_obs: str = struct.field(pytree_node=False, default="quaternion")


def orientation_error(state: EpisodeState) -> jax.Array:
    """o = 1 - <q_tip, q_target>^2 of the tip's benchmark frame and the target's yaw."""
    return rewards.orientation_distance(rewards.benchmark_frame(state.tip_R), rewards.yaw_frame(state.goal))


class IK4D(CurvatureTask):
    """Reach a target position and tip yaw."""

    name = "ik_4d"
    obs_size = 86
    action_size = 15
    episode_length = 101
    published_return = 197.0
    twist = True
    ppo_defaults = {**CurvatureTask.ppo_defaults, "total_episodes": 20_000}
    sac_defaults = {**CurvatureTask.sac_defaults, "total_episodes": 20_000}

    orientation_obs = "quaternion"

    def default_params(self) -> IKParams:
        return IKParams(orientation_obs=self.orientation_obs)

    def _check(self, params: IKParams) -> None:
        super()._check(params)
        if params.orientation_obs != self.orientation_obs:
            raise ValueError(f"{self.name} observes orientation_obs={self.orientation_obs!r} ({self.obs_size} values); "
                             f"got IKParams.orientation_obs={params.orientation_obs!r} (use "
                             f"{'ik_4d' if params.orientation_obs == 'quaternion' else 'ik_4d_frame'})")

    def start(self, key, params: IKParams) -> dict:
        k_pos, k_yaw = jax.random.split(key)
        low, high = jnp.asarray(params.box_low), jnp.asarray(params.box_high)
        return {"target": jax.random.uniform(k_pos, (3,), minval=low, maxval=high),
                "goal": jax.random.uniform(k_yaw, (), minval=-params.yaw_range, maxval=params.yaw_range)}

    def after(self, key, state: EpisodeState, params: IKParams):
        d = jnp.linalg.norm(state.node_p[-1] - state.target)
        o = orientation_error(state)
        return state, rewards.pose_reward(d, o), {"distance": d, "orientation": o}

    def task_obs(self, state: EpisodeState, params: IKParams) -> jax.Array:
        frame = rewards.benchmark_frame(state.tip_R)
        if params.orientation_obs == "frame":
            return jnp.concatenate([state.target, jnp.stack([jnp.cos(state.goal), jnp.sin(state.goal)]),
                                    frame.reshape(-1)])
        return jnp.concatenate([state.target, rewards.yaw_quaternion(state.goal), rewards.quaternion(frame)])

    def _final(self, out: dict) -> tuple[np.ndarray, np.ndarray]:
        d = np.where(out["valid"][:, -1], out["distance"][:, -1], np.inf)
        angle = np.degrees(2.0 * np.arcsin(np.sqrt(np.clip(out["orientation"][:, -1], 0.0, 1.0))))
        return d, np.where(out["valid"][:, -1], angle, np.inf)

    def physical_metrics(self, out: dict, params: IKParams) -> dict:
        d, angle = self._final(out)
        return {"final_distance_m": {"mean": float(np.mean(d)), "median": float(np.median(d)),
                                     "p95": float(np.percentile(d, 95))},
                "final_orientation_deg": {"mean": float(np.mean(angle)), "median": float(np.median(angle)),
                                          "p95": float(np.percentile(angle, 95))},
                "within_2cm_5deg": float(np.mean((d < 0.02) & (angle < 5.0))),
                "within_5cm_10deg": float(np.mean((d < 0.05) & (angle < 10.0)))}

    def episode_rows(self, out: dict, params: IKParams) -> dict:
        d, angle = self._final(out)
        return {"final_distance_m": d, "final_orientation_deg": angle}

    def summary(self, metrics) -> str:
        r = metrics["discounted_return_average"]["mean"]
        d, a = metrics["final_distance_m"], metrics["final_orientation_deg"]
        return (f"eval on {metrics['n_episodes']} episodes: discounted return {r:.1f}; final error median "
                f"{100 * d['median']:.2f} cm, {a['median']:.2f} deg; within 2 cm & 5 deg "
                f"{100 * metrics['within_2cm_5deg']:.1f}%, 5 cm & 10 deg {100 * metrics['within_5cm_10deg']:.1f}%")


class IK4DFrame(IK4D):
    """ik_4d observing the target's yaw as (cos, sin) and the tip frame as a rotation matrix (89 values)."""

    name = "ik_4d_frame"
    obs_size = 89
    orientation_obs = "frame"
