"""The benchmark tasks' drawings: distance over time, the return's histogram, a frame, an episode GIF."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import jax
import matplotlib.pyplot as plt
import numpy as np

from gvsjax.tasks.draw3d import backbones, draw_arm, setup_axes
from gvsjax.utils import plots


def distance_over_time(distance: np.ndarray, dt: float, path) -> Path:
    """Median and 5-95% band of the tip-to-target distance at each control step (n, T)."""
    t = dt * np.arange(1, distance.shape[1] + 1)
    cm = 100 * np.where(np.isfinite(distance), distance, np.nan)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.fill_between(t, np.nanpercentile(cm, 5, 0), np.nanpercentile(cm, 95, 0), alpha=0.25, color="tab:blue",
                    label="5-95%")
    ax.plot(t, np.nanmedian(cm, 0), color="tab:blue", lw=2, label="median")
    for level in (5, 10):
        ax.axhline(level, color="tab:green", lw=0.8, ls=":")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tip-to-target distance [cm]")
    ax.set_ylim(0, max(12.0, float(np.nanpercentile(cm, 99))) * 1.15)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"tip-to-target distance over {distance.shape[0]} episodes")
    return plots.save(fig, path)


def return_histogram(returns: np.ndarray, path, label: str) -> Path:
    fig, ax = plt.subplots(figsize=(6, 3.5))
    finite = returns[np.isfinite(returns)]
    ax.hist(finite, bins=40, color="tab:blue", alpha=0.8)
    ax.axvline(np.mean(finite), color="k", ls="--", label=f"mean {np.mean(finite):.1f}")
    ax.set_xlabel(label)
    ax.set_ylabel("episodes")
    ax.legend(fontsize=8)
    return plots.save(fig, path)


def evaluation_figures(env: Any, extra: dict, out: Path) -> list[Path]:
    """The figures of an evaluation (``CurvatureTask.evaluate``'s ``extra``)."""
    rows = extra["rows"]
    paths = [return_histogram(rows["discounted_return_average"], out / "return_histogram.png",
                              "discounted return (gamma 0.99, averaged over start steps)")]
    paths.append(distance_over_time(extra["distance"], extra["dt"], out / "distance_over_time.png"))
    return paths


def _capsules(ax, obstacles: np.ndarray, radius: float, planar: bool) -> None:
    for a, b in obstacles:
        if planar:
            ax.plot([a[0]], [0.0], [a[2]], "o", color="0.4", ms=radius * 180, alpha=0.5)
        else:
            ax.plot(*np.stack([a, b]).T, color="0.4", lw=max(1.0, radius * 100), alpha=0.7)


def draw(ax, env: Any, params: Any, points: np.ndarray, target: np.ndarray, obstacles: np.ndarray,
         trail: np.ndarray | None = None) -> None:
    draw_arm(ax, points)
    if obstacles.size:
        _capsules(ax, obstacles, float(getattr(params, "radius", 0.03)), env.planar)
    if trail is not None:
        ax.plot(*trail.T, color="tab:red", lw=1, alpha=0.6)
    ax.scatter(*target, color="tab:red", s=40)
    setup_axes(ax)
    if env.planar:
        ax.view_init(elev=0, azim=-90)


def render(env: Any, params: Any, state: Any) -> np.ndarray:
    points = backbones(env.robot_for(state, params), np.asarray(state.q)[None])[0]
    return plots.rgb_image(lambda ax: draw(ax, env, params, points, np.asarray(state.target),
                                          np.asarray(state.obstacles)), projection="3d")


def episode_gif(env: Any, params: Any, path, out: dict, fps: int, dpi: int) -> Path:
    """A GIF of one recorded episode (``CurvatureTask.rollout(..., record_q=True)`` of one key)."""
    first = out["first"]
    robot = env.robot_for(_first(first), params)
    q = np.concatenate([np.asarray(first.q)[:1], np.asarray(out["q"][0])])
    target = np.concatenate([np.asarray(first.target)[:1], np.asarray(out["target"][0])])
    obstacles = np.asarray(first.obstacles[0])
    distance = np.asarray(out["distance"][0])
    shapes = backbones(robot, q)
    dt = params.arm.control_dt
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")

    def frame(k):
        ax.clear()
        draw(ax, env, params, shapes[k], target[k], obstacles, target[max(0, k - 20):k + 1])
        ax.set_title(f"{env.name}: t = {k * dt:.1f} s" + (f", distance {100 * distance[k - 1]:.1f} cm" if k else ""))

    return plots.save_gif(fig, frame, len(q), path, fps=fps, dpi=dpi)


def _first(batched: Any) -> Any:
    return jax.tree.map(lambda x: x[0], batched)
