"""The bound each 3D arm task's actuation sets: how near its own targets the arm can hold its tip still.

For each task on the 3D arm (track3d, reach_pose, reach_obstacles and their muscle or
planar variants) the action box of its actuation is sampled (``holdable.sample_actions``:
corners, faces, inside), each action's static equilibrium is solved (``gv.equilibrium``,
gravity on, ``holdable.equilibrium_poses``), and each target the task itself draws is
measured against the nearest held tip (exact nearest neighbour, ``holdable.nearest``):

* track3d(_muscle): the target's position after every control step of ``--episodes``
  walks (``track3d.start`` / ``move`` with the env's keys), on the published box and on
  the task's default reachable part;
* reach_pose(_muscle): the held-out table evaluation walks through; a target counts as
  held when some equilibrium lies within the task's distance *and* angle thresholds;
* reach_obstacles(_2d): targets of the task's ``reset``; a held pose must not sink more
  than the task's ``tolerance`` into a bar at any contact sample (the task's own gaps),
  and the planar task's actions bend in the x-z plane only (its two actions). The statics
  leave the bars out (no pose carried by a bar is counted): their contact statics did not
  compile within 25 minutes on the shared 2 cores.

Convergence: the same measures on nested prefixes of the action sample, each twice the
last. ``--table`` prints the docs' table from the JSON instead (``docs/gen_results.py``,
beside each task's committed policy from ``benchmarks/eval_<task>.json``).

    python experiments/studies/tendon_reachability.py  # ~45 min on 2 busy cores; benchmarks/tendon_reachability.json
    python experiments/studies/tendon_reachability.py --table
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import gvsjax  # noqa: F401  (XLA flags and 64-bit mode before JAX starts)

# isort: split
import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.tasks import arm3d, holdable, make
from gvsjax.tasks import track3d as t3
from gvsjax.tasks.reach_obstacles import ReachObstaclesParams
from gvsjax.tasks.reach_obstacles.env import gaps
from gvsjax.tasks.reach_pose.env import SUCCESS as POSE_SUCCESS
from gvsjax.tasks.track3d.env import SETTLE_S

ROOT = Path(__file__).resolve().parents[2]
TRACK_CM = (5.0, 10.0)  # track3d's reported shares
def shares(d: np.ndarray, cm=TRACK_CM) -> dict:
    """Median distance (m) and the share within each of ``cm``."""
    return {"median_m": float(np.median(d)), **{f"within_{c:g}cm": float(np.mean(d < c / 100)) for c in cm}}


def walks(params: t3.Track3DParams, n: int, seed: int) -> np.ndarray:
    """(n, T, 3) the target after each control step of ``n`` episodes, keyed as the env's rollouts
    (reset key i of ``seed``; step t's key ``fold_in(key, t)``)."""
    def one(key):
        p, v = t3.start(key, params)

        def body(carry, t):
            p, v = t3.move(jax.random.fold_in(key, t), *carry, params)
            return (p, v), p

        return jax.lax.scan(body, (p, v), jnp.arange(params.episode_steps))[1]

    return np.asarray(jax.jit(jax.vmap(one))(jax.random.split(jax.random.PRNGKey(seed), n)))


def nested(sizes, tips: np.ndarray, measure) -> dict:
    """``measure(tips[:n])`` for each n of ``sizes``."""
    return {str(n): measure(tips[:n]) for n in sizes}


def track_rows(name: str, actuation: str, sol: dict, sizes, args) -> list[dict]:
    rows = []
    settle = int(round(SETTLE_S / 0.1))
    for targets in ("box", "reachable"):
        params = t3.make_params(actuation, targets)
        if name == "track3d_muscle":
            params = params.replace(action_rate_weight=0.0)
        pts = walks(params, args.episodes, args.seed)

        def measure(tips, pts=pts):
            d = holdable.nearest(pts.reshape(-1, 3), tips)[0].reshape(pts.shape[:2])
            return {**shares(d), f"after_{SETTLE_S:g}s": shares(d[:, settle:])}

        rows.append({"task": name, "targets": targets, "n_targets": int(pts.shape[0] * pts.shape[1]),
                     "what": f"the target after each of {pts.shape[1]} steps of {pts.shape[0]} walks",
                     "by_samples": nested(sizes, sol["position"], measure)})
    return rows


def pose_rows(name: str, sol: dict, sizes) -> list[dict]:
    params = make(name).default_params()
    pos, axis = np.asarray(params.position), np.asarray(params.axis)

    def measure(n):
        out = shares(holdable.nearest(pos, sol["position"][:n])[0])
        for dm, deg in POSE_SUCCESS:
            held = holdable.pose_reachable(pos, axis, sol["position"][:n], sol["axis"][:n], dm, deg)
            out[f"within_{100 * dm:g}cm_{deg:g}deg"] = float(np.mean(held))
        return out

    return [{"task": name, "targets": "table", "n_targets": len(pos), "what": "the held-out poses evaluation uses",
             "by_samples": {str(n): measure(n) for n in sizes}}]


def obstacle_rows(name: str, sol: dict, sizes, args) -> list[dict]:
    env = make(name)
    params: ReachObstaclesParams = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(args.seed), args.obstacle_targets)
    state = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, params)[1]
    target = np.asarray(state.target)
    if np.any(np.asarray(state.yaw) != 0) or np.any(np.asarray(state.shift) != 0):
        raise RuntimeError("the default scene turns or moves; measure each episode's own scene")
    qd = jnp.zeros(sol["q"].shape[1])
    gap = np.asarray(jax.jit(jax.vmap(lambda q: gaps(params, 0.0, q, qd)))(jnp.asarray(sol["q"])))
    clear = gap.min(axis=1) >= -params.tolerance
    cm = (100 * params.success_distance, 10.0)

    def measure(n):
        ok = clear[:n]
        out = shares(holdable.nearest(target, sol["position"][:n][ok])[0], cm)
        return {**out, "clear_share": float(ok.mean()),
                "ignoring_obstacles": shares(holdable.nearest(target, sol["position"][:n])[0], cm)}

    return [{"task": name, "targets": "reset", "n_targets": len(target),
             "what": f"targets of {len(target)} resets (a held pose at most {1000 * params.tolerance:g} mm into a bar)",
             "by_samples": {str(n): measure(n) for n in sizes}}]


def solve(arm: arm3d.ArmParams, n: int, seed: int, k: int | None = None, full=None) -> dict:
    """Equilibria of ``n`` sampled actions (``k`` entries, mapped by ``full`` to the arm's actions)."""
    t = time.time()
    actions = holdable.sample_actions(jax.random.PRNGKey(seed), n, k or arm3d.n_actions(arm))
    sol = holdable.equilibrium_poses(arm, actions if full is None else np.asarray(full(jnp.asarray(actions))))
    bad = int(np.sum(~sol["converged"]))
    print(f"  {n} equilibria ({arm.actuation}, {actions.shape[1]} actions): {time.time() - t:.0f} s, "
          f"{bad} not converged", flush=True)
    return {k: v[sol["converged"]] for k, v in sol.items()} | {"not_converged": bad}


def run(args) -> dict:
    out: dict = {"command": "python experiments/studies/tendon_reachability.py " + " ".join(sys.argv[1:]),
                 "samples": args.samples, "doublings": args.doublings, "seed": args.seed, "rows": []}
    sizes = [args.samples >> i for i in range(args.doublings, -1, -1)]
    muscle_n = args.samples // 2
    muscle_sizes = [muscle_n >> i for i in range(args.doublings, -1, -1)]
    tendon = solve(arm3d.ArmParams(), args.samples, args.seed)
    muscle = solve(arm3d.ArmParams(actuation="muscle"), muscle_n, args.seed)
    planar_env = make("reach_obstacles_2d")
    planar_n = args.samples // 16
    planar = solve(arm3d.ArmParams(), planar_n, args.seed, k=2, full=planar_env.full_action)
    out["not_converged"] = {"tendon": tendon["not_converged"], "muscle": muscle["not_converged"],
                            "planar": planar["not_converged"]}
    out["rows"] += track_rows("track3d", "tendon", tendon, sizes, args)
    out["rows"] += track_rows("track3d_muscle", "muscle", muscle, muscle_sizes, args)
    out["rows"] += pose_rows("reach_pose", tendon, sizes)
    out["rows"] += pose_rows("reach_pose_muscle", muscle, muscle_sizes)
    out["rows"] += obstacle_rows("reach_obstacles", tendon, sizes, args)
    out["rows"] += obstacle_rows("reach_obstacles_2d", planar, [planar_n >> i for i in range(args.doublings, -1, -1)],
                                 args)
    for row in out["rows"]:
        print(json.dumps({k: row[k] for k in ("task", "targets")}), json.dumps(row["by_samples"])[:400], flush=True)
    return out


def table(data: dict) -> str:
    """The docs' markdown table of ``data`` (this script's JSON) beside the committed policies' results
    (``docs/gen_results.py``, which the docs site also uses)."""
    sys.path.insert(0, str(ROOT / "docs"))
    import gen_results

    return gen_results.reachability_table(data, lambda task: gen_results.headline(ROOT, task))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--samples", type=int, default=65536, help="tendon actions (muscle: half, planar: 1/16)")
    ap.add_argument("--doublings", type=int, default=4, help="nested prefixes, each half the next")
    ap.add_argument("--episodes", type=int, default=500, help="track3d target walks (100 steps each)")
    ap.add_argument("--obstacle-targets", type=int, default=10000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "tendon_reachability.json"))
    ap.add_argument("--table", action="store_true", help="print the markdown table of --json and exit")
    args = ap.parse_args()
    if args.table:
        print(table(json.loads(Path(args.json).read_text())))
        return
    out = run(args)
    Path(args.json).write_text(json.dumps(out, indent=1) + "\n")
    print(table(out))


if __name__ == "__main__":
    main()
