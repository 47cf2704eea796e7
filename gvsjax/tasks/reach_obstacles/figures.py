"""reach_obstacles' drawings: distance and penetration over time, final arms among the obstacles, a GIF."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from gvsjax.core.kinematics import backbone
from gvsjax.core.model import Robot
from gvsjax.tasks.draw3d import backbones, draw_arm, setup_axes
from gvsjax.utils import plots


def over_time(policy: dict, held: dict, dt: float, tolerance: float, success: float, path,
              ramped: dict | None = None, who: str = "policy") -> Path:
    """Median and 5-95% band of the tip's distance to the target and of each step's deepest
    penetration, for the policy and the held reference action; the median alone for the ramped one."""
    t = dt * np.arange(1, policy["distance"].shape[1] + 1)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, key, scale, unit, limit in ((axes[0], "distance", 100.0, "tip to target [cm]", success),
                                        (axes[1], "depth", 1000.0, "deepest penetration in the step [mm]", tolerance)):
        for out, color, label in ((policy, "tab:blue", who), (held, "tab:orange", "reference action, held")):
            x = scale * np.where(out["valid"], out[key], np.nan)
            ax.fill_between(t, np.nanpercentile(x, 5, 0), np.nanpercentile(x, 95, 0), alpha=0.2, color=color)
            ax.plot(t, np.nanmedian(x, 0), color=color, lw=2, label=f"{label}, median")
        if ramped is not None:
            x = scale * np.where(ramped["valid"], ramped[key], np.nan)
            ax.plot(t, np.nanmedian(x, 0), color="tab:purple", lw=1.5, ls="--",
                    label="reference action, ramped, median")
        ax.axhline(scale * limit, color="tab:green", ls=":", lw=1, label="success limit")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, title="shaded: 5-95%", title_fontsize=8)
    axes[0].set_yscale("log")
    fig.suptitle(f"reaching among obstacles, {policy['distance'].shape[0]} episodes")
    return plots.save(fig, path)


def draw_obstacles(ax, robot: Robot, color: str = "0.45") -> None:
    """The robot's capsule obstacles as thick segments (drawn width ~ their radius)."""
    for obs in robot.contact.obstacles:
        seg = np.stack([np.asarray(obs.start), np.asarray(obs.end)])
        ax.plot(*seg.T, color=color, lw=max(1.0, 100 * float(obs.radius)), alpha=0.6, solid_capstyle="round")


def draw_target(ax, target: np.ndarray, success: float) -> None:
    ax.scatter(*target, color="tab:red", s=40, depthshade=False, label=f"target ({100 * success:g} cm)")


def final_arms(robots: list[Robot], q_final: np.ndarray, targets: np.ndarray, success: float, path) -> Path:
    """A few episodes' final arms among their obstacles, side by side."""
    k = len(robots)
    fig = plt.figure(figsize=(5 * k, 5))
    for i in range(k):
        ax = fig.add_subplot(1, k, i + 1, projection="3d")
        draw_obstacles(ax, robots[i])
        draw_arm(ax, backbones(robots[i], q_final[i:i + 1])[0])
        draw_target(ax, targets[i], success)
        setup_axes(ax)
        ax.set_title(f"episode {i + 1}: final arm")
    return plots.save(fig, path)


def evaluation_figures(params, extra: dict, out: Path, robots: list[Robot]) -> list[Path]:
    """The figures of an evaluation (``ReachObstacles.evaluate``'s ``extra``); ``robots``: the
    first episodes' arms with their (turned) obstacles, one per episode drawn."""
    pol, held = extra["policy"], extra["held_action"]
    k = len(robots)
    return [over_time(pol, held, extra["dt"], params.tolerance, params.success_distance,
                      out / "reach_obstacles_over_time.png", extra.get("ramped_action"), extra.get("who", "policy")),
            final_arms(robots, pol["q"][:k, -1], pol["target"][:k], params.success_distance,
                       out / "reach_obstacles_final.png")]


def render(robot: Robot, q, target) -> np.ndarray:
    """An RGB frame of the arm, its obstacles and the target."""
    points = np.asarray(backbone(robot, q))

    def draw(ax):
        draw_obstacles(ax, robot)
        draw_arm(ax, points)
        ax.scatter(*np.asarray(target), color="tab:red", s=40)
        setup_axes(ax)

    return plots.rgb_image(draw, projection="3d")


def episode_gif(path, robot: Robot, q: np.ndarray, target: np.ndarray, distance: np.ndarray, depth: np.ndarray,
                dt: float, fps: int, dpi: int) -> Path:
    """A GIF of an episode: q (T + 1, n) at each control step among the robot's obstacles."""
    shapes = backbones(robot, q)
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")

    def frame(k):
        ax.clear()
        draw_obstacles(ax, robot)
        draw_arm(ax, shapes[k])
        ax.scatter(*target, color="tab:red", s=40)
        setup_axes(ax)
        ax.view_init(elev=15, azim=-60)
        text = f"t = {k * dt:.1f} s" + (f", {100 * distance[k - 1]:.1f} cm, depth {1000 * depth[k - 1]:.1f} mm"
                                         if k else "")
        ax.set_title(text, fontsize=9)

    return plots.save_gif(fig, frame, len(q), path, fps=fps, dpi=dpi)
