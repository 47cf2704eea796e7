"""Drawings of pick and place: an episode's shapes and controls (paper Fig. 6), its GIF.

Episodes are simulated by ``motion.episode``, the function the env steps with,
at the drawing resolution ``DRAWING_INTEGRATION`` (smooth frames). Lengths in
metres; the joint at the origin, gravity -y.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gvsjax.core.kinematics import backbone  # noqa: E402
from gvsjax.tasks.pickplace.motion import action_to_physical, cycloid, episode  # noqa: E402
from gvsjax.tasks.pickplace.params import DRAWING_INTEGRATION, PickPlaceParams  # noqa: E402
from gvsjax.utils.plots import save, save_gif  # noqa: E402


def draw_state(ax, arm, q, targets) -> None:
    """The arm's backbone at q and the (2, 2) targets on ``ax``."""
    pts = np.asarray(backbone(arm, jnp.asarray(q)))
    ax.plot(pts[:, 0], pts[:, 1], "k-", lw=3, label="arm")
    t = np.asarray(targets)
    ax.plot(t[:, 0], t[:, 1], "rx", ms=10, label="targets")
    ax.set(xlim=(-1.2, 1.2), ylim=(-1.2, 1.2), aspect="equal")
    ax.legend(loc="upper right", fontsize=7)


@jax.jit
def _drawn_episode(params, actions):
    tr1, tr2 = episode(params.replace(**DRAWING_INTEGRATION), actions, save_every=5)
    arms = [jax.vmap(lambda q: backbone(params.arm, q))(tr.q) for tr in (tr1, tr2)]
    return (tr1, tr2), arms


def episode_drawing(params: PickPlaceParams, actions) -> dict[str, Any]:
    """Both steps of an episode at the drawing resolution: t, q, tips, arms (per saved state)."""
    (tr1, tr2), (a1, a2) = _drawn_episode(params, jnp.asarray(actions, float))
    T = params.step_time
    return {"t": np.concatenate([np.asarray(tr1.t), T + np.asarray(tr2.t)[1:]]),
            "q": np.concatenate([np.asarray(tr1.q), np.asarray(tr2.q)[1:]]),
            "tip": np.concatenate([np.asarray(tr1.tip), np.asarray(tr2.tip)[1:]])[:, :2],
            "arm": np.concatenate([np.asarray(a1), np.asarray(a2)[1:]])[..., :2],
            "n_first": len(tr1.t)}


def episode_figure(params: PickPlaceParams, actions, targets, path, every_s: float = 0.5) -> Path:
    """Shapes every ``every_s`` seconds in each step, and the joint angle and tension over time (Fig. 6)."""
    e = episode_drawing(params, actions)
    theta, tension = (np.asarray(x) for x in action_to_physical(jnp.asarray(actions, float), params))
    targets = np.asarray(targets)
    T, n1 = params.step_time, e["n_first"]
    fig = plt.figure(figsize=(13, 8))
    axes = [fig.add_subplot(2, 2, 1), fig.add_subplot(2, 2, 2), fig.add_subplot(2, 1, 2)]
    spans = (range(0, n1), range(n1 - 1, len(e["t"])))
    for k, span in enumerate(spans):
        ax, idx = axes[k], np.asarray(span)
        step = max(1, int(round(every_s / (e["t"][1] - e["t"][0]))))
        shown = idx[::step]
        cmap = plt.get_cmap("viridis")
        for j, i in enumerate(shown):
            ax.plot(e["arm"][i, :, 0], e["arm"][i, :, 1], color=cmap(j / max(len(shown) - 1, 1)), lw=1.2)
        ax.plot(e["tip"][idx, 0], e["tip"][idx, 1], "k--", lw=0.7, label="tip path")
        ax.plot(*targets[k], "r*", ms=12, label="target")
        ax.plot(0, 0, "ks")
        ax.set(xlim=(-1.15, 1.15), ylim=(-1.15, 1.15), aspect="equal")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
        d = np.hypot(*(e["tip"][idx[-1]] - targets[k]))
        ax.set_title(f"step {k + 1}: theta_F = {np.degrees(theta[k]):.1f} deg, T = {tension[k]:.1f} N, "
                     f"miss {100 * d:.2f} cm (shapes every {every_s:.1f} s)", fontsize=9)
    t = e["t"]
    pull = np.where(t <= T, tension[0] * np.asarray(cycloid(np.minimum(t, T) / T)),
                    tension[0] + (tension[1] - tension[0]) * np.asarray(cycloid(np.clip(t - T, 0, T) / T)))
    ax = axes[2]
    ax.plot(t, np.degrees(e["q"][:, 0]), "tab:blue")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("joint angle [deg]", color="tab:blue")
    ax.axvline(T, color="k", lw=0.6, ls=":")
    bx = ax.twinx()
    bx.plot(t, pull, "tab:red")
    bx.set_ylabel("tendon tension [N]", color="tab:red")
    ax.set_title("joint angle (cycloidal profile) and tendon tension (same smooth ramp) over both steps")
    return save(fig, path)


def episode_gif(path, params: PickPlaceParams, actions, targets=None, fps: int = 8, dpi: int = 80) -> Path:
    """Animate an episode for ``actions`` (2, 2) in [-1, 1]: one frame every 0.25 s.

    ``targets``: optional (2, 2) m pick and place points to mark (default: the tips reached).
    """
    a = np.asarray(actions, float)
    if a.shape != (2, 2) or not np.all(np.isfinite(a)) or np.abs(a).max() > 1:
        raise ValueError(f"actions={a.tolist()!r} must be (2, 2) numbers in [-1, 1]")
    e = episode_drawing(params, a)
    t, arms, tips, n1 = e["t"], e["arm"], e["tip"], e["n_first"]
    frames = np.arange(0, len(t), 5)  # saved every 5 drawing steps; a frame every 25 (0.25 s)
    ends = np.stack([tips[n1 - 1], tips[-1]])
    marks = ends if targets is None else np.asarray(targets, float)
    theta_f, tension = (np.asarray(x) for x in action_to_physical(jnp.asarray(a), params))

    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    c = np.linspace(0, 2 * np.pi, 200)
    ax.plot(np.cos(c), np.sin(c), ":", color="0.6", lw=0.8)
    ax.plot(0, 0, "ks")
    label = "targets" if targets is not None else "tips reached"
    ax.plot(*marks[0], "*", color="tab:red", ms=13, label=f"pick ({label})")
    ax.plot(*marks[1], "*", color="tab:purple", ms=13, label=f"place ({label})")
    ax.set(xlim=(-1.2, 1.2), ylim=(-1.2, 1.2), aspect="equal", xlabel="x [m]", ylabel="y [m]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    (arm_line,) = ax.plot([], [], color="tab:green", lw=4, solid_capstyle="round")
    (trail,) = ax.plot([], [], "k--", lw=0.7)
    title = ax.set_title("", fontsize=9)

    def draw(j):
        k = frames[j]
        arm_line.set_data(arms[k, :, 0], arms[k, :, 1])
        trail.set_data(tips[: k + 1, 0], tips[: k + 1, 1])
        s = 0 if k < n1 else 1
        title.set_text(f"step {s + 1} ({'pick' if s == 0 else 'place'}): theta_F = "
                       f"{np.degrees(theta_f[s]):.0f} deg, tension {tension[s]:.1f} N, t = {t[k]:.2f} s")
        return arm_line, trail, title

    return save_gif(fig, draw, len(frames), path, fps, dpi)
