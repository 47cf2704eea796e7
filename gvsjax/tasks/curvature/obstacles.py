"""obstacles_2d and obstacles_3d: reach a fixed target among obstacles, touched through penalty contact.

As published (Choi & Tong, arXiv 2511.06667): 51 steps of 0.5 s, each adding 0.25 x
action to the turning angles; reward as follow_target's, with no penalty for touching.
* obstacles_2d: a planar arm (bending in the x-z plane, 5 actions) among six posts of
  radius 0.1 m, bars along y through (x, z) = (0.2, 0.12), (0.6, 0.12), (0.4, 0),
  (0.4, 0.37), (0.4, 0.57), (0.4, 0.77); target (0.8, 0, 0.15). Observation (47,):
  turning angles (5), node x-z positions and velocities (40), the target's x, z.
* obstacles_3d: eight capsules of radius 3 cm and length 1 m drawn anew each episode
  (``random_capsules``, the benchmark's sampler: centres uniform in x in [0.3, 0.6],
  y in [-0.6, 0.6], z in [-0.1, 0.8], directions uniform, both ends in that box,
  >= 1.5 cm apart); target (0.8, 0, 0.35). Observation (121,): turning angles (10),
  node positions and velocities (60), the target (3), the capsules' ends (48). (The
  benchmark's repository also holds a fixed layout of twelve capsules; its code and
  published results use the random ones.)
Success: the tip within 5 cm of the target at the end, never deeper than 1 cm into an
obstacle at any saved instant (``save_every`` substeps apart).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.contact import Contact, Penalty
from gvsjax.core.curvature_arm import curvature_arm
from gvsjax.core.obstacles import Capsule
from gvsjax.tasks.curvature import rewards
from gvsjax.tasks.curvature.base import CurvatureTask, EpisodeState
from gvsjax.tasks.curvature.control import ArmControl
from gvsjax.tasks.curvature.layouts import POSTS_2D, random_capsules

# the rod's contact law (per metre of rod): about 1 cm deep under the arm's own weight pressed on a bar;
# the penalty is explicit, so it sets the substeps (docs/tasks_benchmark.md)
PENALTY = Penalty(stiffness=3e5, damping=1e3)
N_CONTACT = 3  # contact samples per link (its ends and middle): 21 along the arm, <= 10 cm apart
TOLERANCE = 0.01  # m of penetration a successful episode may not exceed


def contact_arm(planar: bool) -> ArmControl:
    robot = curvature_arm(planar=planar)
    robot = dataclasses.replace(robot, contact=Contact(obstacles=(), rod=PENALTY, n_points=N_CONTACT))
    return ArmControl(robot=robot, step_scale=0.25, control_dt=0.5, n_substeps=40, save_every=5)


def with_capsules(robot, ends: jax.Array, radius) -> object:
    caps = tuple(Capsule(start=ends[i, 0], end=ends[i, 1], radius=radius) for i in range(ends.shape[0]))
    return dataclasses.replace(robot, contact=robot.contact.replace(obstacles=caps))


@struct.dataclass
class ObstacleParams:
    arm: ArmControl = struct.field(default_factory=lambda: contact_arm(False))
    target: tuple = (0.8, 0.0, 0.35)  # m
    radius: float = 0.03  # m, the capsules'
    n_obstacles: int = struct.field(pytree_node=False, default=8)
    episode_steps: int = struct.field(pytree_node=False, default=51)


class _Obstacles(CurvatureTask):
    episode_length = 51

    def _check(self, params: ObstacleParams) -> None:
        super()._check(params)
        if params.arm.robot.contact is None:
            raise ValueError(f"{self.name}.arm.robot needs a contact model (obstacles.contact_arm)")

    def after(self, key, state: EpisodeState, params: ObstacleParams):
        d = jnp.linalg.norm(state.node_p[-1] - state.target)
        return state, rewards.reach_reward(d), {"distance": d}

    def robot_for(self, state: EpisodeState, params: ObstacleParams):
        return with_capsules(params.arm.robot, state.obstacles, params.radius)

    def _success(self, out: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        d = np.where(out["valid"][:, -1], out["distance"][:, -1], np.inf)
        deepest = out["deepest"][:, -1]
        return d, deepest, (d < 0.05) & (deepest <= TOLERANCE)

    def physical_metrics(self, out: dict, params: ObstacleParams) -> dict:
        d, deepest, ok = self._success(out)
        return {"success": float(np.mean(ok)), "final_distance_m": {"mean": float(np.mean(d)),
                                                                     "median": float(np.median(d))},
                "within_5cm": float(np.mean(d < 0.05)), "penetrating": float(np.mean(deepest > TOLERANCE)),
                "deepest_m": {"median": float(np.median(deepest)), "max": float(np.max(deepest))}}

    def episode_rows(self, out: dict, params: ObstacleParams) -> dict:
        d, deepest, ok = self._success(out)
        return {"final_distance_m": d, "deepest_penetration_m": deepest, "success": ok}

    def summary(self, metrics) -> str:
        r = metrics["discounted_return_average"]["mean"]
        return (f"eval on {metrics['n_episodes']} episodes: discounted return {r:.1f}; success "
                f"{100 * metrics['success']:.1f}% (within 5 cm {100 * metrics['within_5cm']:.1f}%, deeper than 1 cm "
                f"{100 * metrics['penetrating']:.1f}%), median final distance "
                f"{100 * metrics['final_distance_m']['median']:.1f} cm")


class Obstacles2D(_Obstacles):
    """The planar arm among six posts."""

    name = "obstacles_2d"
    published_return = 40.0
    obs_size = 47
    action_size = 5
    directions = 1
    planar = True
    ppo_defaults = {**CurvatureTask.ppo_defaults, "total_episodes": 20_000}
    sac_defaults = {**CurvatureTask.sac_defaults, "total_episodes": 4_000}

    def default_params(self) -> ObstacleParams:
        return ObstacleParams(arm=contact_arm(True), target=(0.8, 0.0, 0.15), radius=0.1, n_obstacles=6)

    def start(self, key, params: ObstacleParams) -> dict:
        return {"target": jnp.asarray(params.target, float), "obstacles": jnp.asarray(POSTS_2D)}

    def task_obs(self, state: EpisodeState, params: ObstacleParams) -> jax.Array:
        return state.target[::2]


class Obstacles3D(_Obstacles):
    """The 3D arm among eight random capsules."""

    name = "obstacles_3d"
    published_return = 28.0
    obs_size = 121
    action_size = 10
    ppo_defaults = {**CurvatureTask.ppo_defaults, "total_episodes": 20_000}
    sac_defaults = {**CurvatureTask.sac_defaults, "total_episodes": 4_000}

    def default_params(self) -> ObstacleParams:
        return ObstacleParams()

    def _check(self, params: ObstacleParams) -> None:
        super()._check(params)
        if params.n_obstacles != 8:
            raise ValueError(f"obstacles_3d's n_obstacles must be 8 (the observation holds their ends); got "
                             f"{params.n_obstacles}")

    def start(self, key, params: ObstacleParams) -> dict:
        return {"target": jnp.asarray(params.target, float), "obstacles": random_capsules(key, params.n_obstacles)}

    def task_obs(self, state: EpisodeState, params: ObstacleParams) -> jax.Array:
        return jnp.concatenate([state.target, state.obstacles.reshape(-1)])
