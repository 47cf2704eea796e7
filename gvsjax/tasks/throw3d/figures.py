"""Drawings of throw3d: a throw in 3D, the misses over the court, the throw as a GIF.

Every arm shape and release state comes from ``throw.swing``, the function the
env steps with. Metres; base at the origin, z up.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import jax  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gvsjax.core.kinematics import backbone  # noqa: E402
from gvsjax.tasks.throw3d import throw  # noqa: E402
from gvsjax.tasks.throw3d.params import Throw3DParams  # noqa: E402
from gvsjax.utils.plots import save, save_gif  # noqa: E402

# the GIF's swing: 300 RK4 steps, every 5th state drawn
SWING_STEPS, SWING_INTEGRATOR, SWING_SAVE = 300, "rk4", 5


@jax.jit
def _release(params, T, delta, psi):
    traj = throw.swing(params, T, delta, psi)
    return backbone(params.arm, traj.q[-1]), throw.flight_path(traj.tip[-1], traj.tip_velocity[-1], params)


def release_drawing(params: Throw3DParams, T: float, delta: float, psi: float) -> tuple[np.ndarray, np.ndarray]:
    """(arm backbone (k, 3) m at release, ball path (200, 3) m) of one throw, as numpy."""
    arm, ball = _release(params, T, delta, psi)
    return np.asarray(arm), np.asarray(ball)


def _court_rings(ax, params: Throw3DParams, z: float | None = None) -> None:
    a = np.linspace(0.0, 2.0 * np.pi, 200)
    for r in params.court[:2]:
        if z is None:
            ax.plot(r * np.cos(a), r * np.sin(a), color="0.5", ls="--", lw=1)
        else:
            ax.plot(r * np.cos(a), r * np.sin(a), np.full_like(a, z), color="0.6", ls="--", lw=1)


def court_figure(params: Throw3DParams, targets: np.ndarray, miss: np.ndarray, path) -> Path:
    """Top view and side view (distance vs height) of the targets, coloured by miss."""
    cm = np.minimum(np.where(np.isfinite(miss), miss, 1.0) * 100.0, 10.0)
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2), gridspec_kw={"width_ratios": [1, 1.3]})
    ax = axes[0]
    _court_rings(ax, params)
    sc = ax.scatter(targets[:, 0], targets[:, 1], c=cm, s=8, cmap="viridis_r", vmin=0, vmax=10)
    ax.plot(0, 0, "k^", ms=8, label="shooter")
    ax.set(aspect="equal", xlabel="x [m]", ylabel="y [m]", title="top view (dashed: court rings)")
    ax.legend(loc="upper right", fontsize=8)
    ax = axes[1]
    rho = np.hypot(targets[:, 0], targets[:, 1])
    ax.scatter(rho, targets[:, 2], c=cm, s=8, cmap="viridis_r", vmin=0, vmax=10)
    ax.axhline(params.court[2], color="k", lw=1)
    ax.set(xlabel="horizontal distance from the base [m]", ylabel="height z [m]",
           title=f"{len(miss)} targets: < 10 cm {np.mean(miss < 0.1) * 100:.1f}%, "
                 f"< 1 cm {np.mean(miss < 0.01) * 100:.1f}%")
    fig.colorbar(sc, ax=axes, label="miss [cm] (clipped at 10)")
    return save(fig, path)


def _axes3d(ax, params: Throw3DParams, extent: float) -> None:
    ax.set(xlim=(-extent, extent), ylim=(-extent, extent), zlim=(params.court[2], params.court[3]),
           xlabel="x [m]", ylabel="y [m]", zlabel="z [m]")
    ax.set_box_aspect((2 * extent, 2 * extent, params.court[3] - params.court[2]))
    _court_rings(ax, params, z=params.court[2])


def throw_figure(params: Throw3DParams, target, T: float, delta: float, psi: float, path,
                 miss_m: float | None = None) -> Path:
    """One throw: the arm at release, the ball's flight to the floor, the target."""
    arm, ball = release_drawing(params, T, delta, psi)
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    _axes3d(ax, params, max(2.0, float(np.max(np.abs(ball[:, :2]))) + 0.5))
    ax.plot(*arm.T, color="tab:green", lw=4, label="arm at release")
    ax.plot(*ball.T, color="tab:blue", label="ball")
    ax.plot(*ball[:, :2].T, np.full(len(ball), params.court[2]), color="0.7", lw=1, label="ball's shadow")
    ax.plot(*np.asarray(target)[:, None], "x", color="tab:red", ms=10, mew=2, label="target")
    title = f"T = {T:.3f} s, delta = {delta:.3f}, yaw at release = {np.degrees(psi):.1f} deg"
    if miss_m is not None:
        title += f"\nmiss = {miss_m * 100:.2f} cm"
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=8)
    return save(fig, path)


def throw_gif(path, params: Throw3DParams, T: float, delta: float, psi: float, frames: int = 60,
              fps: int = 20, dpi: int = 80) -> Path:
    """The turn-and-swing to release, then the flight, as a GIF (``frames`` in all): the arm
    close up on the left, the court and the ball's flight on the right."""
    traj = jax.jit(lambda T, d, s: throw.swing(params, T, d, s, n_steps=SWING_STEPS, integrator=SWING_INTEGRATOR,
                                                save_every=SWING_SAVE))(T, delta, psi)
    arms = np.asarray(jax.jit(jax.vmap(lambda q: backbone(params.arm, q)))(traj.q))
    ball = np.asarray(throw.flight_path(traj.tip[-1], traj.tip_velocity[-1], params, n=200))
    t_rel = float(delta * T)
    n_swing = max(2, frames * 2 // 3)
    n_fly = max(1, frames - n_swing)
    swing_idx = np.linspace(0, len(arms) - 1, n_swing).astype(int)
    fly_idx = np.linspace(0, len(ball) - 1, n_fly + 1).astype(int)[1:]
    extent = max(2.0, float(np.max(np.abs(ball[:, :2]))) + 0.5)
    fig = plt.figure(figsize=(10, 5))
    near, far = fig.add_subplot(1, 2, 1, projection="3d"), fig.add_subplot(1, 2, 2, projection="3d")
    reach = 1.2

    def draw(k):
        for ax in (near, far):
            ax.cla()
        near.set(xlim=(-reach, reach), ylim=(-reach, reach), zlim=(-reach, reach), xlabel="x [m]",
                 ylabel="y [m]", zlabel="z [m]")
        near.set_box_aspect((1, 1, 1))
        _axes3d(far, params, extent)
        j = swing_idx[k] if k < n_swing else len(arms) - 1
        for ax in (near, far):
            ax.plot(*arms[j].T, color="tab:green", lw=4)
            ax.plot(*arms[j][:, :2].T, np.full(len(arms[j]), -reach if ax is near else params.court[2]),
                    color="0.7", lw=2)
        if k < n_swing:
            near.set_title(f"t = {t_rel * j / (len(arms) - 1):.2f} s (release at {t_rel:.2f} s)")
        else:
            b = fly_idx[k - n_swing]
            inside = ball[: b + 1][np.all(np.abs(ball[: b + 1]) <= reach, axis=1)]  # 3D axes do not clip
            near.plot(*inside.T, color="tab:blue")
            far.plot(*ball[: b + 1].T, color="tab:blue")
            far.plot(*ball[b][:, None], "o", color="tab:orange", ms=6)
            far.plot(*ball[: b + 1, :2].T, np.full(b + 1, params.court[2]), color="0.7", lw=1)
            near.set_title("release")
        far.set_title(f"T = {T:.2f} s, delta = {delta:.2f}, yaw at release {np.degrees(psi):.0f} deg")

    return save_gif(fig, draw, frames, path, fps, dpi)
