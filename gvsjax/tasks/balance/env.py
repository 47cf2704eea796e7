"""balance: swing the paper's arm up from hanging on a torque-driven base and hold it upright.

The arm (``gv.paper_arm(base="torque")``: 1 m, radius 5 cm, E = 5 MPa, planar,
gravity along world -y) hangs from a frictionless revolute base at the origin.
Every ``control_dt`` (0.05 s) the policy sets the base torque, action x
``torque_max`` (20 N m, below the 38.5 N m that holds the straight arm
horizontal: a swing-up, see ``BalanceParams``), held while the physics takes
``n_substeps`` ``ars443`` steps. Episodes last 10 s (200 steps) and start near
hanging at rest (base angle and rate uniform in +-``start_angle``, +-``start_rate``).

The *tilt* is the angle between the base-to-tip line and straight up, in [0, pi]
(pi: hanging). Observation (14,): cos and sin of the base angle, its rate / 10,
the curvature coefficients and their rates / 10, the tip's position (m) and
velocity / 5 (m/s), the tilt / pi, the last action and the fraction of the
episode left. Reward per step, in [0, 1]: u / (1 + (v / speed_scale)^2)
x (1 - action_cost a^2), v the tip's speed, with the uprightness
u = (1 - b)(1 - tilt / pi) + b exp(-(tilt / upright_deg)^2), b = ``upright_bonus``:
the first term pays for every degree of the swing, the second tells 1 degree
from 5, where the first hardly changes. Its factors only scale the uprightness
down, so no cost makes hanging still (reward 0) better than starting to swing;
additive costs do, and PPO then stays hanging. The speed factor makes spinning the
arm round and round (a mean of 1/2 at most, ~0.1 at its speed) a poor substitute
for standing still upright (1). Success (``evaluate``): the tilt stays below
``upright_deg`` (5 degrees) from some time on to the end, for at least 2 s.
A non-finite or out-of-bound state ends the episode with ``info["valid"] = False``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.kinematics import tip_state
from gvsjax.core.model import SoftLink
from gvsjax.core.simulation import simulate
from gvsjax.tasks.balance import figures
from gvsjax.tasks.balance.params import BalanceParams
from gvsjax.tasks.base import (
    Box,
    Controller,
    Environment,
    EvalResult,
    Policy,
    bounded,
    record_episodes,
    sanitize_action,
)

Q_BOUND = 50.0  # |curvature coefficient| (1/m) beyond which a state is treated as diverged
QD_BOUND = 1e3  # rad/s or 1/(m s)
MIN_HOLD_S = 2.0  # s: a success holds the arm upright for at least the episode's last seconds


@struct.dataclass
class BalanceState:
    q: jax.Array  # (3,) base angle (rad; 0 hangs, pi stands), curvature coefficients (1/m)
    qd: jax.Array  # (3,)
    tip: jax.Array  # (3,) m
    tip_velocity: jax.Array  # (3,) m/s
    action: jax.Array  # () the last action, in [-1, 1]
    step: jax.Array  # () int32, control steps taken


def tilt(tip: jax.Array) -> jax.Array:
    """Angle (rad, [0, pi]) between the base-to-tip line (the base at the origin) and world +y."""
    return jnp.arctan2(jnp.abs(tip[..., 0]), tip[..., 1])


def advance(params: BalanceParams, q, qd, torque, save_every: int | None = None):
    """One control step with the base ``torque`` (N m) held: the ``Trajectory``."""
    return simulate(params.arm, params.control_dt, n_steps=params.n_substeps, joint_force=torque, q0=q, qd0=qd,
                    save_every=save_every or params.n_substeps, integrator=params.integrator,
                    check_stability=False)


def observe(state: BalanceState, params: BalanceParams) -> jax.Array:
    """The observation of ``state`` (see the module docstring)."""
    theta, bend = state.q[0], state.q[1:]
    left = 1.0 - state.step / params.episode_steps
    return jnp.concatenate([jnp.stack([jnp.cos(theta), jnp.sin(theta), state.qd[0] / 10.0]), bend,
                            state.qd[1:] / 10.0, state.tip[:2], state.tip_velocity[:2] / 5.0,
                            jnp.stack([tilt(state.tip) / jnp.pi, state.action, jnp.asarray(left, float)])])


def reward(params: BalanceParams, tip, tip_velocity, action) -> jax.Array:
    """The uprightness scaled down by the tip's speed and the action (see the module docstring)."""
    speed2 = jnp.sum(tip_velocity**2) / params.speed_scale**2
    up, b = tilt(tip), params.upright_bonus
    upright = (1.0 - b) * (1.0 - up / jnp.pi) + b * jnp.exp(-((up / jnp.deg2rad(params.upright_deg)) ** 2))
    return upright / (1.0 + speed2) * (1.0 - params.action_cost * action**2)


def check(params: BalanceParams, episode_length: int) -> None:
    """The arm is a paper arm on a torque-driven base (three coordinates); raises ValueError otherwise."""
    robot = params.arm
    ok = (len(robot.links) == 1 and isinstance(robot.links[0], SoftLink) and robot.actuated == (0,)
          and not robot.prescribed and robot.n_dofs == 3)
    if not ok:
        raise ValueError("BalanceParams.arm must be gv.paper_arm(base='torque') with n_modes=2 (three coordinates: "
                         f"the base angle, free and torque-driven, and two curvature terms); got {robot.n_dofs} "
                         f"coordinates, actuated={robot.actuated}, prescribed={robot.prescribed}")
    if params.episode_steps != episode_length:
        raise ValueError(f"BalanceParams.episode_steps must be {episode_length} (got {params.episode_steps})")
    if not (isinstance(params.n_substeps, int) and params.n_substeps >= 1):
        raise ValueError(f"BalanceParams.n_substeps={params.n_substeps!r} must be an int >= 1")
    for name in ("torque_max", "control_dt", "upright_deg", "speed_scale"):
        value = getattr(params, name)
        if isinstance(value, (int, float)) and not value > 0:
            raise ValueError(f"BalanceParams.{name}={value!r} must be > 0")
    for name in ("start_angle", "start_rate"):
        value = getattr(params, name)
        if isinstance(value, (int, float)) and not value >= 0:
            raise ValueError(f"BalanceParams.{name}={value!r} must be >= 0")
    for name in ("action_cost", "upright_bonus"):
        value = getattr(params, name)
        if isinstance(value, (int, float)) and not 0 <= value <= 1:
            raise ValueError(f"BalanceParams.{name}={value!r} must be in [0, 1]")


class Balance(Environment):
    """Swing-up and balance of a soft arm on a torque-driven base."""

    name = "balance"
    obs_size = 14
    action_size = 1
    episode_length = 200
    rows_file = "eval_episodes.csv"
    animation_keys = {"seed": 0, "fps": 20, "dpi": 70}
    animates_policy = True
    ppo_defaults = dict(
        network="separate", actor_hidden=(64, 64), critic_hidden=(64, 64), activation="tanh",
        num_envs=512, num_steps=32, num_minibatches=8, update_epochs=4, gamma=0.99, gae_lambda=0.95,
        learning_rate=3e-4, clip_eps=0.2, ent_coef=0.0, init_log_std=-0.5, anneal_lr=True,
        finetune_fraction=0.0, max_grad_norm=0.5, total_episodes=20_000,
    )

    def default_params(self) -> BalanceParams:
        return BalanceParams()

    def observation_space(self, params=None) -> Box:
        low, high = np.full(self.obs_size, -np.inf), np.full(self.obs_size, np.inf)
        low[[0, 1, -3, -2, -1]], high[[0, 1, -3, -2, -1]] = -1.0, 1.0
        low[[-3, -1]] = 0.0
        return Box(low, high)

    def reset(self, key, params: BalanceParams):
        """Near hanging at rest: the base angle and rate uniform in +-start_angle, +-start_rate; straight."""
        check(params, self.episode_length)
        k_angle, k_rate = jax.random.split(key)
        q = jnp.zeros(3).at[0].set(params.start_angle * jax.random.uniform(k_angle, (), minval=-1.0, maxval=1.0))
        qd = jnp.zeros(3).at[0].set(params.start_rate * jax.random.uniform(k_rate, (), minval=-1.0, maxval=1.0))
        tip, tip_velocity = tip_state(params.arm, q, qd)
        state = BalanceState(q=q, qd=qd, tip=tip, tip_velocity=tip_velocity, action=jnp.zeros(()),
                             step=jnp.zeros((), jnp.int32))
        return observe(state, params), state

    def step(self, key, state: BalanceState, action, params: BalanceParams):
        """One control step (the torque held for ``control_dt``): ``(obs, state, reward, done, info)``."""
        check(params, self.episode_length)
        action, finite = sanitize_action(action, self.action_size)
        a = jnp.clip(action[0], -1.0, 1.0)
        tr = advance(params, state.q, state.qd, a * params.torque_max)
        q, qd, tip, tip_velocity = tr.q[-1], tr.qd[-1], tr.tip[-1], tr.tip_velocity[-1]
        valid = (finite & bounded(q[1:], Q_BOUND) & bounded(qd, QD_BOUND) & jnp.all(jnp.isfinite(q))
                 & jnp.all(jnp.isfinite(tip)))
        r = jnp.where(valid, reward(params, jnp.where(valid, tip, 0.0), jnp.where(valid, tip_velocity, 0.0), a), 0.0)
        keep = lambda new, old: jnp.where(valid, new, old)  # noqa: E731
        new = BalanceState(q=keep(q, state.q), qd=keep(qd, 0.0 * state.qd), tip=keep(tip, state.tip),
                           tip_velocity=keep(tip_velocity, 0.0 * state.tip_velocity), action=a,
                           step=state.step + 1)
        done = (new.step >= self.episode_length) | ~valid
        up = (tilt(new.tip) < jnp.deg2rad(params.upright_deg)).astype(float)
        info = {"tilt": tilt(new.tip), "upright": up, "valid": valid, "truncated": jnp.zeros((), bool)}
        return observe(new, params), new, r, done, info

    # ------------------------------------------------------------------ evaluation

    def evaluate(self, params: BalanceParams, policy: Policy | Controller, n_episodes: int, seed: int) -> EvalResult:
        """``n_episodes`` episodes from ``reset`` keys of ``seed``: success, time to upright, wobble."""
        run = jax.jit(lambda keys: rollout(self, params, policy, keys))
        out = {k: np.asarray(v) for k, v in run(jax.random.split(jax.random.PRNGKey(seed), n_episodes)).items()}
        s = upright_summary(out["tilt"], out["valid"], out["tip"], float(params.control_dt),
                            float(params.upright_deg))
        ok = s["success"]
        t_up = s["time_to_upright_s"]
        metrics = {"n_episodes": int(n_episodes), "valid_fraction": float(np.mean(out["valid"][:, -1])),
                   "success_rate": float(np.mean(ok)),
                   "time_to_upright_s": _stats(t_up[ok]), "wobble_rms_deg": _stats(s["wobble_rms_deg"][ok]),
                   "wobble_max_deg": _stats(s["wobble_max_deg"][ok]),
                   "tip_sway_rms_mm": _stats(s["tip_sway_rms_mm"][ok]),
                   f"last_{MIN_HOLD_S:g}s_rms_deg": _stats(s["last_rms_deg"][ok]),
                   f"last_{MIN_HOLD_S:g}s_max_deg": _stats(s["last_max_deg"][ok]),
                   "failures": {"never_upright": int(np.sum(~ok & ~s["ever_upright"])),
                                "upright_then_lost": int(np.sum(~ok & s["ever_upright"])),
                                "invalid": int(np.sum(~out["valid"][:, -1]))},
                   "mean_abs_torque_Nm": float(np.mean(np.abs(out["action"])) * params.torque_max)}
        rows = {"success": ok, "time_to_upright_s": t_up, "wobble_rms_deg": s["wobble_rms_deg"],
                "wobble_max_deg": s["wobble_max_deg"], "tip_sway_rms_mm": s["tip_sway_rms_mm"],
                "last_2s_rms_deg": s["last_rms_deg"], "last_2s_max_deg": s["last_max_deg"],
                "final_tilt_deg": np.degrees(out["tilt"][:, -1]), "min_tilt_deg": np.degrees(out["tilt"].min(1)),
                "valid": out["valid"][:, -1]}
        return EvalResult(metrics=metrics, rows=rows,
                          extra={"tilt": out["tilt"], "action": out["action"][:8], "success": ok,
                                 "time_to_upright": t_up, "dt": float(params.control_dt),
                                 "torque_max": float(params.torque_max), "upright_deg": float(params.upright_deg)})

    def headline(self, metrics) -> tuple[str, float]:
        return "success", metrics["success_rate"]

    def summary(self, metrics) -> str:
        t, w = metrics["time_to_upright_s"], metrics["wobble_rms_deg"]
        last = metrics[f"last_{MIN_HOLD_S:g}s_max_deg"]
        f = metrics["failures"]
        return (f"eval on {metrics['n_episodes']} episodes: success {100 * metrics['success_rate']:.1f}%, time to "
                f"upright median {t['median']:.2f} s (max {t['max']:.2f}), wobble rms median {w['median']:.2f} deg, "
                f"max tilt in the last {MIN_HOLD_S:g} s median {last['median']:.2f} deg (max {last['max']:.2f}); "
                f"failures: never upright {f['never_upright']}, upright then lost {f['upright_then_lost']}, "
                f"invalid {f['invalid']}")

    def figures(self, params: BalanceParams, result: EvalResult, out: Path) -> list[Path]:
        return figures.evaluation_figures(result.extra, out)

    # ------------------------------------------------------------------ drawing

    def render(self, params: BalanceParams, state: BalanceState, last_action) -> np.ndarray:
        torque_max = float(params.torque_max)
        return figures.render(params.arm, state.q, float(np.asarray(state.action)) * torque_max, torque_max)

    def animate(self, path: Path, policy: Policy | None = None, **keys: Any) -> Path:
        """A GIF of one episode (reset key ``seed``) under ``policy`` (default: no torque)."""
        k = {**self.animation_keys, **keys}
        params = self.default_params()
        policy = policy or (lambda obs: jnp.zeros(obs.shape[:-1] + (self.action_size,)))
        out = jax.jit(lambda keys: rollout(self, params, policy, keys, record_q=True))(
            jax.random.PRNGKey(int(k["seed"]))[None])
        return figures.episode_gif(path, params.arm, np.asarray(out["q"][0]), np.asarray(out["tilt"][0]),
                                   params.torque_max * np.asarray(out["action"][0]), float(params.torque_max),
                                   float(params.control_dt),
                                   float(params.upright_deg), fps=int(k["fps"]), dpi=int(k["dpi"]))


def _stats(x: np.ndarray) -> dict[str, float]:
    """Median, mean and max of ``x`` (NaN when empty)."""
    if x.size == 0:
        return {"median": float("nan"), "mean": float("nan"), "max": float("nan")}
    return {"median": float(np.median(x)), "mean": float(np.mean(x)), "max": float(np.max(x))}


def upright_summary(tilt_rad: np.ndarray, valid: np.ndarray, tip: np.ndarray, dt: float,
                    upright_deg: float) -> dict[str, np.ndarray]:
    """Per episode, from the tilt (n, T) after each control step and the tip (n, T, 3):

    ``success``: valid, and the tilt below ``upright_deg`` from some step on to the end,
    for at least ``MIN_HOLD_S``; ``time_to_upright_s``: the end of the first step of that
    final upright stretch (NaN without one); ``wobble_rms_deg`` / ``wobble_max_deg``: the
    tilt over it, ``tip_sway_rms_mm``: the rms of the tip's horizontal position over it;
    ``last_rms_deg`` / ``last_max_deg``: the tilt over the last ``MIN_HOLD_S`` (the final
    stretch's maximum is below ``upright_deg`` by its definition; this is the settled wobble);
    ``ever_upright``: the tilt went below ``upright_deg`` at some step.
    """
    n, T = tilt_rad.shape
    up = (tilt_rad < np.radians(upright_deg)) & valid
    # index of the first step of the final upright stretch (T: the last step is not upright)
    not_up_after = np.where(~up, np.arange(T)[None], -1).max(1)
    start = not_up_after + 1
    success = (start <= T - int(round(MIN_HOLD_S / dt))) & valid[:, -1]
    t_up = np.where(start < T, dt * (start + 1), np.nan)
    mask = np.arange(T)[None] >= start[:, None]
    count = np.maximum(mask.sum(1), 1)
    deg = np.degrees(tilt_rad)
    rms = np.where(start < T, np.sqrt(np.sum(np.where(mask, deg, 0.0) ** 2, 1) / count), np.nan)
    mx = np.where(start < T, np.max(np.where(mask, deg, -np.inf), 1), np.nan)
    sway = np.where(start < T, 1e3 * np.sqrt(np.sum(np.where(mask, tip[..., 0], 0.0) ** 2, 1) / count), np.nan)
    last = deg[:, T - int(round(MIN_HOLD_S / dt)):]
    return {"success": success, "time_to_upright_s": t_up, "wobble_rms_deg": rms, "wobble_max_deg": mx,
            "tip_sway_rms_mm": sway, "last_rms_deg": np.sqrt(np.mean(last**2, 1)), "last_max_deg": last.max(1),
            "ever_upright": up.any(1)}


def rollout(env: Balance, params: BalanceParams, policy: Policy | Controller, keys: jax.Array,
            record_q: bool = False) -> dict:
    """Episodes from ``reset(keys[i])`` under ``policy(obs (n, 14)) -> (n, 1)``; jittable.

    Returns per control step (n, T): ``tilt`` (rad), ``valid`` (so far), ``action`` (clipped),
    ``tip`` (n, T, 3), and with ``record_q`` the coordinates ``q`` (n, T + 1, 3), the first the start.
    """
    def record(state, info):
        rec = {"tilt": info["tilt"], "action": state.action, "tip": state.tip}
        return {**rec, "q": state.q} if record_q else rec

    first, rec = record_episodes(env, params, policy, keys, record)
    if record_q:
        rec["q"] = jnp.concatenate([first.q[:, None], rec["q"]], 1)
    return rec
