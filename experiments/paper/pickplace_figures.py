"""Table I, Fig. 6 and the reachable set of the pick-and-place task.

    python experiments/paper/pickplace_figures.py [checkpoint=PATH] [out=figures]

Always writes ``pickplace_reachable.png``: the target tables (tips at the end
of step 1 and step 2 for random actions) in the plane and as radius against
angle about the joint, with the paper's pair marked: the reachable set is a
band 98.6-100 cm from the joint and ~1-2 mm thick at a given angle (the arm
hangs from its base angle; the 0.75 N m tendon moment only trims it, mostly
along the band), so the paper's targets at 0.949 m and 0.978 m from the
joint are not exactly reachable with this model.

With a checkpoint (a run folder of ``python -m gvsjax.train task=pickplace`` or
its ``checkpoint.ckpt``), the deterministic policy is run on the paper's pair:
``pickplace_table1.md`` / ``.json`` (Table I: targets, tips, distances, and
the actions) and ``pickplace_fig6.png`` (Fig. 6, the task's ``episode_figure``:
the arm's shapes every 0.5 s over both steps, the joint angle and the tendon
tension over the 10 s) and,
when the run folder has ``metrics.csv``, ``pickplace_learning_curve.png``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import matplotlib
import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from gvsjax.ppo.checkpoint import load_policy, make_policy, resolve
from gvsjax.tasks import pickplace as pp
from gvsjax.tasks.pickplace.figures import episode_figure


def reachable_figure(params, path) -> Path:
    pick, place = np.asarray(params.pick), np.asarray(params.place)
    paper = np.asarray(pp.PAPER_PAIR)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 5))
    ax.scatter(*pick.T, s=2, label="step 1 tips (pick targets)")
    ax.scatter(*place.T, s=2, alpha=0.5, label="step 2 tips (place targets)")
    ax.plot(*paper.T, "r*", ms=12, label="paper's pair (Table I)")
    c = np.linspace(0, 2 * np.pi, 200)
    ax.plot(np.cos(c), np.sin(c), "k:", lw=0.8, label="1 m circle")
    ax.plot(0, 0, "ko")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="center", bbox_to_anchor=(0.5, 0.68), fontsize=8)  # inside the band: no point hidden
    ax.set_title("reachable targets (end-of-step tips of random actions)")
    for pts, lab in ((pick, "step 1"), (place, "step 2")):
        bx.scatter(np.degrees(np.arctan2(pts[:, 0], -pts[:, 1])), 100 * np.hypot(*pts.T), s=2, label=lab)
    bx.plot(np.degrees(np.arctan2(paper[:, 0], -paper[:, 1])), 100 * np.hypot(*paper.T), "r*", ms=12,
            label="paper's pair")
    bx.set_xlabel("tip angle about the joint [deg] (0: hanging, 180: upright)")
    bx.set_ylabel("distance from the joint [cm]")
    bx.legend(fontsize=8)
    bx.set_title("the reachable band (radius vs angle)")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def learning_curve(metrics_csv, path) -> Path:
    """Mean reward per step (episode return / 2) and step-2 distance vs episodes."""
    import csv

    with open(metrics_csv, newline="") as f:
        rows = list(csv.DictReader(f))
    ep = np.array([float(r["episodes"]) for r in rows])
    reward = np.array([float(r["episode_reward"]) for r in rows]) / 2.0
    dist = np.array([float(r.get("episode_distance", "nan")) for r in rows])
    wall = np.array([float(r["wall_s"]) for r in rows])
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(ep, reward, "tab:blue", label="mean reward per step (stochastic policy)")
    ax.set_xlabel("episodes")
    ax.set_ylabel("reward per step", color="tab:blue")
    ax.set_ylim(0, 1.02)
    bx = ax.twinx()
    bx.semilogy(ep, 100 * dist, "tab:red", lw=0.8, label="step-2 distance")
    bx.set_ylabel("step-2 distance [cm] (stochastic policy)", color="tab:red")
    ax.grid(alpha=0.3)
    ax.set_title(f"PPO on pick and place ({ep[-1]:.0f} episodes, {wall[-1]:.0f} s wall incl. setup)")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return Path(path)


def policy_actions(ckpt, targets):
    """``(env params, actions (2, 2))``: the checkpoint's deterministic policy on a target pair (2, 2)."""
    config, env, params, net = load_policy(ckpt)
    policy = make_policy(config, env.action_size, net)
    acts = jax.jit(lambda t: pp.rollout(params, policy, t))(jnp.asarray(targets)[None])[0]
    return params, np.asarray(acts[0])


def table1(params, actions, targets, out: Path) -> dict:
    d, tips = jax.jit(lambda a, t: pp.episode_distances(params, a, t))(jnp.asarray(actions), jnp.asarray(targets))
    theta, tension = pp.action_to_physical(jnp.asarray(actions), params)
    rows = []
    lines = ["|        | X_target [m] | Y_target [m] | X_tip [m] | Y_tip [m] | Distance [cm] "
             "| theta_F [deg] | T [N] |", "|---|---|---|---|---|---|---|---|"]
    for k in range(2):
        t, p = targets[k], np.asarray(tips[k])
        rows.append({"target": list(map(float, t)), "tip": p.tolist(), "distance_m": float(d[k]),
                     "theta_final_rad": float(theta[k]), "tension_N": float(tension[k])})
        lines.append(f"| Step {k + 1} | {t[0]:.3f} | {t[1]:.3f} | {p[0]:.3f} | {p[1]:.3f} | "
                     f"{100 * float(d[k]):.2f} | {np.degrees(float(theta[k])):.1f} | {float(tension[k]):.1f} |")
    (out / "pickplace_table1.md").write_text("\n".join(lines) + "\n")
    (out / "pickplace_table1.json").write_text(json.dumps(rows, indent=2))
    print("\n".join(lines))
    return {"rows": rows}


def main(argv: list[str]) -> None:
    if any(a in ("-h", "--help", "help") for a in argv):
        print(__doc__.strip())
        return
    args = {"checkpoint": "", "out": "figures"}
    for item in argv:
        key, _, value = item.partition("=")
        if key not in args:
            raise SystemExit(f"unknown argument {item!r}; valid: checkpoint=PATH out=DIR")
        args[key] = value
    out = Path(args["out"])
    out.mkdir(parents=True, exist_ok=True)
    params = pp.make_params()
    print("wrote", reachable_figure(params, out / "pickplace_reachable.png"))
    if args["checkpoint"]:
        targets = np.asarray(pp.PAPER_PAIR)
        params, actions = policy_actions(args["checkpoint"], targets)
        table1(params, actions, targets, out)
        print("wrote", out / "pickplace_table1.md", out / "pickplace_table1.json")
        print("wrote", episode_figure(params, actions, targets, out / "pickplace_fig6.png"))
        metrics = resolve(args["checkpoint"]).parent / "metrics.csv"
        if metrics.exists():
            print("wrote", learning_curve(metrics, out / "pickplace_learning_curve.png"))


if __name__ == "__main__":
    main(sys.argv[1:])
