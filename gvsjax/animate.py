"""GIF animations of the tasks: a basketball throw and a pick-and-place episode.

    python -m gvsjax.animate task=basketball T=2 delta=0.9 out=throw.gif
    python -m gvsjax.animate task=pickplace action=0.5,0.6,-0.7,0.2 out=pickplace.gif

The shapes come from the simulator's saved states (``gv.simulate`` with
``save_every``) drawn with ``gv.backbone``; frames are spaced uniformly in
simulated time, so the GIF plays in (scaled) real time. matplotlib's
``FuncAnimation`` writes them with ``PillowWriter`` (Pillow ships with
matplotlib). Lengths in metres, the arm's base at the origin, gravity along -y.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.animation import FuncAnimation, PillowWriter

import gvsjax as gv
from gvsjax.evaluate import parse_key_values
from gvsjax.tasks import basketball as bb
from gvsjax.tasks import pickplace as pp

# RK4 steps to release and every 5th state kept: 60 frames of the swing (the task itself
# takes 40 ars443 steps; the two releases agree within 0.5 mm)
SWING_STEPS, SWING_SAVE = 300, 5


def _shapes(arm, q) -> np.ndarray:
    """Backbones (m, points, 2) of saved states q (m, n)."""
    return np.asarray(jax.vmap(lambda x: gv.backbone(arm, x))(jnp.asarray(q)))[..., :2]


@jax.jit
def _swing(params, T, delta):
    law = lambda t: params.theta_final * (t / T) ** 2
    tr = gv.simulate(params.arm, delta * T, n_steps=SWING_STEPS, base_angle=law,
                     save_every=SWING_SAVE, check_stability=False)
    return tr.t, tr.q, tr.tip[:, :2], tr.tip_velocity[-1, :2]


def _check_range(name: str, value: float, lo: float, hi: float) -> None:
    if not (np.isfinite(value) and lo <= value <= hi):
        raise ValueError(f"{name}={value!r} is out of range; allowed: [{lo}, {hi}]")


def _save(fig, draw, n_frames: int, path, fps: int, dpi: int) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    FuncAnimation(fig, draw, frames=n_frames, blit=False).save(path, writer=PillowWriter(fps=fps), dpi=dpi)
    plt.close(fig)
    return path


def throw_gif(path, T: float = 2.0, delta: float = 0.9, target=None, params=None,
              frames: int = 60, fps: int = 20, dpi: int = 80) -> Path:
    """Animate a throw: the arm's swing to release at delta*T, then the ball's flight to the floor.

    ``params``: ``BasketballParams`` (default: the task's arm and ball, no target tables needed);
    ``target``: an optional (x, y) m to mark. Frames are uniform in simulated time over the swing
    and the flight. Returns the GIF's path.
    """
    params = params if params is not None else bb.BasketballParams(arm=gv.paper_arm(tip_force=bb.BALL_WEIGHT))
    _check_range("T", T, *params.T_range)
    _check_range("delta", delta, *params.delta_range)
    if not (isinstance(frames, int) and frames >= 2):
        raise ValueError(f"frames={frames!r} must be an int >= 2")
    t, q, tip, v0 = (np.asarray(x) for x in _swing(params, float(T), float(delta)))
    shapes, p0, t_rel = _shapes(params.arm, q), tip[-1], t[-1]
    tau_end = float(bb.floor_time(jnp.asarray(p0), jnp.asarray(v0), params.g, params.y_floor))
    times = np.linspace(0.0, t_rel + tau_end, frames)
    ball = lambda tau: p0 + v0 * tau + 0.5 * np.array([0.0, -params.g]) * tau**2
    taus = np.linspace(0.0, tau_end, 200)
    path_pts = np.array([ball(s) for s in taus])

    fig, ax = plt.subplots(figsize=(7, 4.5))
    x0, _, _, y1 = params.window
    ax.axhline(params.y_floor, color="k", lw=1)
    ax.plot(*bb.HOOP, "o", mfc="none", mec="tab:orange", ms=10, mew=2, label="hoop (3-pt)")
    if target is not None:
        ax.plot(*np.asarray(target, float), "x", color="tab:red", ms=10, mew=2, label="target")
    xs = np.concatenate([path_pts[:, 0], shapes[..., 0].ravel(), [x0, 1.2]])
    ys = np.concatenate([path_pts[:, 1], shapes[..., 1].ravel(), [params.y_floor, 1.2]])
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
        arm_line.set_data(shapes[i, :, 0], shapes[i, :, 1])
        arm_line.set_alpha(1.0 if tk <= t_rel else 0.35)  # after release: the pose at release
        if tk <= t_rel:
            b, done = tip[i], tip[: i + 1]
        else:
            flown = path_pts[taus <= tk - t_rel]
            b, done = ball(tk - t_rel), np.concatenate([tip, flown])
        ball_dot.set_data([b[0]], [b[1]])
        trail.set_data(done[:, 0], done[:, 1])
        phase = "swing" if tk <= t_rel else "flight"
        title.set_text(f"T = {T:.2f} s, delta = {delta:.3f}: {phase}, t = {tk:.2f} s")
        return arm_line, trail, ball_dot, title

    return _save(fig, draw, frames, path, fps, dpi)


def pickplace_gif(path, actions, targets=None, params=None, save_every: int = 25,
                  fps: int = 8, dpi: int = 80) -> Path:
    """Animate a pick-and-place episode: two 5 s steps for ``actions`` (2, 2) in [-1, 1].

    ``params``: ``PickPlaceParams`` (default: the task's tendon arm, no target tables needed);
    ``targets``: optional (2, 2) m pick and place points to mark (default: the tips reached).
    The episode is drawn from 500 RK4 steps per 5 s step (the task's 60 ars443 steps end within
    0.2 mm of it): one frame per ``save_every`` of them (25: every 0.25 s). Returns the GIF's path.
    """
    params = params if params is not None else pp.PickPlaceParams(arm=gv.paper_arm(tendon_offset=0.025))
    params = params.replace(**pp.DRAWING_INTEGRATION)
    a = np.asarray(actions, float)
    if a.shape != (2, 2) or not np.all(np.isfinite(a)) or np.abs(a).max() > 1:
        raise ValueError(f"actions={a.tolist()!r} must be (2, 2) numbers in [-1, 1]")
    if not (isinstance(save_every, int) and save_every >= 1 and params.n_steps % save_every == 0):
        raise ValueError(f"save_every={save_every!r} must be a positive int dividing n_steps={params.n_steps}")
    tr1, tr2 = jax.jit(lambda x: pp.episode(params, x, save_every=save_every))(jnp.asarray(a))
    q = np.concatenate([np.asarray(tr1.q), np.asarray(tr2.q)[1:]])
    t = np.concatenate([np.asarray(tr1.t), params.step_time + np.asarray(tr2.t)[1:]])
    tips = np.concatenate([np.asarray(tr1.tip), np.asarray(tr2.tip)[1:]])[:, :2]
    ends = np.stack([np.asarray(tr1.tip[-1, :2]), np.asarray(tr2.tip[-1, :2])])
    marks = ends if targets is None else np.asarray(targets, float)
    theta_f, tension = (np.asarray(x) for x in pp.action_to_physical(jnp.asarray(a), params))
    shapes = _shapes(params.arm, q)
    n1 = len(tr1.t)

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

    def draw(k):
        arm_line.set_data(shapes[k, :, 0], shapes[k, :, 1])
        trail.set_data(tips[: k + 1, 0], tips[: k + 1, 1])
        s = 0 if k < n1 else 1
        title.set_text(f"step {s + 1} ({'pick' if s == 0 else 'place'}): theta_F = "
                       f"{np.degrees(theta_f[s]):.0f} deg, tension {tension[s]:.1f} N, t = {t[k]:.2f} s")
        return arm_line, trail, title

    return _save(fig, draw, len(t), path, fps, dpi)


KEYS: dict[str, Any] = {"task": "basketball", "out": "", "T": 2.0, "delta": 0.9, "target": "",
        "action": "0.5,0.6,-0.7,0.2", "frames": 60, "fps": 0, "dpi": 80}
USAGE = __doc__.strip() + """

Keys (key=value): task (basketball | pickplace), out (GIF path; default <task>.gif),
T [s] and delta (basketball), target=x,y (basketball, optional, m), action=a0,a1,a2,a3
(pickplace: step 1 then step 2, each (angle, tension) in [-1, 1]), frames (basketball),
fps (default 20 basketball, 8 pickplace), dpi."""


def _floats(key: str, text: str, n: int) -> list[float]:
    try:
        vals = [float(x) for x in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) != n:
        raise ValueError(f"{key}={text!r} must be {n} comma-separated numbers")
    return vals


def parse_args(argv: list[str]) -> dict:
    args = parse_key_values(argv, KEYS)
    if args["task"] not in ("basketball", "pickplace"):
        raise ValueError(f"task={args['task']!r} is unknown; choose basketball or pickplace")
    return args


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if any(a in ("-h", "--help", "help") for a in argv):
        print(USAGE)
        return 0
    try:
        args = parse_args(argv)
        out = args["out"] or f"{args['task']}.gif"
        if args["task"] == "basketball":
            target = _floats("target", args["target"], 2) if args["target"] else None
            path = throw_gif(out, args["T"], args["delta"], target=target, frames=args["frames"],
                             fps=args["fps"] or 20, dpi=args["dpi"])
        else:
            action = np.reshape(_floats("action", args["action"], 4), (2, 2))
            path = pickplace_gif(out, action, fps=args["fps"] or 8, dpi=args["dpi"])
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
