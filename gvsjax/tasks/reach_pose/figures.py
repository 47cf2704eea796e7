"""reach_pose's drawings: errors over time, final errors, final poses in 3D, a frame, an episode GIF."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from gvsjax.core.kinematics import backbone
from gvsjax.core.model import Robot
from gvsjax.tasks.draw3d import backbones, draw_arm, setup_axes
from gvsjax.utils import plots

ARROW = 0.15  # m, the drawn length of a target direction


def errors_over_time(policy: dict, held: dict, dt: float, path, who: str = "policy") -> Path:
    """Median and 5-95% band of the position and angle errors at each control step, for the
    policy and for the open-loop held action."""
    t = dt * np.arange(1, policy["distance"].shape[1] + 1)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, key, scale, unit in ((axes[0], "distance", 100.0, "position error [cm]"),
                                 (axes[1], "angle_deg", 1.0, "angle error [deg]")):
        what = unit.split()[0]
        for out, color, label in ((policy, "tab:blue", who), (held, "tab:orange", "target's own action, held")):
            x = scale * np.where(out["valid"], out[key], np.nan)
            ax.fill_between(t, np.nanpercentile(x, 5, 0), np.nanpercentile(x, 95, 0), alpha=0.2, color=color)
            ax.plot(t, np.nanmedian(x, 0), color=color, lw=2, label=f"{label}: {what}, median")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(unit)
        ax.set_yscale("log")
        ax.grid(alpha=0.3, which="both")
        ax.legend(loc="lower left", fontsize=8, title="shaded: 5-95%", title_fontsize=8)
    fig.suptitle(f"reaching {policy['distance'].shape[0]} held-out poses")
    return plots.save(fig, path)


def final_errors(policy: dict, held: dict, path, who: str = "policy") -> Path:
    """Final position vs angle error of every episode, with the success boxes."""
    fig, ax = plt.subplots(figsize=(6, 5))
    for out, color, label in ((held, "tab:orange", "target's own action, held"), (policy, "tab:blue", who)):
        ok = out["valid"][:, -1]
        ax.plot(100 * out["distance"][ok, -1], out["angle_deg"][ok, -1], ".", ms=3, alpha=0.5, color=color,
                label=label)
    for cm, deg in ((5, 10), (2, 5)):
        ax.plot([cm, cm, 1e-3], [1e-3, deg, deg], color="tab:green", lw=1, ls=":", label=f"{cm} cm & {deg} deg")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(0.05, 100)
    ax.set_ylim(0.05, 100)
    ax.set_xlabel("final position error [cm]")
    ax.set_ylabel("final angle error [deg]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title("after 2 s (dotted: 5 cm & 10 deg, 2 cm & 5 deg)")
    return plots.save(fig, path)


def final_poses(robot: Robot, q_final: np.ndarray, target: np.ndarray, axis: np.ndarray, path) -> Path:
    """A few episodes' final arms (k, n) with their target poses (k, 3) and directions (k, 3)."""
    shapes = backbones(robot, q_final)
    fig = plt.figure(figsize=(6, 6))
    ax = fig.add_subplot(projection="3d")
    for i in range(len(shapes)):
        draw_arm(ax, shapes[i], color=f"C{i}", label=f"episode {i + 1}")
        draw_target(ax, target[i], axis[i], color=f"C{i}")
    setup_axes(ax)
    ax.set_title("final arms and target poses (arrows)")
    return plots.save(fig, path)


def evaluation_figures(params, extra: dict, out: Path) -> list[Path]:
    """The figures of an evaluation (``ReachPose.evaluate``'s ``extra``)."""
    pol, held = extra["policy"], extra["held_action"]
    k = min(4, pol["q"].shape[0])
    who = extra.get("who", "policy")
    return [errors_over_time(pol, held, extra["dt"], out / "reach_errors.png", who),
            final_errors(pol, held, out / "reach_final_errors.png", who),
            final_poses(params.arm.robot, pol["q"][:k, -1], np.asarray(params.position[:k]),
                        np.asarray(params.axis[:k]), out / "reach_poses.png")]


def draw_target(ax, target: np.ndarray, axis: np.ndarray, color: str = "tab:red") -> None:
    """The target point and an arrow along its direction."""
    ax.scatter(*target, color=color, s=30)
    ax.quiver(*target, *(ARROW * axis), color=color, lw=2, arrow_length_ratio=0.3)


def render(robot: Robot, q, target, axis) -> np.ndarray:
    """An RGB frame of the arm and the target pose."""
    points = np.asarray(backbone(robot, q))

    def draw(ax):
        draw_arm(ax, points)
        draw_target(ax, np.asarray(target), np.asarray(axis))
        setup_axes(ax)

    return plots.rgb_image(draw, projection="3d")


def episode_gif(path, robot: Robot, q: np.ndarray, target: np.ndarray, axis: np.ndarray, distance: np.ndarray,
                angle_deg: np.ndarray, dt: float, fps: int, dpi: int) -> Path:
    """A GIF of an episode: q (T + 1, n) at each control step, the target pose fixed."""
    shapes = backbones(robot, q)
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")

    def frame(k):
        ax.clear()
        draw_arm(ax, shapes[k])
        draw_target(ax, target, axis)
        setup_axes(ax)
        text = f"t = {k * dt:.1f} s" + (f", {100 * distance[k - 1]:.1f} cm, {angle_deg[k - 1]:.1f} deg" if k else "")
        ax.set_title(text)

    return plots.save_gif(fig, frame, len(q), path, fps=fps, dpi=dpi)
