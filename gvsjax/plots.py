"""Matplotlib figures of the basketball task (all saved as PNG; Agg backend).

Lengths in metres on the axes; the arm's base is at the origin, gravity -y.
"""

from __future__ import annotations

import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import jax  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import gvsjax as gv  # noqa: E402


def _save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def moving_average(x: np.ndarray, w: int) -> np.ndarray:
    """Trailing mean over the last ``w`` samples (shorter at the start)."""
    c = np.cumsum(np.insert(np.asarray(x, float), 0, 0.0))
    n = np.arange(1, len(x) + 1)
    lo = np.maximum(n - w, 0)
    return (c[n] - c[lo]) / (n - lo)


def learning_curve(metrics_csv, path, window_episodes: int = 100) -> Path:
    """Mean episode reward vs episodes with a ``window_episodes`` moving average (Fig. 3).

    metrics.csv holds one row per PPO update (the mean over that update's
    episodes), so the moving average weighs each row by its episode count.
    """
    with open(metrics_csv, newline="") as f:
        rows = [r for r in csv.DictReader(f)]
    ep = np.array([float(r["episodes"]) for r in rows])
    reward = np.array([float(r["episode_reward"]) for r in rows])
    count = np.maximum(np.array([float(r.get("episodes_completed", 1) or 1) for r in rows]), 1)
    # rows per window: enough updates to cover window_episodes episodes
    w = max(1, int(np.ceil(window_episodes / np.median(count))))
    ok = np.isfinite(reward)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(ep[ok], reward[ok], lw=0.6, alpha=0.4, label="per update (mean over its episodes)")
    ax.plot(ep[ok], moving_average(reward[ok] * count[ok], w) / moving_average(count[ok], w),
            lw=1.8, label=f"{window_episodes}-episode moving average")
    ax.set_xlabel("episodes")
    ax.set_ylabel("average reward")
    # episode reward is a sum over steps: up to 1 for basketball, 2 for pick and place
    ax.set_ylim(0, max(1.02, 1.02 * float(np.nanmax(reward[ok])) if ok.any() else 1.02))
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    ax.set_title("PPO learning curve")
    return _save(fig, path)


def error_histogram(miss_m, path, max_cm: int = 10) -> Path:
    """Percent of targets per 1 cm error bracket, last bar ``>= max_cm`` (Fig. 5)."""
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
    ax.set_ylabel("targets [%]")
    ax.set_ylim(0, max(pct.max() * 1.15, 5))
    ax.set_title(f"error over {len(cm)} targets (success < 10 cm: {np.mean(cm < 10) * 100:.1f}%)")
    return _save(fig, path)


@jax.jit
def _release_jit(params, T, delta):
    law = lambda t: params.theta_final * (t / T) ** 2  # noqa: E731
    traj = gv.simulate(params.arm, delta * T, n_steps=params.n_steps, base_angle=law,
                       save_every=params.n_steps, check_stability=False)
    return traj.q[-1], traj.tip[-1, :2], traj.tip_velocity[-1, :2]


def _release(params, T: float, delta: float):
    """q at release (n,), tip p0 (2,), v0 (2,) by simulating the throw (float T, delta)."""
    return tuple(np.asarray(x) for x in _release_jit(params, float(T), float(delta)))


def _path(p0, v0, g, tau_end, n=400):
    tau = np.linspace(0.0, tau_end, n)[:, None]
    return p0 + v0 * tau + 0.5 * np.array([0.0, -g]) * tau**2


def _floor_time(p0, v0, g, y_floor):
    return (v0[1] + np.sqrt(max(v0[1] ** 2 + 2 * g * (p0[1] - y_floor), 0.0))) / g


def _court(ax, params, hoop=True):
    x0, x1, y0, y1 = params.window
    ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ls="--", color="0.5",
                               label="target window"))
    ax.axhline(params.y_floor, color="k", lw=1)
    if hoop:
        ax.plot(-6.75, 1.1, "o", mfc="none", mec="tab:orange", ms=10, mew=2, label="hoop (3-pt)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)


def throw(params, target, T: float, delta: float, path, miss_m: float | None = None) -> Path:
    """One throw: arm shape at release and the ball's path to the target (Fig. 4)."""
    q, p0, v0 = _release(params, T, delta)
    arm = np.asarray(gv.backbone(params.arm, q))
    fig, ax = plt.subplots(figsize=(8, 5))
    _court(ax, params, hoop=False)
    ball = _path(p0, v0, params.g, _floor_time(p0, v0, params.g, params.y_floor))
    ax.plot(arm[:, 0], arm[:, 1], "-", color="tab:green", lw=4, label="arm at release")
    ax.plot(ball[:, 0], ball[:, 1], color="tab:blue", label="ball")
    ax.plot(*target, "x", color="tab:red", ms=10, mew=2, label="target")
    title = f"T = {T:.3f} s, delta = {delta:.3f}"
    if miss_m is not None:
        title += f", miss = {miss_m * 100:.2f} cm"
    ax.set_title(title)
    ax.legend(loc="upper right", fontsize=8)
    return _save(fig, path)


def workspace(params, path, n_paths: int = 60, targets=None) -> Path:
    """Workspace: flight paths of actions spread over the box, and sampled targets (Fig. 2 left)."""
    fig, ax = plt.subplots(figsize=(9, 6))
    _court(ax, params)
    p0, v0 = np.asarray(params.path_p0), np.asarray(params.path_v0)
    idx = np.linspace(0, len(p0) - 1, n_paths).astype(int)
    for j, i in enumerate(idx):
        ball = _path(p0[i], v0[i], params.g, _floor_time(p0[i], v0[i], params.g, params.y_floor))
        ax.plot(ball[:, 0], ball[:, 1], lw=0.5, color="0.3", label="flight paths" if j == 0 else None)
    if targets is not None:
        t = np.asarray(targets)
        ax.plot(t[:, 0], t[:, 1], ".", ms=2, color="tab:red", alpha=0.5, label=f"{len(t)} targets")
    x0, x1, y0, y1 = params.window
    ax.set_xlim(x0 - 1, x1 + 1)
    ax.set_ylim(y0 - 0.5, y1 + 1)
    ax.set_title("workspace: T in [0.5, 3] s, delta in [0.85, 1]")
    ax.legend(loc="upper right", fontsize=8)
    return _save(fig, path)


def shapes(params, path, T: float = 2.0, deltas=(0.85, 0.9, 0.95, 1.0)) -> Path:
    """Arm shapes at release and flight paths for one T at several delta (Fig. 2 right)."""
    fig, ax = plt.subplots(figsize=(9, 6))
    _court(ax, params, hoop=False)
    for i, d in enumerate(deltas):
        q, p0, v0 = _release(params, T, d)
        arm = np.asarray(gv.backbone(params.arm, q))
        color = f"C{i}"
        ax.plot(arm[:, 0], arm[:, 1], color=color, lw=3)
        ball = _path(p0, v0, params.g, _floor_time(p0, v0, params.g, params.y_floor))
        ax.plot(ball[:, 0], ball[:, 1], color=color, lw=1.2, label=f"delta = {d:.2f}")
    ax.set_title(f"arm at release and ball paths, T = {T} s")
    ax.legend(loc="upper right", fontsize=8)
    return _save(fig, path)
