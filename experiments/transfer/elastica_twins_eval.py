"""The benchmark tasks in gvsjax and in their PyElastica twins (``elastica_twins.py``), the same episodes.

* ``follow_target``, ``ik_4d``: the gvsjax-trained PPO policies (deterministic), on the episodes of
  ``python -m gvsjax.evaluate``'s seed (``reset`` keys ``split(PRNGKey(1_000_003), n)``, step keys
  ``fold_in(key, t)``); gvsjax runs them with ``task.rollout`` in float64.
* ``obstacles_2d``, ``obstacles_3d`` (no trained policy): open-loop random actions, uniform in [-1, 1] and
  held for ``--hold`` steps, identical in both (episode i's from ``fold_in(PRNGKey(--seed), i)``).

Per task: the benchmark's return (``discounted_returns``' ``average``) and the task's ``physical_metrics``
in both, their paired difference, the tip's distance between the two simulators, penetration. Each
PyElastica episode is cached in ``--cache`` (a rerun resumes; ``--workers 2`` spawns two processes, only
on an otherwise idle machine). ``--contact gvsjax`` runs the obstacle twins with gvsjax's penalty
(3e5 N/m^2, 1e3 N s/m^2 per metre, times the element length) instead of theirs.

    python experiments/transfer/elastica_twins_eval.py --task follow_target --episodes 100 [--first 16]
    python experiments/transfer/elastica_twins_eval.py --task obstacles_2d --episodes 40
    python experiments/transfer/elastica_twins_eval.py --task obstacles_2d --episodes 100 --checkpoint RUN --label SAC
    python experiments/transfer/elastica_twins_eval.py --figure      # figures/elastica_twins.png from the JSON
    python experiments/transfer/elastica_twins_eval.py --shapes      # the rest-shape gap of the two curvature mappings

Writes (merges into) benchmarks/elastica_twins.json.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path[:0] = [HERE, ROOT, os.path.join(ROOT, "experiments", "benchmarks")]  # bench_sim

import elastica_twins as et  # noqa: I001  (imports gvsjax, which configures JAX, first)
import jax
import jax.numpy as jnp

from gvsjax.ppo import checkpoint as ckpt
from gvsjax.tasks import make
from gvsjax.tasks.curvature.control import discounted_returns
from gvsjax.tasks.curvature.obstacles import PENALTY

EVAL_SEED = 1_000_003
CHECKPOINTS = {t: os.path.join(ROOT, "runs", "curvature_ppo_study", f"{t}_defaults_s0", "checkpoint.ckpt")
               for t in ("follow_target", "ik_4d")}
CONTACTS = {"theirs": (et.CONTACT_K, et.CONTACT_NU),  # per element
            "gvsjax": (float(PENALTY.stiffness) * et.LENGTH / et.N_EL, float(PENALTY.damping) * et.LENGTH / et.N_EL)}
LABEL = ""  # --label: the policy of a --checkpoint, in the cache's file names and the JSON entry's name
FIELDS = ("reward", "distance", "orientation", "deepest", "tip", "target", "valid")


def setup(task_name: str):
    """(task, params, policy of batched obs or None)."""
    if task_name in CHECKPOINTS:
        config, task, params, net = ckpt.load_policy(CHECKPOINTS[task_name])
        return task, params, jax.jit(ckpt.make_policy(config, task.action_size, net))
    task = make(task_name)
    return task, task.default_params(), None


def keys_and_actions(task, n: int, seed: int, hold: int):
    keys = jax.random.split(jax.random.PRNGKey(EVAL_SEED), n)
    actions = np.stack([et.held_actions(jax.random.fold_in(jax.random.PRNGKey(seed), i), task.episode_length,
                                        task.action_size, hold) for i in range(n)])
    return keys, actions


_CACHE: dict = {}


def _episode(job) -> tuple[int, dict]:
    """One PyElastica episode (in this process or a spawned worker)."""
    task_name, i, n, seed, hold, contact, checkpoint = job
    if checkpoint:  # a spawned worker starts from the module's defaults
        CHECKPOINTS[task_name] = checkpoint
    if job[:1] + job[2:] not in _CACHE:  # one twin (its jitted reward and observation) for all episodes
        task, params, policy = setup(task_name)
        _CACHE[job[:1] + job[2:]] = (task, policy, et.ElasticaTwin(task, params, contact=CONTACTS[contact]),
                                     *keys_and_actions(task, n, seed, hold))
    task, policy, twin, keys, actions = _CACHE[job[:1] + job[2:]]
    twin.steps_simulated = 0
    if policy is not None:
        out = et.run_episode(twin, keys[i], policy=lambda obs: np.asarray(policy(jnp.asarray(obs)[None])[0]))
    else:
        out = et.run_episode(twin, keys[i], actions=actions[i])
    out["verlet_steps"] = twin.steps_simulated
    return i, out


def elastica_runs(task_name, n, seed, hold, contact, cache_dir, workers, first) -> dict:
    """Per-step arrays (first, T, ...) of the first ``first`` of the n PyElastica episodes, cached one file
    per episode."""
    os.makedirs(cache_dir, exist_ok=True)
    tag = f"{task_name}_{LABEL}" if LABEL else task_name
    path = lambda i: os.path.join(cache_dir, f"{tag}_{contact}_n{n}_s{seed}_h{hold}_{i}.npz")  # noqa: E731
    job = (task_name, n, seed, hold, contact, CHECKPOINTS.get(task_name, "") if LABEL else "")
    todo = [(job[0], i, *job[1:]) for i in range(first) if not os.path.exists(path(i))]
    print(f"{task_name}: {first - len(todo)} PyElastica episodes cached, {len(todo)} to run", flush=True)
    t0 = time.perf_counter()

    def save(i, out):
        np.savez(path(i), **out)
        print(f"  episode {i}: {out['wall_s']:.1f} s, return {np.sum(out['reward']):.2f} "
              f"({time.perf_counter() - t0:.0f} s so far)", flush=True)

    if workers > 1 and todo:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(workers) as pool:  # spawn: never fork a process running JAX
            for i, out in pool.imap_unordered(_episode, todo):
                save(i, out)
    else:
        for job in todo:
            save(*_episode(job))
    runs = [dict(np.load(path(i))) for i in range(first)]
    return {k: np.stack([r[k] for r in runs]) for k in (*FIELDS, "wall_s", "verlet_steps")}


def gvsjax_runs(task, params, policy, keys, actions) -> dict:
    if policy is None:
        out = et.gvsjax_open_loop(task, params, keys, actions)
        out["orientation"] = np.zeros_like(out["distance"])
        return out
    out = jax.jit(lambda k: task.rollout(params, policy, k))(keys)
    out = {k: np.asarray(v) for k, v in out.items() if k != "first"}
    out["orientation"] = out.get("orientation", np.zeros_like(out["distance"]))
    return out


def stats(x) -> dict:
    x = np.asarray(x, float)
    return {"mean": float(np.mean(x)), "median": float(np.median(x)), "std": float(np.std(x)),
            "p05": float(np.percentile(x, 5)), "p95": float(np.percentile(x, 95))}


def compare(task, params, g: dict, e: dict) -> dict:
    """Side by side: the returns, the task's physical metrics, and the two simulators' tip distance."""
    side = {}
    for name, out in (("gvsjax", g), ("pyelastica", e)):
        ret = discounted_returns(out["reward"], out["valid"])
        side[name] = {"discounted_return_average": stats(ret["average"]),
                      "discounted_return_start": stats(ret["start"]), "return": stats(ret["undiscounted"]),
                      "valid_fraction": float(np.mean(out["valid"][:, -1])),
                      "deepest_m": stats(out["deepest"][:, -1]),
                      **task.physical_metrics({**out, "valid": out["valid"].astype(bool)}, params),
                      "per_episode_return": [float(x) for x in ret["average"]]}
    rg = np.array(side["gvsjax"]["per_episode_return"])
    re = np.array(side["pyelastica"]["per_episode_return"])
    both = g["valid"] & e["valid"].astype(bool)
    tip = np.linalg.norm(g["tip"] - e["tip"], axis=-1)
    tip = np.where(both, tip, np.nan)
    return {**side, "paired": {
        "return_difference": stats(re - rg),
        "relative_mean_difference": float((re.mean() - rg.mean()) / abs(rg.mean())) if rg.mean() else None,
        # None where every episode is the same (obstacles_2d: a fixed start, layout and target)
        "mean_difference_over_gvsjax_std": float((re.mean() - rg.mean()) / rg.std()) if rg.std() > 0 else None,
        "return_correlation": float(np.corrcoef(rg, re)[0, 1]) if rg.std() > 0 and re.std() > 0 else None,
        "tip_distance_m": {"mean": float(np.nanmean(tip)), "median": float(np.nanmedian(tip)),
                           "p95": float(np.nanpercentile(tip, 95)), "max": float(np.nanmax(tip))},
        "targets_identical": bool(np.allclose(g["target"], e["target"], atol=1e-9)),
    }}


def run(args) -> None:
    from bench_sim import load_average

    task, params, policy = setup(args.task)
    n, first = args.episodes, args.first or args.episodes
    keys, actions = keys_and_actions(task, n, args.seed, args.hold)
    keys, actions = keys[:first], actions[:first]
    before, t0 = load_average(), time.perf_counter()
    e = elastica_runs(args.task, n, args.seed, args.hold, args.contact, args.cache, args.workers, first)
    wall_e = time.perf_counter() - t0
    t1 = time.perf_counter()
    g = gvsjax_runs(task, params, policy, keys, actions)
    wall_g = time.perf_counter() - t1
    res = compare(task, params, g, e)
    touches = args.task.startswith("obstacles")  # the contact law matters, policy or not
    name = f"{args.task} (gvsjax's contact law)" if touches and args.contact == "gvsjax" else args.task
    name = f"{name} ({LABEL} policy)" if LABEL else name
    ep = int(np.argsort(res["pyelastica"]["per_episode_return"])[first // 2])  # the median episode, for the figure
    res.update(task=args.task, n_episodes=first, of_keys=f"the first {first} of split(PRNGKey({EVAL_SEED}), {n})",
               policy=CHECKPOINTS.get(args.task, f"open loop, held {args.hold} steps, "
                                                                                 f"seed {args.seed}"),
               contact=args.contact if touches else None, eval_seed=EVAL_SEED, label=LABEL,
               pyelastica={**res["pyelastica"], "seconds_per_episode": stats(e["wall_s"]),
                           "verlet_steps_per_episode": int(np.max(e["verlet_steps"])),
                           "wall_s_this_run": wall_e},
               gvsjax={**res["gvsjax"], "wall_s": wall_g},
               figure_episode={"index": ep, "tip_gvsjax": g["tip"][ep].tolist(),
                               "tip_pyelastica": e["tip"][ep].tolist(), "target": g["target"][ep].tolist()},
               command=f"python experiments/transfer/elastica_twins_eval.py --task {args.task} --episodes {n} "
                       f"--first {first} --hold {args.hold} --seed {args.seed} --contact {args.contact}"
                       + (f" --checkpoint {args.checkpoint} --label {LABEL}" if LABEL else ""),
               load_average_before=before, load_average_after=load_average(), getloadavg=list(os.getloadavg()))
    data = json.load(open(args.json)) if os.path.exists(args.json) else {}
    data[name] = res
    with open(args.json, "w") as fh:
        json.dump(data, fh, indent=1)
    s, p = res, res["paired"]
    print(f"{name}: return gvsjax {s['gvsjax']['discounted_return_average']['mean']:.3f}, PyElastica "
          f"{s['pyelastica']['discounted_return_average']['mean']:.3f} (paired difference median "
          f"{p['return_difference']['median']:.3f}); tip distance median {100 * p['tip_distance_m']['median']:.1f} cm")


def figure(path_json: str, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = json.load(open(path_json))
    # each task's SAC-policy entry where there is one (--label SAC, their contact law), else its default
    names = [(k, f"{k} (SAC policy)" if f"{k} (SAC policy)" in data else k)
             for k in ("follow_target", "ik_4d", "obstacles_2d", "obstacles_3d") if k in data]
    fig, axes = plt.subplots(2, len(names), figsize=(4.2 * len(names), 7.2), squeeze=False)
    for j, (name, entry) in enumerate(names):
        f = data[entry]["figure_episode"]
        tg, te, tt = (np.array(f[k]) for k in ("tip_gvsjax", "tip_pyelastica", "target"))
        t = 0.1 * np.arange(1, len(tg) + 1) * (5 if name.startswith("obstacles") else 1)
        ax = axes[0, j]
        if name == "obstacles_2d":
            from gvsjax.tasks.curvature.layouts import POSTS_XZ

            for x, z in POSTS_XZ:
                ax.add_patch(plt.Circle((x, z), 0.1, color="0.8"))
                ax.add_patch(plt.Circle((x, z), 0.1 + et.RADIUS, fill=False, ls=":", color="0.5"))
        k = 100 if name == "follow_target" else len(tg)  # follow_target: the first 10 s of 50
        ax.plot(tt[:k, 0], tt[:k, 2], "k:", lw=1.5, label="target")
        ax.plot(tg[:k, 0], tg[:k, 2], lw=1.2, label="gvsjax tip")
        ax.plot(te[:k, 0], te[:k, 2], lw=1.2, ls="--", label="PyElastica tip")
        ax.plot(*tt[0, [0, 2]], "ko", ms=4)
        span = " (first 10 s)" if k < len(tg) else ""
        who = "SAC" if entry != name else ("open loop" if name.startswith("obstacles") else "PPO")
        ax.set(xlabel="x (m)", ylabel="z (m)", title=f"{name} ({who}), episode {f['index']}{span}: x-z",
               aspect="equal")
        ax.legend(fontsize=7)
        bx = axes[1, j]
        bx.plot(t, 100 * np.linalg.norm(tg - tt, axis=1), label="gvsjax: tip to target")
        bx.plot(t, 100 * np.linalg.norm(te - tt, axis=1), ls="--", label="PyElastica: tip to target")
        bx.plot(t, 100 * np.linalg.norm(te - tg, axis=1), color="0.4", lw=0.8, label="between the two tips")
        bx.set(xlabel="t (s)", ylabel="cm", title="distances")
        bx.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


def rest_shape_gap(path_json: str, n: int = 100) -> None:
    """The curvature mapping alone: the rest-shape tips of the discrete rod and gvsjax's continuum
    (``elastica_twins.rest_tips``) for n random turning angles uniform in [-a, a] per point and direction."""
    rng = np.random.default_rng(0)
    rows = []
    for amp in (0.5, 1.0, 2.0):
        d = [np.linalg.norm(np.subtract(*et.rest_tips(th))) for th in rng.uniform(-amp, amp, (n, 5, 2))]
        rows.append({"amplitude_rad": amp, "n": n, "tip_gap_m": stats(d) | {"max": float(np.max(d))}})
        print(f"|theta| <= {amp}: rest-shape tips {1000 * np.median(d):.2f} mm apart (median)", flush=True)
    data = json.load(open(path_json)) if os.path.exists(path_json) else {}
    data["_rest_shape_gap"] = {"rows": rows, "command": "python experiments/transfer/elastica_twins_eval.py --shapes"}
    with open(path_json, "w") as fh:
        json.dump(data, fh, indent=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", choices=("follow_target", "ik_4d", "obstacles_2d", "obstacles_3d"))
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--first", type=int, default=0, help="run only the first of the --episodes episodes (0: all)")
    ap.add_argument("--hold", type=int, default=10, help="steps each open-loop action is held (obstacle tasks)")
    ap.add_argument("--seed", type=int, default=0, help="of the open-loop actions")
    ap.add_argument("--contact", choices=tuple(CONTACTS), default="theirs")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--checkpoint", default="", help="a run folder or checkpoint: its policy instead of the default "
                    "(then also give --label; one worker)")
    ap.add_argument("--label", default="", help="names the --checkpoint's policy, e.g. SAC")
    ap.add_argument("--cache", default=os.path.join(ROOT, "runs", "elastica_twins"))
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "elastica_twins.json"))
    ap.add_argument("--figure", action="store_true", help="only draw figures/elastica_twins.png from the JSON")
    ap.add_argument("--shapes", action="store_true", help="only the rest-shape gap of the two curvature mappings")
    args = ap.parse_args()
    if bool(args.checkpoint) != bool(args.label):
        ap.error("--checkpoint and --label go together")
    if args.checkpoint:
        global LABEL
        CHECKPOINTS[args.task], LABEL = args.checkpoint, args.label
    if args.figure:
        figure(args.json, os.path.join(ROOT, "figures", "elastica_twins.png"))
    elif args.shapes:
        rest_shape_gap(args.json)
    else:
        run(args)


if __name__ == "__main__":
    main()
