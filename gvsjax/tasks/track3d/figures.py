"""track3d's drawings: distance over time, tip and target paths in 3D, a frame, an episode GIF."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from gvsjax.core.kinematics import backbone
from gvsjax.core.model import Robot
from gvsjax.tasks.draw3d import backbones, draw_arm, setup_axes
from gvsjax.utils import plots


def distance_over_time(distance: np.ndarray, rest: np.ndarray, dt: float, path, who: str = "policy") -> Path:
    """Median and 5-95% band of the tip-to-target distance at each control step (``who``: the
    controller's name in the legend), with the distance an arm left at rest would have."""
    t = dt * np.arange(1, distance.shape[1] + 1)
    cm = 100 * np.where(np.isfinite(distance), distance, np.nan)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.fill_between(t, np.nanpercentile(cm, 5, 0), np.nanpercentile(cm, 95, 0), alpha=0.25, color="tab:blue",
                    label=f"{who}, 5-95%")
    ax.plot(t, np.nanmedian(cm, 0), color="tab:blue", lw=2, label=f"{who}, median")
    ax.plot(t, np.median(100 * rest, 0), color="0.4", ls="--", label="arm left at rest, median")
    for level in (5, 10):
        ax.axhline(level, color="tab:green", lw=0.8, ls=":")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tip-to-target distance [cm]")
    # headroom above the curves for the legend, so it hides none of them
    ax.set_ylim(0, max(10.0, float(np.nanpercentile(cm, 99)), float(np.median(100 * rest, 0).max())) * 1.3)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper center", ncol=3, fontsize=8)
    ax.set_title(f"tracking over {distance.shape[0]} episodes")
    return plots.save(fig, path)


def paths_3d(tip: np.ndarray, target: np.ndarray, path) -> Path:
    """Tip (solid) and target (dashed) paths of a few episodes (n, T, 3)."""
    fig = plt.figure(figsize=(6, 6))
    ax = fig.add_subplot(projection="3d")
    for i in range(tip.shape[0]):
        color = f"C{i}"
        ax.plot(*target[i].T, color=color, ls="--", lw=1)
        ax.plot(*tip[i].T, color=color, lw=1.8, label=f"episode {i + 1}")
        ax.scatter(*target[i, 0], color=color, marker="o", s=20)
    setup_axes(ax)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title("tip (solid) and target (dashed)")
    return plots.save(fig, path)


def evaluation_figures(extra: dict, out: Path) -> list[Path]:
    """The figures of an evaluation (``Track3D.evaluate``'s ``extra``)."""
    d = extra["distance"]
    return [distance_over_time(d, extra["rest_distance"], extra["dt"], out / "tracking_distance.png",
                              extra.get("who", "policy")),
            paths_3d(extra["tip"], extra["target"], out / "tracking_paths.png"),
            plots.error_histogram(d[np.isfinite(d)], out / "error_histogram.png", max_cm=20,
                                  title="tip-to-target distance at each control step")]


def draw(ax, points: np.ndarray, target: np.ndarray, trail: np.ndarray | None = None) -> None:
    """The backbone ``points`` (k, 3), the target and its recent ``trail`` on 3D axes."""
    draw_arm(ax, points)
    if trail is not None:
        ax.plot(*trail.T, color="tab:red", lw=1, alpha=0.6)
    ax.scatter(*target, color="tab:red", s=40)
    setup_axes(ax)


def render(robot: Robot, q, target) -> np.ndarray:
    """An RGB frame of the arm and the target."""
    points = np.asarray(backbone(robot, q))
    return plots.rgb_image(lambda ax: draw(ax, points, np.asarray(target)), projection="3d")


def episode_gif(path, robot: Robot, q: np.ndarray, target: np.ndarray, distance: np.ndarray, dt: float,
                fps: int, dpi: int) -> Path:
    """A GIF of an episode: q (T + 1, n) and target (T + 1, 3) at each control step."""
    shapes = backbones(robot, q)
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")

    def frame(k):
        ax.clear()
        draw(ax, shapes[k], target[k], target[max(0, k - 20):k + 1])
        text = f"t = {k * dt:.1f} s" + (f", distance {100 * distance[k - 1]:.1f} cm" if k else "")
        ax.set_title(text)

    return plots.save_gif(fig, frame, len(q), path, fps=fps, dpi=dpi)
