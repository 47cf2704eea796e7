"""Differentiable-physics baseline vs PPO on the same held-out throw3d targets.

    python experiments/studies/baseline_throw3d.py [run_dir] [--n 1000] [--seed 1000003] [--refine-only] [--plan]

Draws the targets exactly as ``Throw3D.evaluate`` does (``reset`` keys from
``seed``) and solves each by Gauss-Newton through the simulator from a grid of
starts (``gvsjax.tasks.throw3d.baseline.solve_targets``: ``baseline_eval.json``,
``baseline_throws.csv`` in ``run_dir``, default ``figures/``). If
``run_dir/eval.json`` holds a PPO evaluation with the same seed and count, its
summary is printed too, and the policy's actions (from ``eval_throws.csv``) are
refined by 4 Gauss-Newton steps each (``baseline.refine``: ``refined_eval.json``,
``refined_throws.csv``). ``--refine-only`` skips the solve from the grid. ``--plan`` runs only the
policy-first planner (``baseline.plan``: up to 12 Gauss-Newton steps from the policy's action, then
multi-start Gauss-Newton where the miss is still above 1 cm): ``planned_eval.json``,
``planned_throws.csv``, the latter with each target's table action (``source_*``, the grid throw that
generated it: a diagnostic, unseen by the planner).
"""

import argparse
import json
from pathlib import Path

import jax
import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax.evaluate import write_rows
from gvsjax.tasks import ballistics
from gvsjax.tasks import throw3d as t3
from gvsjax.tasks.throw3d import baseline


def _write(out: Path, stem: str, method: str, seed: int, targets, r, info=None, columns=None) -> dict:
    metrics = ballistics.miss_metrics(r["miss"])
    (out / f"{stem}_eval.json").write_text(json.dumps({"method": method, "seed": seed, "seconds": r["seconds"],
                                                       **(info or {}), **metrics}, indent=2))
    write_rows(out / f"{stem}_throws.csv", {"target_x": targets[:, 0], "target_y": targets[:, 1],
                                            "target_z": targets[:, 2], "T": r["T"], "delta": r["delta"],
                                            "yaw_deg": np.degrees(r["yaw"]), "miss_m": r["miss"], **(columns or {})})
    return metrics


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run_dir", nargs="?", default="figures")
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1_000_003)
    ap.add_argument("--refine-only", action="store_true")
    ap.add_argument("--plan", action="store_true", help="only the policy-first planner (baseline.plan)")
    args = ap.parse_args()
    out = Path(args.run_dir)
    out.mkdir(parents=True, exist_ok=True)
    env = t3.Throw3D()
    params = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(args.seed), args.n)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    targets = np.asarray(state.target)
    if not (args.refine_only or args.plan):
        r = baseline.solve_targets(params, targets)
        m = _write(out, "baseline", "gauss-newton through the simulator", args.seed, targets, r)
        print("baseline:", env.summary(m), f"({r['seconds']:.0f} s)")
    ppo = out / "eval.json"
    if ppo.exists():
        p = json.loads(ppo.read_text())
        if p.get("seed") == args.seed and p.get("n_targets") == args.n:
            print("PPO:     ", env.summary(p))
            rows = np.genfromtxt(out / "eval_throws.csv", delimiter=",", names=True)
            start = np.asarray(t3.physical_to_action(rows["T"], rows["delta"], np.radians(rows["yaw_deg"]), params))
            if args.plan:
                _plan(env, params, out, args.seed, targets, start, np.asarray(state.source_action))
                return
            f = baseline.refine(params, start, targets)
            m = _write(out, "refined", "PPO + 4 Gauss-Newton steps", args.seed, targets, f)
            print("PPO + 4 Gauss-Newton steps:", env.summary(m), f"({f['seconds']:.0f} s)")
    if args.plan:
        raise SystemExit(f"--plan needs {ppo} from the policy's evaluation with seed {args.seed}, n {args.n}")


def _plan(env, params, out: Path, seed: int, targets, start, source) -> None:
    r = baseline.plan(params, start, targets)
    T, delta, psi = (np.asarray(x) for x in t3.action_to_physical(source, params))
    info = {"fallback_targets": int(r["fallback"].sum()), "fallback_seconds": r["fallback_seconds"],
            "mean_steps": float(r["steps"].mean())}
    cols = {"start_miss_m": r["start_miss"], "steps": r["steps"], "fallback": r["fallback"].astype(int),
            "source_T": T, "source_delta": delta, "source_yaw_deg": np.degrees(psi)}
    m = _write(out, "planned", "PPO + up to 12 Gauss-Newton steps, multi-start where still > 1 cm", seed,
               targets, r, info, cols)
    print("PPO + planner:", env.summary(m), f"({r['seconds']:.0f} s, fallback on {info['fallback_targets']} "
          f"targets: {r['fallback_seconds']:.0f} s)")


if __name__ == "__main__":
    main()
