"""balance's drawings: the tilt over time, the torques of a few episodes, the time to upright, a frame, a GIF."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from gvsjax.core.kinematics import backbone
from gvsjax.core.model import Robot
from gvsjax.utils import plots


def tilt_over_time(tilt: np.ndarray, success: np.ndarray, dt: float, upright_deg: float, path) -> Path:
    """The tilt (deg, log scale) at each control step: median and 5-95% band over all episodes,
    and the first failed episodes."""
    t = dt * np.arange(1, tilt.shape[1] + 1)
    deg = np.clip(np.degrees(np.where(np.isfinite(tilt), tilt, np.nan)), 0.01, 180)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.fill_between(t, np.nanpercentile(deg, 5, 0), np.nanpercentile(deg, 95, 0), alpha=0.25, color="tab:blue",
                    label="5-95%")
    ax.plot(t, np.nanmedian(deg, 0), color="tab:blue", lw=2, label="median")
    for k, i in enumerate(np.flatnonzero(~success)[:3]):
        ax.plot(t, deg[i], color=f"C{k + 1}", lw=1, label=f"failed episode {i}")
    ax.axhline(upright_deg, color="tab:green", ls=":", label=f"{upright_deg:g} deg")
    ax.set_yscale("log")
    ax.set_ylim(0.05, 200)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tilt of the base-to-tip line from vertical [deg]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(f"{tilt.shape[0]} episodes, success {100 * np.mean(success):.1f}%")
    return plots.save(fig, path)


def torques(action: np.ndarray, torque_max: float, dt: float, path) -> Path:
    """The base torque of a few episodes (k, T)."""
    t = dt * np.arange(action.shape[1])
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for i in range(action.shape[0]):
        ax.step(t, torque_max * action[i], where="post", lw=1, label=f"episode {i}")
    ax.axhline(torque_max, color="0.5", ls="--", lw=0.8)
    ax.axhline(-torque_max, color="0.5", ls="--", lw=0.8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("base torque [N m]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=7, ncol=2)
    ax.set_title("base torque (zero-order hold)")
    return plots.save(fig, path)


def time_to_upright(t_up: np.ndarray, success: np.ndarray, dt: float, path) -> Path:
    """Histogram of the time to upright of the successful episodes."""
    fig, ax = plt.subplots(figsize=(6, 3.5))
    x = t_up[success]
    edges = np.arange(0, 10 + dt, 0.25)
    counts, _ = np.histogram(x, edges)
    ax.bar(edges[:-1], 100 * counts / max(len(t_up), 1), width=0.25, align="edge", color="tab:blue", label="bars")
    ax.set_xlabel("time to upright [s]")
    ax.set_ylabel("% of episodes")
    ax.set_title(f"time to upright ({int(success.sum())} of {len(t_up)} episodes succeed)")
    ax.grid(alpha=0.3)
    return plots.save(fig, path)


def evaluation_figures(extra: dict, out: Path) -> list[Path]:
    """The figures of an evaluation (``Balance.evaluate``'s ``extra``)."""
    return [tilt_over_time(extra["tilt"], extra["success"], extra["dt"], extra["upright_deg"],
                           out / "balance_tilt.png"),
            torques(extra["action"][:4], extra["torque_max"], extra["dt"], out / "balance_torque.png"),
            time_to_upright(extra["time_to_upright"], extra["success"], extra["dt"], out / "time_to_upright.png")]


def draw(ax, points: np.ndarray, torque: float, torque_max: float, upright_deg: float = 5.0) -> None:
    """The backbone ``points`` (k, 3) in the x-y plane, the upright cone and the base torque (an arc
    about the base, counter-clockwise positive, three quarters of a turn at ``torque_max``)."""
    cone = np.radians(upright_deg)
    for s in (-1, 1):
        ax.plot([0, 1.1 * np.sin(s * cone)], [0, 1.1 * np.cos(cone)], color="tab:green", lw=0.8, ls=":")
    ax.plot(points[:, 0], points[:, 1], color="tab:blue", lw=5, solid_capstyle="round")
    ax.scatter([0], [0], color="k", s=30, zorder=3)
    if abs(torque) > 1e-9:
        span = np.linspace(0, np.sign(torque) * min(abs(torque) / torque_max, 1.0) * 1.5 * np.pi, 30)
        ax.plot(0.12 * np.cos(span - np.pi / 2), 0.12 * np.sin(span - np.pi / 2), color="tab:red", lw=2)
    ax.set_xlim(-1.15, 1.15)
    ax.set_ylim(-1.15, 1.15)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m] (up)")
    ax.grid(alpha=0.3)


def render(robot: Robot, q, torque: float, torque_max: float) -> np.ndarray:
    """An RGB frame of the arm and the base torque."""
    points = np.asarray(backbone(robot, q))
    return plots.rgb_image(lambda ax: draw(ax, points, torque, torque_max))


def episode_gif(path, robot: Robot, q: np.ndarray, tilt: np.ndarray, torque: np.ndarray, torque_max: float,
                dt: float, upright_deg: float, fps: int, dpi: int) -> Path:
    """A GIF of an episode: q (T + 1, 3) at each control step, tilt and torque (T,) after / over each."""
    import jax

    shapes = np.asarray(jax.jit(jax.vmap(lambda x: backbone(robot, x)))(q))
    fig, ax = plt.subplots(figsize=(4.5, 4.5), layout="constrained")  # keeps the axis labels in the frame

    def frame(k):
        ax.clear()
        draw(ax, shapes[k], torque[min(k, len(torque) - 1)], torque_max, upright_deg)
        text = f"t = {k * dt:.2f} s" + (f", tilt {np.degrees(tilt[k - 1]):.1f} deg, torque "
                                        f"{torque[k - 1]:+.1f} N m" if k else "")
        ax.set_title(text, fontsize=9)

    return plots.save_gif(fig, frame, len(q), path, fps=fps, dpi=dpi)
