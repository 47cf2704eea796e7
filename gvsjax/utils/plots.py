"""Figures every task shares (PNG and GIF, Agg backend): the learning curve, an error
histogram, and the helpers that save a figure, an animation or an RGB image.

Task-specific drawings live with their task (``gvsjax/tasks/<task>/figures.py``).
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402


def save(fig, path) -> Path:
    """Save ``fig`` as a PNG at ``path`` (folders created) and close it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def rgb_image(draw: Callable, size: float = 4.0, dpi: int = 80, projection: str | None = None) -> np.ndarray:
    """An RGB array (H, W, 3) uint8 of ``draw(ax)`` on its own Agg canvas (``projection="3d"``: 3D axes).

    Headless, and neither pyplot's figure list nor the user's backend is touched.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(size, size), dpi=dpi)
    canvas = FigureCanvasAgg(fig)
    draw(fig.subplots(subplot_kw={"projection": projection} if projection else None))
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def moving_average(x: np.ndarray, w: int) -> np.ndarray:
    """Trailing mean over the last ``w`` samples (shorter at the start)."""
    c = np.cumsum(np.insert(np.asarray(x, float), 0, 0.0))
    n = np.arange(1, len(x) + 1)
    lo = np.maximum(n - w, 0)
    return (c[n] - c[lo]) / (n - lo)


def learning_curve(metrics_csv, path, evaluation: dict | None = None, window_episodes: int = 100) -> Path:
    """Mean episode reward vs episodes with a ``window_episodes`` moving average (paper Fig. 3); beside
    it, when the run logged them, the discounted returns of the last finished training episodes (sampled
    actions) and, at the end, those of ``evaluation`` (eval.json's dict: the deterministic policy).

    metrics.csv holds one row per PPO update or SAC iteration (the mean over the episodes
    that ended in it), so the moving average weighs each row by its episode count.
    """
    with open(metrics_csv, newline="") as f:
        rows = [r for r in csv.DictReader(f)]
    ep = np.array([float(r["episodes"]) for r in rows])
    reward = np.array([float(r["episode_reward"]) for r in rows])
    count = np.maximum(np.array([float(r.get("episodes_completed", 1) or 1) for r in rows]), 1)
    ok = np.isfinite(reward)  # rows where no episode ended (long episodes) have no reward
    w = max(1, int(np.ceil(window_episodes / np.median(count[ok])))) if ok.any() else 1  # rows covering the window
    discounted = bool(rows) and "train_discounted_return_average" in rows[0]
    fig, axes = plt.subplots(1, 2 if discounted else 1, figsize=(13 if discounted else 7, 4), squeeze=False)
    ax = axes[0, 0]
    sac = bool(rows) and "critic_loss" in rows[0]
    ax.plot(ep[ok], reward[ok], lw=0.6, alpha=0.4,
            label=f"per {'iteration' if sac else 'update'} (mean over its episodes)")
    ax.plot(ep[ok], moving_average(reward[ok] * count[ok], w) / moving_average(count[ok], w),
            lw=1.8, label=f"{window_episodes}-episode moving average")
    ax.set_xlabel("episodes")
    ax.set_ylabel("average reward")
    top = float(np.nanmax(reward[ok])) if ok.any() else 1.0
    ax.set_ylim(min(0.0, float(np.nanmin(reward[ok])) if ok.any() else 0.0), max(1.02, 1.02 * top))
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    ax.set_title(f"{'SAC' if sac else 'PPO'} learning curve")
    if discounted:
        _discounted_panel(axes[0, 1], rows, ep, evaluation or {})
    return save(fig, path)


def _discounted_panel(ax, rows: list[dict], ep: np.ndarray, evaluation: dict) -> None:
    """Training's windowed discounted returns against episodes; the evaluation's as points at the end."""
    for key, name, color in (("average", "averaged over start steps", "tab:blue"),
                             ("start", "from the first step", "tab:orange")):
        y = np.array([float(r[f"train_discounted_return_{key}"]) for r in rows])
        ax.plot(ep, y, color=color, lw=1.5, label=f"training, {name}")
        stats = evaluation.get(f"discounted_return_{key}")
        if isinstance(stats, dict) and "mean" in stats:
            ax.plot([ep[-1]], [stats["mean"]], "o", color=color, ms=7, label=f"evaluation, {name}")
    held = int(float(rows[-1].get("train_window_episodes") or 0))
    n = evaluation.get("n_episodes")
    ax.set_title(f"discounted returns\ntraining: the last {held} episodes, sampled actions"
                 + (f"; evaluation: {n} held-out episodes, deterministic" if n else ""), fontsize=9)
    ax.set_xlabel("episodes")
    ax.set_ylabel("discounted return")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)


def error_histogram(miss_m, path, max_cm: int = 10, title: str = "error") -> Path:
    """Percent of episodes per 1 cm error bracket, last bar ``>= max_cm`` (paper Fig. 5)."""
    cm = np.asarray(miss_m) * 100.0
    edges = np.arange(0, max_cm + 1)
    counts = [np.sum((cm >= a) & (cm < a + 1)) for a in edges[:-1]] + [np.sum(cm >= max_cm)]
    pct = 100.0 * np.array(counts) / max(len(cm), 1)
    labels = [f"{a}-{a + 1}" for a in edges[:-1]] + [f">={max_cm}"]
    fig, ax = plt.subplots(figsize=(7, 4))
    bars = ax.bar(range(len(pct)), pct, color="tab:blue")
    for b, p in zip(bars, pct):
        if p > 0:
            ax.text(b.get_x() + b.get_width() / 2, p + 0.5, f"{p:.1f}%", ha="center", fontsize=8)
    ax.set_xticks(range(len(pct)), labels, rotation=45)
    ax.set_xlabel("distance from target [cm]")
    ax.set_ylabel("episodes [%]")
    ax.set_ylim(0, max(pct.max() * 1.15, 5))
    ax.set_title(f"{title} over {len(cm)} episodes (< 10 cm: {np.mean(cm < 10) * 100:.1f}%)")
    return save(fig, path)


def save_gif(fig, draw, n_frames: int, path, fps: int, dpi: int) -> Path:
    """Write ``draw(k)`` for k < n_frames as a GIF (Pillow, which ships with matplotlib)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    FuncAnimation(fig, draw, frames=n_frames, blit=False).save(path, writer=PillowWriter(fps=fps), dpi=dpi)
    plt.close(fig)
    return path
