"""Drawings of the basketball task: a throw (paper Fig. 4), the workspace and arm
shapes (Fig. 2) and the throw as a GIF.

Every arm shape and release state comes from ``throw.swing``/``throw.release``,
the functions the env steps with. Lengths in metres; base at the origin, gravity -y.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gvsjax.core.kinematics import backbone  # noqa: E402
from gvsjax.tasks.basketball import throw  # noqa: E402
from gvsjax.tasks.basketball.params import HOOP, BasketballParams  # noqa: E402
from gvsjax.utils.plots import save, save_gif  # noqa: E402

# The GIF's swing: 300 RK4 steps, every 5th state drawn (60 frames); its release is
# within 0.5 mm of the task's 40 ars443 steps.
SWING_STEPS, SWING_INTEGRATOR, SWING_SAVE = 300, "rk4", 5


@jax.jit
def _release(params, T, delta):
    q, p0, v0 = throw.release(params, T, delta)
    return q, backbone(params.arm, q), throw.flight_path(p0, v0, params)


def release_drawing(params: BasketballParams, T: float, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """(arm backbone (k, 3) m at release, ball path (200, 2) m) of one throw, as numpy."""
    _, arm, path = _release(params, float(T), float(delta))
    return np.asarray(arm), np.asarray(path)


def court(ax, params: BasketballParams, hoop: bool = True) -> None:
    x0, x1, y0, y1 = params.window
    ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ls="--", color="0.5",
                               label="target window"))
    ax.axhline(params.y_floor, color="k", lw=1)
    if hoop:
        ax.plot(*HOOP, "o", mfc="none", mec="tab:orange", ms=10, mew=2, label="hoop (3-pt)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)


def throw_figure(params: BasketballParams, target, T: float, delta: float, path,
                 miss_m: float | None = None) -> Path:
    """One throw: the arm at release and the ball's path to the floor, with the target (Fig. 4)."""
    arm, ball = release_drawing(params, T, delta)
    fig, ax = plt.subplots(figsize=(8, 5))
    court(ax, params, hoop=False)
    ax.plot(arm[:, 0], arm[:, 1], "-", color="tab:green", lw=4, label="arm at release")
    ax.plot(ball[:, 0], ball[:, 1], color="tab:blue", label="ball")
    ax.plot(*np.asarray(target), "x", color="tab:red", ms=10, mew=2, label="target")
    title = f"T = {T:.3f} s, delta = {delta:.3f}"
    if miss_m is not None:
        title += f", miss = {miss_m * 100:.2f} cm"
    ax.set_title(title)
    ax.legend(loc="upper right", fontsize=8)
    return save(fig, path)


def workspace(params: BasketballParams, path, n_paths: int = 60, targets=None) -> Path:
    """Flight paths of actions spread over the box, and sampled targets (Fig. 2 left).

    Draws from the target tables of ``params`` (``make_params``).
    """
    fig, ax = plt.subplots(figsize=(9, 6))
    court(ax, params)
    p0, v0 = np.asarray(params.path_p0), np.asarray(params.path_v0)
    for j, i in enumerate(np.linspace(0, len(p0) - 1, n_paths).astype(int)):
        ball = np.asarray(throw.flight_path(jnp.asarray(p0[i]), jnp.asarray(v0[i]), params))
        ax.plot(ball[:, 0], ball[:, 1], lw=0.5, color="0.3", label="flight paths" if j == 0 else None)
    if targets is not None:
        t = np.asarray(targets)
        ax.plot(t[:, 0], t[:, 1], ".", ms=2, color="tab:red", alpha=0.5, label=f"{len(t)} targets")
    x0, x1, y0, y1 = params.window
    ax.set_xlim(x0 - 1, x1 + 1)
    ax.set_ylim(y0 - 0.5, y1 + 1)
    ax.set_title(f"workspace: T in {list(params.T_range)} s, delta in {list(params.delta_range)}")
    ax.legend(loc="upper right", fontsize=8)
    return save(fig, path)


def shapes(params: BasketballParams, path, T: float = 2.0, deltas=(0.85, 0.9, 0.95, 1.0)) -> Path:
    """Arm shapes at release and flight paths for one T at several delta (Fig. 2 right)."""
    fig, ax = plt.subplots(figsize=(9, 6))
    court(ax, params, hoop=False)
    for i, d in enumerate(deltas):
        arm, ball = release_drawing(params, T, d)
        ax.plot(arm[:, 0], arm[:, 1], color=f"C{i}", lw=3)
        ax.plot(ball[:, 0], ball[:, 1], color=f"C{i}", lw=1.2, label=f"delta = {d:.2f}")
    ax.set_title(f"arm at release and ball paths, T = {T} s")
    ax.legend(loc="upper right", fontsize=8)
    return save(fig, path)


@jax.jit
def _swing_frames(params, T, delta):
    tr = throw.swing(params, T, delta, n_steps=SWING_STEPS, integrator=SWING_INTEGRATOR, save_every=SWING_SAVE)
    arms = jax.vmap(lambda q: backbone(params.arm, q))(tr.q)
    return tr.t, arms, tr.tip[:, :2], tr.tip_velocity[-1, :2]


def throw_gif(path, params: BasketballParams, T: float = 2.0, delta: float = 0.9, target=None,
              frames: int = 60, fps: int = 20, dpi: int = 80) -> Path:
    """Animate a throw: the swing to release at delta T, then the ball's flight to the floor.

    Frames are uniform in simulated time over the swing and the flight.
    """
    t, arms, tip, v0 = (np.asarray(x) for x in _swing_frames(params, float(T), float(delta)))
    p0, t_rel = tip[-1], t[-1]
    tau_end = float(throw.floor_time(jnp.asarray(p0), jnp.asarray(v0), params.g, params.y_floor))
    times = np.linspace(0.0, t_rel + tau_end, frames)
    taus = np.linspace(0.0, tau_end, 200)
    path_pts = np.asarray(throw.flight_point(jnp.asarray(p0), jnp.asarray(v0), taus, params.g))

    fig, ax = plt.subplots(figsize=(7, 4.5))
    x0, _, _, y1 = params.window
    ax.axhline(params.y_floor, color="k", lw=1)
    ax.plot(*HOOP, "o", mfc="none", mec="tab:orange", ms=10, mew=2, label="hoop (3-pt)")
    if target is not None:
        ax.plot(*np.asarray(target, float), "x", color="tab:red", ms=10, mew=2, label="target")
    xs = np.concatenate([path_pts[:, 0], arms[..., 0].ravel(), [x0, 1.2]])
    ys = np.concatenate([path_pts[:, 1], arms[..., 1].ravel(), [params.y_floor, 1.2]])
    ax.set_xlim(xs.min() - 0.3, xs.max() + 0.3)
    ax.set_ylim(ys.min() - 0.3, min(ys.max(), y1 + 3) + 0.3)
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    (arm_line,) = ax.plot([], [], color="tab:green", lw=4, solid_capstyle="round")
    (trail,) = ax.plot([], [], color="tab:blue", lw=1, alpha=0.6)
    (ball_dot,) = ax.plot([], [], "o", color="tab:orange", ms=9)
    ax.legend(loc="upper right", fontsize=8)
    title = ax.set_title("")

    def draw(k):
        tk = times[k]
        i = min(round(tk / t_rel * (len(t) - 1)), len(t) - 1)
        arm_line.set_data(arms[i, :, 0], arms[i, :, 1])
        arm_line.set_alpha(1.0 if tk <= t_rel else 0.35)  # after release: the pose at release
        if tk <= t_rel:
            b, done = tip[i], tip[: i + 1]
        else:
            flown = path_pts[taus <= tk - t_rel]
            b = np.asarray(throw.flight_point(jnp.asarray(p0), jnp.asarray(v0), tk - t_rel, params.g))
            done = np.concatenate([tip, flown])
        ball_dot.set_data([b[0]], [b[1]])
        trail.set_data(done[:, 0], done[:, 1])
        phase = "swing" if tk <= t_rel else "flight"
        title.set_text(f"T = {T:.2f} s, delta = {delta:.3f}: {phase}, t = {tk:.2f} s")
        return arm_line, trail, ball_dot, title

    return save_gif(fig, draw, frames, path, fps, dpi)
