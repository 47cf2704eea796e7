"""reach_pose: bring the tip of the upright 3D soft arm to a target position *and* direction.

Each episode draws a target pose from the params' table of reachable poses
(``poses``): a tip position and the rod's tangent there, both of a static
equilibrium of the arm. The arm (``gv.soft_arm``) starts straight and at rest;
the policy acts every 0.1 s for 2 s (20 steps) through its two tendon groups
(``ReachPose``) or bending moments at six control points (``ReachPoseMuscle``,
whose targets are equilibria under muscle actions; ``gvsjax.tasks.actuation``).
What counts is the pose at the end: the position error (m) and the angle
between the tip's tangent and the target direction.

Neither actuation twists the rod, so a roll about the tip's own axis is not a
target here: the direction of the tip (two angles) and its position (three
coordinates) are.

Observation (40,) for the default arm: ``arm3d.arm_features`` (24: tip position,
velocity, scaled q and qd), the tip's tangent (3), the target position (3) and
direction (3), target minus tip for both (6, x ``ERROR_GAIN``), and the fraction of the episode
left. Reward per step (exp(-c) + exp(-precision c)) / 2 in (0, 1], with
c = k_position d + k_angle theta (theta in rad). A
non-finite or out-of-bound state ends the episode with ``info["valid"] = False``
and reward 0.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.kinematics import tip_frame
from gvsjax.tasks import arm3d
from gvsjax.tasks.base import Box, Controller, Environment, EvalResult, Policy, as_controller, sanitize_action
from gvsjax.tasks.reach_pose import figures
from gvsjax.tasks.reach_pose.params import ReachPoseParams
from gvsjax.tasks.reach_pose.poses import TRAIN_POSES, TRAIN_SEED, make_params

SUCCESS = ((0.05, 10.0), (0.02, 5.0))  # (m, deg): the pose is reached when both errors are below these
ERROR_GAIN = 10.0  # errors observed in units of 10 cm: the last centimetres stay visible to the policy


@struct.dataclass
class ReachPoseState:
    q: jax.Array  # (n,) strain coordinates
    qd: jax.Array  # (n,)
    tip: jax.Array  # (3,) m
    tip_velocity: jax.Array  # (3,) m/s
    tip_axis: jax.Array  # (3,) unit tangent at the tip
    target: jax.Array  # (3,) m
    target_axis: jax.Array  # (3,) unit
    index: jax.Array  # () int32, the target's row in the table
    step: jax.Array  # () int32, control steps taken


def angle(a: jax.Array, b: jax.Array) -> jax.Array:
    """The angle (rad) between unit vectors ``a`` and ``b``, accurate near 0 and pi."""
    return jnp.arctan2(jnp.linalg.norm(jnp.cross(a, b), axis=-1), jnp.sum(a * b, -1))


def observe(state: ReachPoseState, params: ReachPoseParams) -> jax.Array:
    """The observation of ``state`` (see the module docstring)."""
    left = 1.0 - state.step / params.episode_steps
    return jnp.concatenate([arm3d.arm_features(params.arm.robot, state.q, state.qd, state.tip, state.tip_velocity),
                            state.tip_axis, state.target, state.target_axis, ERROR_GAIN * (state.target - state.tip),
                            ERROR_GAIN * (state.target_axis - state.tip_axis), jnp.asarray(left, state.q.dtype)[None]])


def start(index: jax.Array, params: ReachPoseParams) -> ReachPoseState:
    """The straight arm at rest and the table's target ``index``."""
    robot = params.arm.robot
    q, qd = arm3d.rest(robot)
    R, tip = tip_frame(robot, q)
    return ReachPoseState(q=q, qd=qd, tip=tip, tip_velocity=jnp.zeros(3), tip_axis=R[:, 0],
                          target=params.position[index], target_axis=params.axis[index],
                          index=jnp.asarray(index, jnp.int32), step=jnp.zeros((), jnp.int32))


class ReachPose(Environment):
    """Closed-loop reaching of a 3D tip pose (position and direction)."""

    name = "reach_pose"
    obs_size = 40  # 6 + 2 x 9 strain coordinates + 16
    action_size = 4
    episode_length = 20
    animation_keys = {"seed": 0, "fps": 10, "dpi": 70}
    animates_policy = True
    ppo_defaults = {**arm3d.PPO_DEFAULTS, "total_episodes": 100_000}

    def default_params(self) -> ReachPoseParams:
        """The held-out table (``EVAL_POSES`` poses): what evaluation walks through."""
        return make_params()

    def train_params(self, variant: str = "") -> ReachPoseParams:
        """The training table (``TRAIN_POSES`` poses of another seed)."""
        if variant:
            super().train_params(variant)  # raises, naming the choices
        return make_params(TRAIN_POSES, TRAIN_SEED)

    def _check(self, params: ReachPoseParams) -> None:
        if params.position is None:
            raise ValueError("params has no target table; build it with gvsjax.tasks.reach_pose.make_params(...)")
        if params.action is not None and params.action.shape[-1:] != (self.action_size,):
            raise ValueError(f"the target table's actions have shape {params.action.shape}; {self.name} takes "
                             f"{self.action_size} (build the table with make_params(actuation=...) of its arm)")
        arm3d.check_task(self, params.arm, params.episode_steps, other_obs=16)

    def with_sim_dtype(self, params: ReachPoseParams, sim_dtype: str) -> ReachPoseParams:
        return dataclasses.replace(params, arm=arm3d.with_sim_dtype(params.arm, sim_dtype))

    def observation_space(self, params=None) -> Box:
        low, high = np.full(self.obs_size, -np.inf), np.full(self.obs_size, np.inf)
        low[-1], high[-1] = 0.0, 1.0
        return Box(low, high)

    def reset(self, key, params: ReachPoseParams):
        """The arm at rest and a target drawn uniformly from the table."""
        self._check(params)
        state = start(jax.random.randint(key, (), 0, params.position.shape[0]), params)
        return observe(state, params), state

    def step(self, key, state: ReachPoseState, action, params: ReachPoseParams):
        """One control step (the action's input held for ``control_dt``): ``(obs, state, reward, done, info)``."""
        self._check(params)
        action, finite = sanitize_action(action, self.action_size)
        robot = params.arm.robot
        tr = arm3d.control_step(params.arm, state.q, state.qd, action)[0]
        q, qd, tip, tip_velocity = tr.q[-1], tr.qd[-1], tr.tip[-1], tr.tip_velocity[-1]
        axis = tip_frame(robot, q)[0][:, 0]
        d = jnp.linalg.norm(tip - state.target)
        theta = angle(axis, state.target_axis)
        valid = finite & arm3d.healthy(robot, q, qd) & jnp.isfinite(d) & jnp.isfinite(theta)
        cost = jnp.where(valid, params.k_position * d + params.k_angle * theta, 0.0)
        reward = jnp.where(valid, 0.5 * (jnp.exp(-cost) + jnp.exp(-params.precision * cost)), 0.0)
        keep = lambda new, old: jnp.where(valid, new, old)  # noqa: E731
        new = dataclasses.replace(state, q=keep(q, state.q), qd=keep(qd, 0.0 * state.qd), tip=keep(tip, state.tip),
                            tip_velocity=keep(tip_velocity, 0.0 * state.tip_velocity),
                            tip_axis=keep(axis, state.tip_axis), step=state.step + 1)
        done = (new.step >= self.episode_length) | ~valid
        info = {"distance": d, "angle_deg": jnp.degrees(theta), "valid": valid, "truncated": jnp.zeros((), bool)}
        return observe(new, params), new, reward, done, info

    # ------------------------------------------------------------------ evaluation

    def evaluate(self, params: ReachPoseParams, policy: Policy | Controller, n_episodes: int, seed: int) -> EvalResult:
        """The first ``n_episodes`` targets of the (held-out) table, in order; ``seed`` is unused, the
        episodes being deterministic. Also scored: the open-loop baseline holding each target's own
        action (``action``) and the arm left at rest."""
        self._check(params)
        p = params.position.shape[0]
        if not 1 <= n_episodes <= p:
            raise ValueError(f"n_episodes={n_episodes} is invalid for reach_pose; expected 1..{p} (the poses "
                             "in the evaluation table)")
        index = jnp.arange(n_episodes)
        run = jax.jit(lambda i, open_loop: rollout(self, params, policy, i, open_loop=open_loop, record_q=True))
        pol, base = ({k: np.asarray(v) for k, v in run(index, jnp.asarray(o)).items()} for o in (False, True))
        rest_tip = tip_frame(params.arm.robot, arm3d.rest(params.arm.robot)[0])[1]
        rest_d = np.linalg.norm(np.asarray(params.position[index] - rest_tip), axis=-1)
        rest_a = np.degrees(np.asarray(angle(params.axis[index], jnp.array([0.0, 0.0, 1.0]))))
        metrics = {"n_episodes": int(n_episodes), "valid_fraction": float(np.mean(pol["valid"][:, -1])),
                   "policy": final_summary(pol), "held_action": final_summary(base),
                   "rest_arm": final_summary({"distance": rest_d[:, None], "angle_deg": rest_a[:, None],
                                              "valid": np.ones((n_episodes, 1), bool)})}
        d, a = _final(pol)
        rows = {"target_x": np.asarray(params.position[index, 0]), "target_y": np.asarray(params.position[index, 1]),
                "target_z": np.asarray(params.position[index, 2]), "final_distance_m": d, "final_angle_deg": a,
                "held_action_distance_m": _final(base)[0], "held_action_angle_deg": _final(base)[1],
                "valid": pol["valid"][:, -1]}
        return EvalResult(metrics=metrics, rows=rows,
                          extra={"policy": pol, "held_action": base, "dt": params.arm.control_dt})

    def headline(self, metrics) -> tuple[str, float]:
        return "within 5 cm & 10 deg", metrics["policy"]["within_5cm_10deg"]

    def summary(self, metrics) -> str:
        parts = []
        for name in ("policy", "held_action"):
            m = metrics[name]
            label = metrics.get("who", "policy") if name == "policy" else name.replace("_", " ")  # an MPC's: "MPC"
            parts.append(f"{label}: final distance {100 * m['distance_mean_m']:.1f} cm (median "
                         f"{100 * m['distance_median_m']:.1f}), angle {m['angle_mean_deg']:.1f} deg (median "
                         f"{m['angle_median_deg']:.1f}), within 5 cm & 10 deg {100 * m['within_5cm_10deg']:.1f}%, "
                         f"2 cm & 5 deg {100 * m['within_2cm_5deg']:.1f}%")
        return f"eval on {metrics['n_episodes']} held-out poses: " + "; ".join(parts)

    def figures(self, params: ReachPoseParams, result: EvalResult, out: Path) -> list[Path]:
        return figures.evaluation_figures(params, result.extra, out)

    # ------------------------------------------------------------------ drawing

    def render(self, params: ReachPoseParams, state: ReachPoseState, last_action) -> np.ndarray:
        return figures.render(params.arm.robot, state.q, state.target, state.target_axis)

    def animate(self, path: Path, policy: Policy | None = None, **keys: Any) -> Path:
        """A GIF of the held-out target ``seed`` under ``policy`` (default: its held action, open loop)."""
        k = {**self.animation_keys, **keys}
        params = self.default_params()
        index = jnp.array([int(k["seed"]) % params.position.shape[0]])
        zero = lambda obs: jnp.zeros(obs.shape[:-1] + (self.action_size,))  # noqa: E731
        out = jax.jit(lambda i: rollout(self, params, policy or zero, i, open_loop=policy is None,
                                        record_q=True))(index)
        i = int(index[0])
        return figures.episode_gif(path, params.arm.robot, np.asarray(out["q"][0]), np.asarray(params.position[i]),
                                   np.asarray(params.axis[i]), np.asarray(out["distance"][0]),
                                   np.asarray(out["angle_deg"][0]), params.arm.control_dt, fps=int(k["fps"]),
                                   dpi=int(k["dpi"]))


class ReachPoseMuscle(ReachPose):
    """reach_pose actuated by distributed bending moments: 12 actions, six control points x two
    directions (``ArmParams.actuation = "muscle"``). Its target tables are the arm's equilibria
    under muscle actions (the tendon tables hold poses the moments cannot reach)."""

    name = "reach_pose_muscle"
    action_size = 12

    def default_params(self) -> ReachPoseParams:
        return make_params(actuation="muscle")

    def train_params(self, variant: str = "") -> ReachPoseParams:
        if variant:
            super().train_params(variant)  # raises, naming the choices
        return make_params(TRAIN_POSES, TRAIN_SEED, actuation="muscle")


def _final(out: dict) -> tuple[np.ndarray, np.ndarray]:
    ok = out["valid"][:, -1]
    return np.where(ok, out["distance"][:, -1], np.inf), np.where(ok, out["angle_deg"][:, -1], np.inf)


def final_summary(out: dict) -> dict[str, float]:
    """Statistics of the final position (m) and angle (deg) errors; a diverged episode counts as infinite."""
    d, a = _final(out)
    p95 = lambda x: float(np.percentile(x, 95, method="inverted_cdf"))  # noqa: E731 (no interpolating infs)
    summary = {"distance_mean_m": float(np.mean(d)), "distance_median_m": float(np.median(d)), "distance_p95_m": p95(d),
               "angle_mean_deg": float(np.mean(a)), "angle_median_deg": float(np.median(a)), "angle_p95_deg": p95(a)}
    for dm, deg in SUCCESS:
        summary[f"within_{100 * dm:g}cm_{deg:g}deg"] = float(np.mean((d < dm) & (a < deg)))
    return summary


def rollout(env: ReachPose, params: ReachPoseParams, policy: Policy | Controller, index: jax.Array,
            open_loop: bool | jax.Array = False, record_q: bool = False) -> dict:
    """Episodes towards the table's targets ``index`` (n,) under ``policy(obs (n, k)) -> (n, action_size)``, or with
    ``open_loop`` (a bool, may be traced) each target's own held action; jittable.

    Returns per step (n, T): ``distance`` (m), ``angle_deg``, ``valid`` (so far), ``tip`` (n, T, 3), and with
    ``record_q`` the coordinates ``q`` (n, T + 1, n_dofs), the first the rest state.
    """
    state = jax.vmap(start, in_axes=(0, None))(index, params)
    obs = jax.vmap(observe, in_axes=(0, None))(state, params)
    keys = jax.random.split(jax.random.PRNGKey(0), index.shape[0])  # the task draws nothing while stepping
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))
    control = as_controller(policy)

    def one(carry, t):
        obs, state, memory, alive = carry
        action, memory = control.act(memory, obs, state, t)
        action = jnp.where(open_loop, params.action[state.index], action)
        obs, state, _, _, info = step(keys, state, action, params)
        alive = alive & info["valid"]
        rec = {"distance": info["distance"], "angle_deg": info["angle_deg"], "valid": alive, "tip": state.tip}
        if record_q:
            rec["q"] = state.q
        return (obs, state, memory, alive), rec

    init = (obs, state, control.init(obs, state), jnp.ones(index.shape[0], bool))
    _, rec = jax.lax.scan(one, init, jnp.arange(env.episode_length))
    rec = {k: jnp.swapaxes(v, 0, 1) for k, v in rec.items()}
    if record_q:
        rec["q"] = jnp.concatenate([state.q[:, None], rec["q"]], 1)
    return rec
