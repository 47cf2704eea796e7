"""throw3d: the paper's throw from a base that also turns about the vertical.

One throw per episode at a 3D target anywhere on a court around the shooter.
Action (3,) in [-1, 1], clipped, mapped affinely to the motion time T in
[0.5, 3] s, the release fraction delta in [0.85, 1] and the yaw at release
psi_R in [-198, 198] deg (``throw.action_to_physical``). Observation (3,): the target's
horizontal distance, azimuth / pi and height, scaled to [-1, 1]
(``targets.observe``). Cost c (m): the exact closest distance between the
flight and the target; reward exp(-k c), k = 2.2, as basketball. Single-step
episodes. A non-finite action (played as the box centre) or throw gives
``info["valid"] = False`` and reward 0.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.robots import paper_arm_3d
from gvsjax.tasks.ballistics import miss_metrics
from gvsjax.tasks.base import (
    ROBOT_MATERIAL,
    Box,
    Controller,
    Environment,
    EvalResult,
    Policy,
    bounded,
    policy_only,
    sanitize_action,
    scale_payload,
)
from gvsjax.tasks.basketball import Basketball
from gvsjax.tasks.throw3d import figures, throw
from gvsjax.tasks.throw3d.params import BALL_WEIGHT, Throw3DParams
from gvsjax.tasks.throw3d.targets import make_params, observe, sample_target
from gvsjax.utils import plots

RELEASE_SPEED_BOUND = 100.0  # m/s per component: beyond it a throw counts as diverged
# training draws half its targets uniformly over the court's volume: the far and high targets,
# thrown only by the fastest swings, are otherwise rare (evaluation draws action-uniform)
TRAIN_TARGETS = "mixed"


@struct.dataclass
class Throw3DState:
    target: jax.Array  # (3,) m
    source_action: jax.Array  # (3,) a grid action whose path passes through the target
    step: jax.Array  # int32


class Throw3D(Environment):
    """The 3D throw."""

    name = "throw3d"
    accepts_controller = False  # an open-loop task: evaluated with a policy
    obs_size = 3
    action_size = 3
    episode_length = 1
    train_variants = ("action", "volume", "mixed")
    rows_file = "eval_throws.csv"
    animation_keys = {"T": 1.0, "delta": 0.95, "yaw": 90.0, "frames": 60, "fps": 20, "dpi": 80}
    randomizable = {**ROBOT_MATERIAL, "payload": scale_payload}
    # basketball's recipe (one throw per step, large batches, heavy reuse, KL-adaptive rate,
    # mirrored pairs) with a third action, and twice its episodes: what fits in 15 minutes on 2 cores
    ppo_defaults = {**Basketball.ppo_defaults, "total_episodes": 2_400_000}
    train_sim_dtype = Basketball.train_sim_dtype

    def default_params(self) -> Throw3DParams:
        """The task with its target tables (``make_params()``, cached)."""
        return make_params()

    def train_params(self, variant: str = "") -> Throw3DParams:
        """Targets drawn by ``variant`` ("action", "volume" or "mixed"; empty: ``TRAIN_TARGETS``)."""
        if variant and variant not in self.train_variants:
            super().train_params(variant)  # raises, naming the choices
        return make_params(target_sampling=variant or TRAIN_TARGETS)

    def observation_space(self, params=None) -> Box:
        return Box(-np.ones(3), np.ones(3))

    def reset(self, key, params: Throw3DParams):
        """A new reachable target: ``(obs (3,), state)``; table look-up, no simulation."""
        target, source = sample_target(key, params)
        state = Throw3DState(target=target, source_action=source, step=jnp.zeros((), jnp.int32))
        return observe(target, params), state

    def step(self, key, state: Throw3DState, action, params: Throw3DParams):
        """Throw with ``action`` (3,): ``(obs, state, reward, done=True, info)``.

        ``info``: ``cost`` (m), the physical ``T``, ``delta`` and ``yaw`` (rad), ``valid``, ``truncated``.
        """
        action, finite = sanitize_action(action, self.action_size)
        cost, (T, delta, psi, p0, v0) = throw.throw_cost(params, action, state.target)
        valid = (finite & jnp.isfinite(cost) & jnp.all(jnp.isfinite(p0)) & bounded(v0, RELEASE_SPEED_BOUND))
        reward = jnp.where(valid, jnp.exp(-params.k * jnp.where(valid, cost, 0.0)), 0.0)
        state = dataclasses.replace(state, step=state.step + 1)
        info = {"cost": cost, "T": T, "delta": delta, "yaw": psi, "valid": valid,
                "truncated": jnp.zeros((), bool)}
        return observe(state.target, params), state, reward, jnp.ones((), bool), info

    def evaluate(self, params: Throw3DParams, policy: Policy | Controller, n_episodes: int, seed: int) -> EvalResult:
        """Deterministic throws at ``n_episodes`` targets drawn by ``reset`` keys of ``seed``;
        a diverged throw counts as an infinite miss."""
        policy = policy_only(self, policy)
        keys = jax.random.split(jax.random.PRNGKey(seed), n_episodes)

        @jax.jit
        def run(keys):
            obs, state = jax.vmap(self.reset, in_axes=(0, None))(keys, params)
            action = policy(obs)
            _, _, _, _, info = jax.vmap(self.step, in_axes=(0, 0, 0, None))(keys, state, action, params)
            return state.target, info

        target, info = run(keys)
        target = np.asarray(target)
        miss = np.where(np.asarray(info["valid"]), np.asarray(info["cost"], float), np.inf)
        phys = {k: np.asarray(info[k]) for k in ("T", "delta", "yaw")}
        rows = {"target_x": target[:, 0], "target_y": target[:, 1], "target_z": target[:, 2],
                "T": phys["T"], "delta": phys["delta"], "yaw_deg": np.degrees(phys["yaw"]), "miss_m": miss}
        return EvalResult(metrics=miss_metrics(miss), rows=rows, extra={"target": target, "miss": miss, **phys})

    def summary(self, metrics) -> str:
        return (f"eval on {metrics['n_targets']} targets: "
                f"success<10cm {100 * metrics['success_rate_10cm']:.1f}%, "
                f"<1cm {100 * metrics['within_1cm']:.1f}%, median {100 * metrics['median_m']:.2f} cm, "
                f"p95 {100 * metrics['p95_m']:.2f} cm, max {100 * metrics['max_m']:.2f} cm")

    def figures(self, params: Throw3DParams, result: EvalResult, out: Path) -> list[Path]:
        """error_histogram.png, throw3d_court.png (misses over the court) and throw3d.png
        (the throw at the median miss)."""
        r = result.extra
        i = int(np.argsort(r["miss"])[len(r["miss"]) // 2])
        return [plots.error_histogram(r["miss"], out / "error_histogram.png", title="miss"),
                figures.court_figure(params, r["target"], r["miss"], out / "throw3d_court.png"),
                figures.throw_figure(params, r["target"][i], float(r["T"][i]), float(r["delta"][i]),
                                     float(r["yaw"][i]), out / "throw3d.png", miss_m=float(r["miss"][i]))]

    def render(self, params: Throw3DParams, state: Throw3DState, last_action) -> np.ndarray:
        """Top view of the court, the target and the last throw's flight."""

        def draw(ax):
            rho_max = params.court[1]
            a = np.linspace(0.0, 2.0 * np.pi, 200)
            for r in params.court[:2]:
                ax.plot(r * np.cos(a), r * np.sin(a), color="0.6", ls="--", lw=1)
            ax.plot(*np.asarray(state.target)[:2], "rx", ms=10, label="target")
            if last_action is not None:
                T, delta, psi = throw.action_to_physical(jnp.asarray(last_action), params)
                arm, ball = figures.release_drawing(params, float(T), float(delta), float(psi))
                ax.plot(arm[:, 0], arm[:, 1], "g-", lw=3, label="arm at release")
                ax.plot(ball[:, 0], ball[:, 1], "b-", label="ball")
            ax.set(xlim=(-rho_max, rho_max), ylim=(-rho_max, rho_max), aspect="equal", xlabel="x [m]",
                   ylabel="y [m]")
            ax.legend(loc="upper right", fontsize=7)

        return plots.rgb_image(draw)

    def animate(self, path: Path, **keys: Any) -> Path:
        """A throw's GIF: keys T (s), delta, yaw (the yaw at release psi_R, deg), frames, fps, dpi."""
        k = {**self.animation_keys, **keys}
        params = Throw3DParams(arm=paper_arm_3d(tip_force=BALL_WEIGHT))
        ranges = {"T": params.T_range, "delta": params.delta_range,
                  "yaw": tuple(np.degrees(params.yaw_range))}
        for name, (lo, hi) in ranges.items():
            if not (isinstance(k[name], (int, float)) and np.isfinite(k[name]) and lo <= k[name] <= hi):
                raise ValueError(f"{name}={k[name]!r} is out of range; allowed: [{lo:g}, {hi:g}]")
        if not (isinstance(k["frames"], int) and k["frames"] >= 2):
            raise ValueError(f"frames={k['frames']!r} must be an int >= 2")
        return figures.throw_gif(path, params, k["T"], k["delta"], np.radians(k["yaw"]), frames=k["frames"],
                                 fps=k["fps"], dpi=k["dpi"])
