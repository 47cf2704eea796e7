"""reach_obstacles: bring the tip of the upright 3D soft arm to a target among obstacles.

The arm (``gv.soft_arm``, two tendon groups, ``gvsjax.tasks.arm3d``) starts
straight and at rest; the policy acts every 0.1 s for 3 s (30 steps). The
obstacles are capsules (``layouts``) the rod touches through the penalty contact
of ``gvsjax.core.contact``: it may press them, but a success allows at most
``tolerance`` (1 cm) of penetration at any instant of the episode, and the
tip must end within ``success_distance`` (5 cm) of the target.

Observation (44,) for the default arm: ``arm3d.arm_features`` (24), the target
(3), target minus tip (3, x ``ERROR_GAIN``), the scene's yaw as (cos, sin) (2),
the gap at each of the 11 contact samples (clipped to [-5, 20] cm, in units of
5 cm: the policy feels how close it is) and the fraction of the episode left; the
planar task (46,) also observes its last action. Reward per step
(exp(-k d) + exp(-precision k d)) / 2 minus ``penetration_weight`` x
min(depth / tolerance, 2), depth the deepest penetration during the step, minus
``action_rate_weight`` x the mean squared change of the action (the first
measured from the rest action, 0); the last step's closeness term counts
1 + ``final_weight`` times: in [-1 - 4 action_rate_weight, 1 + final_weight].
With ``residual_scale`` > 0 the actions are corrections to the open-loop ramp of
``reference_action`` (``ramped_reference``), not the tendon actions themselves
(``residual_rise`` 1: the corrections rise with the ramp too). A
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

from gvsjax.core.contact import report
from gvsjax.core.kinematics import tip_frame
from gvsjax.core.validation import concrete
from gvsjax.tasks import arm3d
from gvsjax.tasks.base import Box, Controller, Environment, EvalResult, Policy, record_episodes, sanitize_action
from gvsjax.tasks.reach_obstacles import figures
from gvsjax.tasks.reach_obstacles.layouts import POSTS_TARGET, capsules, posts, turn
from gvsjax.tasks.reach_obstacles.params import ReachObstaclesParams

ERROR_GAIN = 10.0  # target minus tip observed in units of 10 cm
GAP_RANGE = (-0.05, 0.2)  # m, the observed gaps are clipped to this
GAP_SCALE = 0.05  # m
SAVE_EVERY = 2  # ars443 steps between the penetration checks (12.5 ms: shorter than a bar's contact)
YAW_OBS = slice(30, 32)  # where (cos, sin) of the yaw sit in the observation
LEFT_OBS = 43  # where the fraction of the episode left sits
RAMP_S = 1.5  # s, the open-loop ramp baseline's rise: slow enough to pass the bars (docs/tasks/reach_obstacles.md)


@struct.dataclass
class ReachObstaclesState:
    q: jax.Array  # (n,) strain coordinates
    qd: jax.Array  # (n,)
    tip: jax.Array  # (3,) m
    tip_velocity: jax.Array  # (3,) m/s
    target: jax.Array  # (3,) m
    yaw: jax.Array  # () rad, the scene's turn about the base
    shift: jax.Array  # (m, 3) m, each capsule's move from its place in the layout (before the turn)
    gap: jax.Array  # (n_c,) m, each contact sample's gap at the last control step
    deepest: jax.Array  # () m, the deepest penetration so far (>= 0)
    step: jax.Array  # () int32
    last_action: jax.Array  # (4,) the tendon groups' last action (0 at rest)


def scene(params: ReachObstaclesParams, yaw, shift=0.0) -> arm3d.ArmParams:
    """The arm with the layout, each capsule moved by ``shift`` ((m, 3) m) and then all turned by
    ``yaw``, as its obstacles."""
    robot = params.arm.robot
    obstacles = capsules(turn(jnp.asarray(params.start) + shift, yaw), turn(jnp.asarray(params.end) + shift, yaw),
                         jnp.asarray(params.radius))
    contact = dataclasses.replace(robot.contact, obstacles=obstacles)
    return dataclasses.replace(params.arm, robot=dataclasses.replace(robot, contact=contact))


def gaps(params: ReachObstaclesParams, yaw, q, qd, shift=0.0) -> jax.Array:
    """(n_c,) the smallest gap (m) of each contact sample to the moved and turned layout."""
    return report(scene(params, yaw, shift).robot, q, qd, 0.0)[1]


def observe(state: ReachObstaclesState, params: ReachObstaclesParams, last_action: bool = False) -> jax.Array:
    """The observation of ``state`` (see the module docstring); ``last_action``: end with the x-z
    groups' last action (the planar task's)."""
    left = 1.0 - state.step / params.episode_steps
    g = jnp.clip(state.gap, *GAP_RANGE) / GAP_SCALE
    tail = [state.last_action[::2].astype(state.q.dtype)] if last_action else []
    return jnp.concatenate([arm3d.arm_features(params.arm.robot, state.q, state.qd, state.tip, state.tip_velocity),
                            state.target, ERROR_GAIN * (state.target - state.tip),
                            jnp.stack([jnp.cos(state.yaw), jnp.sin(state.yaw)]), g,
                            jnp.asarray(left, state.q.dtype)[None], *tail])


def start(key: jax.Array, params: ReachObstaclesParams) -> ReachObstaclesState:
    """The straight arm at rest, the scene turned by a drawn yaw, the target and the capsules drawn
    near their places."""
    robot = params.arm.robot
    k_yaw, k_target = jax.random.split(key)
    k_layout = jax.random.fold_in(key, 1)  # apart from the split: the yaw and target draws stay as they were
    yaw = params.yaw_range * jax.random.uniform(k_yaw, (), minval=-1.0, maxval=1.0)
    jitter = jnp.asarray(params.target_jitter) * jax.random.uniform(k_target, (3,), minval=-1.0, maxval=1.0)
    target = turn(jnp.asarray(params.target) + jitter, yaw)
    shift = jnp.asarray(params.layout_jitter) * jax.random.uniform(k_layout, jnp.shape(params.start), minval=-1.0,
                                                                   maxval=1.0)
    q, qd = arm3d.rest(robot)
    return ReachObstaclesState(q=q, qd=qd, tip=tip_frame(robot, q)[1], tip_velocity=jnp.zeros(3), target=target,
                               yaw=yaw, shift=shift, gap=gaps(params, yaw, q, qd, shift), deepest=jnp.zeros(()),
                               step=jnp.zeros((), jnp.int32), last_action=jnp.zeros(4, q.dtype))


def ramped_reference(action, cos, sin, k, dt: float, ramp_s: float) -> jax.Array:
    """(..., 4) the tendon-group ``action`` (given for yaw 0) turned by the scene's yaw (``cos``,
    ``sin``) at control step ``k`` (from 0) of a linear rise over ``ramp_s`` seconds (0: at once):
    step k holds (k + 1) dt / ramp_s of it."""
    a = jnp.asarray(action)
    groups = [(a[2 * g] * cos - a[2 * g + 1] * sin, a[2 * g] * sin + a[2 * g + 1] * cos) for g in range(len(a) // 2)]
    full = jnp.clip(jnp.stack([x for pair in groups for x in pair], -1), -1.0, 1.0)
    return full * rise(k, dt, ramp_s)[..., None] if ramp_s > 0 else full


def rise(k, dt: float, ramp_s: float) -> jax.Array:
    """The ramp's fraction at control step ``k`` (from 0) of a linear rise over ``ramp_s`` > 0 seconds."""
    return jnp.clip((jnp.asarray(k) + 1.0) * dt / ramp_s, 0.0, 1.0)


def applied(full, reference, yaw, k, params: ReachObstaclesParams) -> jax.Array:
    """(..., 4) the tendon-group action applied at control step ``k`` for the policy's ``full``
    (its four groups' actions): ``full`` itself, or with ``residual_scale`` s > 0 the correction
    clip(f turned + s (1 - w + w f) full, -1, 1) to the ramp of ``reference`` turned by ``yaw``,
    f the ramp's fraction and w ``residual_rise``."""
    dt = params.arm.control_dt
    r = rise(k, dt, RAMP_S)[..., None]
    gain = params.residual_scale * (1.0 - params.residual_rise + params.residual_rise * r)
    corrected = jnp.clip(r * ramped_reference(reference, jnp.cos(yaw), jnp.sin(yaw), k, dt, 0.0) + gain * full,
                         -1.0, 1.0)
    # a traced choice: another action mode (a baseline's absolute actions, a sweep) reuses the compiled step
    return jnp.where(jnp.asarray(params.residual_scale) == 0, full, corrected)


def held_policy(env: ReachObstacles, action=None, ramp_s: float = 0.0, params=None) -> Policy:
    """The open-loop baselines: ``action`` (4,) (default ``env.reference_action``; given for yaw 0)
    turned with the scene, as ``env``'s actions: applied at once and held (``ramp_s`` 0), or raised
    linearly to it over ``ramp_s`` seconds of ``params``' control steps (default: the task's) and held.
    They are tendon actions: run them with ``residual_scale`` 0 (``absolute``)."""
    a = env.reference_action if action is None else action
    p = params if params is not None else env.default_params()
    steps, dt = p.episode_steps, p.arm.control_dt

    def policy(obs):
        done = jnp.round((1.0 - obs[..., LEFT_OBS]) * steps)
        full = ramped_reference(a, obs[..., YAW_OBS.start], obs[..., YAW_OBS.start + 1], done, dt, ramp_s)
        return full[..., ::2] if env.planar else full

    return policy


def absolute(params: ReachObstaclesParams) -> ReachObstaclesParams:
    """``params`` whose actions are the tendon groups' own (no residual on the ramp)."""
    return dataclasses.replace(params, residual_scale=0.0)


class ReachObstacles(Environment):
    """Closed-loop reaching of a 3D target among obstacles, with contact."""

    name = "reach_obstacles"
    obs_size = 44  # 6 + 2 x 9 strain coordinates + 3 + 3 + 2 + 11 gaps + 1
    action_size = 4
    episode_length = 30
    animation_keys = {"seed": 0, "fps": 10, "dpi": 70}
    animates_policy = True
    # 24k episodes: what trains in 15 minutes on 2 cores (40k reach further: docs/tasks/reach_obstacles.md)
    ppo_defaults = {**arm3d.PPO_DEFAULTS, "num_envs": 256, "total_episodes": 24_000}
    train_sim_dtype = "float32"  # the contact step is the whole cost; evaluation stays float64
    planar = False  # True: two actions, the two groups' bending in the x-z plane
    # the statics' action whose equilibrium reaches the cage's target (``layouts``): the held baseline
    reference_action = (0.5, 0.0, 0.9, 0.0)

    def full_action(self, action: jax.Array) -> jax.Array:
        """The four tendon-group actions of the task's ``action_size`` ones."""
        if not self.planar:
            return action
        zero = jnp.zeros_like(action[..., 0])
        return jnp.stack([action[..., 0], zero, action[..., 1], zero], -1)

    def default_params(self) -> ReachObstaclesParams:
        # corrections to the ramp that rise with it, the last step weighed 11x: above the open-loop ramp
        # on every seed tried, where absolute actions ranged from far below it to level with it
        return ReachObstaclesParams(residual_scale=1.0, residual_rise=1.0, final_weight=10.0)

    def observe(self, state: ReachObstaclesState, params: ReachObstaclesParams) -> jax.Array:
        """The observation of ``state`` (the planar task's ends with its last action)."""
        return observe(state, params, self.planar)

    def _check(self, params: ReachObstaclesParams) -> None:
        arm3d.check(params.arm)
        if params.arm.actuation != "tendon":
            raise ValueError(f"ArmParams.actuation={params.arm.actuation!r} is invalid for {self.name}; expected "
                             "'tendon' (its actions are the tendon groups')")
        if arm3d.n_actions(params.arm) != 4 or params.arm.robot.n_dofs != 9 or params.episode_steps != 30:
            raise ValueError(f"{self.name}'s arm is gv.soft_arm's default (two tendon groups, 9 strain coordinates) "
                             f"and episode_steps=30; got {len(params.arm.robot.tendons)} tendons, "
                             f"{params.arm.robot.n_dofs} coordinates, episode_steps={params.episode_steps}")
        # traced params (a jitted reset) were checked where they were made
        if self.planar and concrete(params.yaw_range) and np.any(np.asarray(params.yaw_range, float) != 0.0):
            raise ValueError(f"yaw_range={params.yaw_range!r} is invalid for {self.name}: the planar task keeps its "
                             "plane (0 only)")
        n_c = params.arm.robot.contact.n_points if params.arm.robot.contact is not None else 0
        if n_c != 11:
            raise ValueError(f"reach_obstacles' arm needs 11 contact samples (its observation's gaps); got contact "
                             f"n_points={n_c} (use reach_obstacles.layouts.contact_arm())")
        shapes = tuple(np.shape(x) for x in (params.start, params.end, params.radius))
        if len(shapes[0]) != 2 or shapes[0][1] != 3 or shapes[1] != shapes[0] or shapes[2] != shapes[0][:1]:
            raise ValueError(f"the layout's start, end and radius must be (m, 3), (m, 3) and (m,); got {shapes}")
        for name in ("target_jitter", "layout_jitter"):
            jitter = getattr(params, name)
            if concrete(jitter) and not (np.shape(jitter) == (3,) and np.all(np.asarray(jitter, float) >= 0)):
                raise ValueError(f"{name}={jitter!r} is invalid for {self.name}; expected three numbers >= 0 (m)")
        for name, value, low in (("yaw_range", params.yaw_range, 0.0), ("action_rate_weight",
                                                                       params.action_rate_weight, 0.0),
                                 ("residual_scale", params.residual_scale, 0.0),
                                 ("final_weight", params.final_weight, 0.0),
                                 ("residual_rise", params.residual_rise, 0.0),
                                 ("tolerance", params.tolerance, 1e-6), ("success_distance", params.success_distance,
                                                                        1e-6)):
            if isinstance(value, (int, float)) and not value >= low:
                raise ValueError(f"{name}={value!r} is invalid for {self.name}; expected >= {low}")
        if isinstance(params.residual_rise, (int, float)) and not params.residual_rise <= 1.0:
            raise ValueError(f"residual_rise={params.residual_rise!r} is invalid for {self.name}; expected in [0, 1]")

    def with_sim_dtype(self, params: ReachObstaclesParams, sim_dtype: str) -> ReachObstaclesParams:
        return dataclasses.replace(params, arm=arm3d.with_sim_dtype(params.arm, sim_dtype))

    def observation_space(self, params=None) -> Box:
        low, high = np.full(self.obs_size, -np.inf), np.full(self.obs_size, np.inf)
        gap = slice(YAW_OBS.stop, LEFT_OBS)  # the 11 gaps sit between the yaw and the time left
        low[gap], high[gap] = GAP_RANGE[0] / GAP_SCALE, GAP_RANGE[1] / GAP_SCALE
        low[YAW_OBS], high[YAW_OBS] = -1.0, 1.0
        low[LEFT_OBS], high[LEFT_OBS] = 0.0, 1.0
        low[LEFT_OBS + 1:], high[LEFT_OBS + 1:] = -1.0, 1.0  # the planar task's last action
        return Box(low, high)

    def reset(self, key, params: ReachObstaclesParams):
        """The arm at rest; the scene's yaw and the target drawn from ``key``."""
        self._check(params)
        state = start(key, params)
        return self.observe(state, params), state

    def step(self, key, state: ReachObstaclesState, action, params: ReachObstaclesParams):
        """One control step (tensions held for ``control_dt``): ``(obs, state, reward, done, info)``."""
        self._check(params)
        action, finite = sanitize_action(action, self.action_size)
        arm = scene(params, state.yaw, state.shift)
        full = applied(self.full_action(action), self.reference_action, state.yaw, state.step, params)
        tr = arm3d.control_step(arm, state.q, state.qd, full, save_every=SAVE_EVERY)[0]
        q, qd, tip, tip_velocity = tr.q[-1], tr.qd[-1], tr.tip[-1], tr.tip_velocity[-1]
        depth = jnp.maximum(-jnp.min(tr.contact_gap), 0.0)
        d = jnp.linalg.norm(tip - state.target)
        valid = finite & arm3d.healthy(arm.robot, q, qd) & jnp.isfinite(d) & jnp.isfinite(depth)
        shaped = 0.5 * (jnp.exp(-params.k * d) + jnp.exp(-params.precision * params.k * d))
        shaped = shaped * (1.0 + params.final_weight * (state.step + 1 >= self.episode_length))
        rate = jnp.sum((full - state.last_action) ** 2) / self.action_size  # the planar zeros add nothing
        penalty = (params.penetration_weight * jnp.minimum(depth / params.tolerance, 2.0)
                   + params.action_rate_weight * rate)
        reward = jnp.where(valid, shaped - penalty, 0.0)
        keep = lambda new, old: jnp.where(valid, new, old)  # noqa: E731
        new = dataclasses.replace(state, q=keep(q, state.q), qd=keep(qd, 0.0 * state.qd), tip=keep(tip, state.tip),
                                  tip_velocity=keep(tip_velocity, 0.0 * state.tip_velocity),
                                  gap=keep(tr.contact_gap[-1], state.gap),
                                  deepest=keep(jnp.maximum(state.deepest, depth), state.deepest), step=state.step + 1,
                                  last_action=keep(full.astype(state.last_action.dtype), state.last_action))
        done = (new.step >= self.episode_length) | ~valid
        info = {"distance": d, "depth": depth, "valid": valid, "truncated": jnp.zeros((), bool)}
        return self.observe(new, params), new, reward, done, info

    # ------------------------------------------------------------------ evaluation

    def evaluate(self, params: ReachObstaclesParams, policy: Policy | Controller, n_episodes: int,
                 seed: int) -> EvalResult:
        """``n_episodes`` episodes from ``reset`` keys of ``seed`` under ``policy`` and under two
        open-loop baselines, the ``reference_action`` turned with the scene: applied at once and held,
        and raised over ``RAMP_S`` then held."""
        self._check(params)
        keys = jax.random.split(jax.random.PRNGKey(seed), n_episodes)
        run = jax.jit(lambda k, pol: rollout(self, params, pol, k), static_argnums=1)
        pol = {k: np.asarray(v) for k, v in run(keys, policy).items()}
        run = jax.jit(lambda k, pol: rollout(self, absolute(params), pol, k), static_argnums=1)
        held, ramped = ({k: np.asarray(v) for k, v in run(keys, p).items()}
                        for p in (held_policy(self, params=params), held_policy(self, ramp_s=RAMP_S, params=params)))
        metrics = {"n_episodes": int(n_episodes), "valid_fraction": float(np.mean(pol["valid"][:, -1])),
                   "policy": final_summary(pol, params), "held_action": final_summary(held, params),
                   "ramped_action": final_summary(ramped, params)}
        d, deepest = _final(pol)
        rows = {"target_x": pol["target"][:, 0], "target_y": pol["target"][:, 1], "target_z": pol["target"][:, 2],
                "yaw": pol["yaw"], "final_distance_m": d, "deepest_penetration_m": deepest,
                "success": _success(pol, params),
                "held_action_distance_m": _final(held)[0], "ramped_action_distance_m": _final(ramped)[0],
                "ramped_action_success": _success(ramped, params), "valid": pol["valid"][:, -1]}
        return EvalResult(metrics=metrics, rows=rows, extra={"policy": pol, "held_action": held,
                                                             "ramped_action": ramped, "dt": params.arm.control_dt})

    def headline(self, metrics) -> tuple[str, float]:
        return "success", metrics["policy"]["success"]

    def summary(self, metrics) -> str:
        parts = []
        for name in ("policy", "held_action", "ramped_action"):
            m = metrics[name]
            label = metrics.get("who", "policy") if name == "policy" else name.replace("_", " ")  # an MPC's: "MPC"
            parts.append(f"{label}: success {100 * m['success']:.1f}% (tip within 5 cm "
                         f"{100 * m['reached']:.1f}%, penetration beyond 1 cm {100 * m['penetrated']:.1f}%), final "
                         f"distance {100 * m['distance_mean_m']:.1f} cm (median {100 * m['distance_median_m']:.1f}), "
                         f"deepest penetration median {1000 * m['deepest_median_m']:.1f} mm")
        return f"eval on {metrics['n_episodes']} episodes: " + "; ".join(parts)

    def figures(self, params: ReachObstaclesParams, result: EvalResult, out: Path) -> list[Path]:
        pol = result.extra["policy"]
        robots = [scene(params, y, s).robot for y, s in zip(pol["yaw"][:3], pol["shift"][:3])]
        return figures.evaluation_figures(params, result.extra, out, robots)

    # ------------------------------------------------------------------ drawing

    def render(self, params: ReachObstaclesParams, state: ReachObstaclesState, last_action) -> np.ndarray:
        return figures.render(scene(params, state.yaw, state.shift).robot, state.q, state.target)

    def animate(self, path: Path, policy: Policy | None = None, **keys: Any) -> Path:
        """A GIF of the episode of ``seed`` under ``policy`` (default: the held reference action)."""
        k = {**self.animation_keys, **keys}
        params = self.default_params() if policy is not None else absolute(self.default_params())
        out = jax.jit(lambda key: rollout(self, params, policy or held_policy(self),
                                          key[None]))(jax.random.PRNGKey(int(k["seed"])))
        robot = scene(params, out["yaw"][0], out["shift"][0]).robot
        return figures.episode_gif(path, robot, np.asarray(out["q"][0]), np.asarray(out["target"][0]),
                                   np.asarray(out["distance"][0]), np.asarray(out["depth"][0]),
                                   params.arm.control_dt, fps=int(k["fps"]), dpi=int(k["dpi"]))


def _final(out: dict) -> tuple[np.ndarray, np.ndarray]:
    ok = out["valid"][:, -1]
    return np.where(ok, out["distance"][:, -1], np.inf), np.where(ok, out["depth"].max(axis=1), np.inf)


def _success(out: dict, params: ReachObstaclesParams) -> np.ndarray:
    d, deepest = _final(out)
    return (d < params.success_distance) & (deepest <= params.tolerance)


def final_summary(out: dict, params: ReachObstaclesParams) -> dict[str, float]:
    """Success (tip within ``success_distance`` at the end, never deeper than ``tolerance``), the
    share penetrating deeper, the final distance (m) and the deepest penetration (m); a diverged
    episode counts as a failure (infinitely far), not as a penetration."""
    d, deepest = _final(out)
    p95 = lambda x: float(np.percentile(x, 95, method="inverted_cdf"))  # noqa: E731 (no interpolating infs)
    reached, clean = d < params.success_distance, deepest <= params.tolerance
    return {"success": float(np.mean(reached & clean)), "reached": float(np.mean(reached)),
            "penetrated": float(np.mean(np.isfinite(deepest) & ~clean)), "distance_mean_m": float(np.mean(d)),
            "distance_median_m": float(np.median(d)), "distance_p95_m": p95(d),
            "deepest_median_m": float(np.median(deepest)), "deepest_p95_m": p95(deepest)}


def rollout(env: ReachObstacles, params: ReachObstaclesParams, policy: Policy | Controller, keys: jax.Array) -> dict:
    """Episodes from ``reset(keys[i])`` under ``policy``; jittable. Returns numpy arrays: per step
    (n, T) ``distance`` (m), ``depth`` (m, the step's deepest penetration), ``valid`` (so far); per
    episode ``target`` (n, 3), ``yaw`` (n,) and ``shift`` (n, m, 3); ``q`` (n, T + 1, n_dofs), the
    first the rest state."""
    first, rec = record_episodes(env, params, policy, keys,
                                 lambda s, info: {"distance": info["distance"], "depth": info["depth"], "q": s.q})
    rec["q"] = jnp.concatenate([first.q[:, None], rec["q"]], 1)
    return {**rec, "target": first.target, "yaw": first.yaw, "shift": first.shift}


class ReachObstacles2D(ReachObstacles):
    """The planar variant: the posts layout in the x-z plane, two actions (each group's bending in
    that plane)."""

    name = "reach_obstacles_2d"
    obs_size = 46  # and its last action
    action_size = 2
    planar = True
    reference_action = (0.7, 0.0, 1.0, 0.0)

    def default_params(self) -> ReachObstaclesParams:
        lay = {k: jnp.asarray(v) for k, v in posts().items()}
        # corrections of at most 0.3 to the rising ramp: larger ones rush the arm in and chatter
        return ReachObstaclesParams(start=lay["start"], end=lay["end"], radius=lay["radius"], target=POSTS_TARGET,
                                    target_jitter=(0.03, 0.0, 0.03), action_rate_weight=0.1,
                                    residual_scale=0.3, residual_rise=1.0, final_weight=10.0)
