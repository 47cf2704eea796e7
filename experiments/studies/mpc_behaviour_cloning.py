"""A policy from the model: behaviour cloning of the gradient MPC (gvsjax.mpc), against the PPO default.

Three stages, each kept on disk so a rerun resumes where the last one stopped:

1. ``collect``: the MPC runs ``--episodes`` training episodes (``reset`` keys of ``--seed``, apart from
   the evaluation's), ``--batch`` at a time in one jitted program, in the task's training precision.
   Each chunk's observations and the MPC's actions go to ``runs/mpc_bc/<task>/demos_<i>.npz``.
2. ``clone``: the task's PPO actor-critic (its ``ppo_defaults``) with the actor's mean fitted to the
   MPC's actions by least squares (Adam, minibatches; 10% of the episodes held out to pick the epoch);
   the critic and the log-std stay at their initial values. Saved as a PPO checkpoint (update 0), so
   ``python -m gvsjax.evaluate checkpoint=...`` reads it, and ``python -m gvsjax.train resume=true``
   continues it with PPO.
3. ``evaluate``: 1000 held-out episodes (``gvsjax.evaluate``'s seed), beside the committed PPO default
   runs (``benchmarks/curvature_ppo_study/<task>_defaults_*.json``): its return and its wall time.

    python experiments/studies/mpc_behaviour_cloning.py --task ik_4d --episodes 64 --batch 32 -- horizon=5 iterations=3
    python experiments/studies/mpc_behaviour_cloning.py --table

Writes benchmarks/mpc_bc/<task>.json: the MPC settings, each stage's wall time (compilation included;
the collection's compile time from JAX's compile events), the clone's fit and its evaluation.
"""

from __future__ import annotations  # noqa: I001  (gvsjax configures JAX, so it is imported first)

import argparse
import dataclasses
import glob
import json
import os
import sys
import time
from pathlib import Path

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
import jax
import jax.numpy as jnp
import numpy as np
import optax

from gvsjax import evaluate, mpc
from gvsjax.ppo import checkpoint as ckpt
from gvsjax.ppo.config import build_config
from gvsjax.ppo.networks import make_network
from gvsjax.ppo.train import init
from gvsjax.tasks import make
from gvsjax.train import task_defaults, training_params
from gvsjax.utils.compile_clock import compile_seconds
from mpc_reference import mpc_config  # this folder is on sys.path when run as a script

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks" / "mpc_bc"
EVAL_SEED = 1_000_003


def collect(task: str, episodes: int, batch: int, seed: int, config: mpc.MPCConfig, work: Path) -> dict:
    """MPC episodes in chunks of ``batch``; each chunk's (obs, action) saved; resumes from saved chunks."""
    if episodes % batch:
        raise ValueError(f"--episodes ({episodes}) must be a multiple of --batch ({batch})")
    env = make(task)
    params = training_params(env)
    controller = mpc.MPC(env, params, config)
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))

    @jax.jit
    def chunk(keys):
        obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)

        def one(carry, t):
            obs, s, plan = carry
            action, plan = controller.act(plan, obs, s, t)
            new_obs, s, reward, _, info = step(jax.vmap(lambda k: jax.random.fold_in(k, t))(keys), s, action,
                                               params)
            return (new_obs, s, plan), (obs, action, reward, info["valid"])

        _, out = jax.lax.scan(one, (obs, state, controller.init(obs, state)), jnp.arange(env.episode_length))
        return jax.tree.map(lambda x: jnp.swapaxes(x, 0, 1), out)

    keys = jax.random.split(jax.random.PRNGKey(seed), episodes)
    times = []
    for i in range(episodes // batch):
        path, timing = work / f"demos_{i}.npz", work / f"demos_{i}.json"
        if not path.exists():
            start = time.perf_counter()
            with compile_seconds() as compiling:
                obs, action, reward, valid = jax.block_until_ready(chunk(keys[i * batch:(i + 1) * batch]))
            tmp = work / f".demos_{i}.tmp.npz"
            np.savez(tmp, obs=np.asarray(obs, np.float32), action=np.asarray(action, np.float32),
                     reward=np.asarray(reward, float), valid=np.asarray(valid, bool))
            tmp.replace(path)
            timing.write_text(json.dumps({"chunk": i, "wall_s": time.perf_counter() - start,
                                          "compile_s": compiling[0], "load": os.getloadavg()}))
            print(f"chunk {i}: {time.perf_counter() - start:.0f} s (compile {compiling[0]:.0f} s), "
                  f"mean reward {float(np.mean(reward)):.3f}", flush=True)
        times.append(json.loads(timing.read_text()))
    return {"batch": batch, "chunks": times}


def load_demos(work: Path) -> dict[str, np.ndarray]:
    files = sorted(glob.glob(str(work / "demos_*.npz")), key=lambda p: int(Path(p).stem.split("_")[1]))
    if not files:
        raise FileNotFoundError(f"no demonstrations in {work}: run the collection first")
    parts = [np.load(f) for f in files]
    return {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "action", "reward", "valid")}


def clone(task: str, demos: dict, work: Path, epochs: int, seed: int) -> dict:
    """The PPO default network with its actor's mean fitted to the demonstrations; saved as a checkpoint."""
    env = make(task)
    config = build_config(task_defaults(task), "none", {"seed": seed})
    state = init(config, env, training_params(env), jax.random.PRNGKey(seed))
    network = make_network(config, env.action_size)

    def apply(p, o):
        return network.apply(p, o)[0]  # the Gaussian's mean

    ok = demos["valid"].all(axis=1)  # episodes that stayed finite
    n_ep = int(ok.sum())
    if n_ep < 2:
        raise ValueError(f"{n_ep} of the {len(ok)} demonstrations stayed finite; cloning needs at least 2")
    held = max(1, n_ep // 10)
    idx = np.flatnonzero(ok)
    rng = np.random.default_rng(seed)
    rng.shuffle(idx)
    split = {"train": idx[held:], "held": idx[:held]}
    data = {k: (demos["obs"][v].reshape(-1, env.obs_size), demos["action"][v].reshape(-1, env.action_size))
            for k, v in split.items()}
    opt = optax.adam(1e-3)
    params = state.params
    opt_state = opt.init(params)

    def loss(p, o, a):
        return jnp.mean(jnp.sum((apply(p, o) - a) ** 2, axis=-1))

    @jax.jit
    def update(p, s, o, a):
        value, grad = jax.value_and_grad(loss)(p, o, a)
        updates, s = opt.update(grad, s, p)
        return optax.apply_updates(p, updates), s, value

    start = time.perf_counter()
    o_train, a_train = data["train"]
    o_held, a_held = (jnp.asarray(x) for x in data["held"])
    best = (np.inf, params, 0)
    curve = []
    for epoch in range(epochs):
        order = rng.permutation(len(o_train))
        for j in range(0, len(order) - 255, 256):
            b = order[j:j + 256]
            params, opt_state, _ = update(params, opt_state, jnp.asarray(o_train[b]), jnp.asarray(a_train[b]))
        held_loss = float(loss(params, o_held, a_held))
        curve.append(held_loss)
        if held_loss < best[0]:
            best = (held_loss, params, epoch)
    state = dataclasses.replace(state, params=best[1])
    config_dict = {"task": task, "algo": "ppo", "train_targets": "", "sim_dtype": env.train_sim_dtype,
                   "randomize": "", "randomize_observe": False, **dataclasses.asdict(config)}
    ckpt.save(work / ckpt.FILE_NAME, state, config_dict, task, 0, {"source": "behaviour cloning of the MPC"})
    return {"wall_s": time.perf_counter() - start, "pairs_train": int(len(o_train)), "pairs_held": int(len(o_held)),
            "episodes_used": n_ep, "epochs": epochs, "best_epoch": best[2], "held_mse": best[0],
            "held_mse_curve": curve, "action_variance": float(np.mean(np.sum(np.var(a_held, 0), -1)))}


def ppo_defaults(task: str) -> list[dict]:
    rows = []
    for f in sorted(glob.glob(str(ROOT / "benchmarks" / "curvature_ppo_study" / f"{task}_defaults_*.json"))):
        d = json.loads(Path(f).read_text())
        t = d["timing"]
        rows.append({"file": os.path.relpath(f, ROOT), "episodes": t["episodes"],
                     "wall_s": t["setup_s"] + t["first_call_s"] + t["train_s"],
                     "discounted_return_average": d["eval"]["discounted_return_average"]["mean"]})
    return rows


def _write(path: Path, record: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(record, indent=2))
    tmp.replace(path)
    print(f"wrote {path}")


def table(root: Path = ROOT) -> str:
    """The committed results (``benchmarks/mpc_bc/*.json``) as a Markdown table."""
    lines = ["| task | MPC | demonstrations | MPC wall time (compiling) | clone's fit: held-out error / "
             "action variance | clone, 1000 held-out episodes | PPO default (return, wall time) |",
             "|---|---|---|---|---|---|---|"]
    for f in sorted((root / "benchmarks" / "mpc_bc").glob("*.json")):
        d = json.loads(f.read_text())
        s, c, chunks = d["controller"], d["clone"], d["collect"]["chunks"]
        ppo = "; ".join(f"{r['discounted_return_average']:.1f}, {r['wall_s'] / 60:.0f} min ({r['episodes']} episodes)"
                        for r in d["ppo_defaults"])
        lines.append(
            f"| `{d['task']}` | H {s['horizon']}, {s['iterations']} Adam steps | {d['episodes']} episodes, "
            f"{c['pairs_train'] + c['pairs_held']} pairs | {sum(x['wall_s'] for x in chunks) / 60:.0f} min "
            f"({sum(x['compile_s'] for x in chunks) / 60:.0f} min) | {c['held_mse']:.2f} / {c['action_variance']:.2f} "
            f"| discounted return {d['eval']['discounted_return_average']['mean']:.1f} | {ppo} |")
    return "\n".join(lines) + "\n\nData: `benchmarks/mpc_bc/*.json`."


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", default="ik_4d")
    ap.add_argument("--episodes", type=int, default=64)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--seed", type=int, default=7, help="the demonstrations' reset keys and the network's init")
    ap.add_argument("--epochs", type=int, default=200)
    ap.add_argument("--eval", type=int, default=1000)
    ap.add_argument("--work", default="", help="the run folder (default runs/mpc_bc/<task>)")
    ap.add_argument("--json", default="", help="the result file (default benchmarks/mpc_bc/<task>.json)")
    ap.add_argument("--table", action="store_true", help="print the committed results")
    ap.add_argument("overrides", nargs="*", help="MPC settings as key=value (after --)")
    args = ap.parse_args()
    if args.table:
        print(table())
        return
    if args.seed == EVAL_SEED:
        ap.error(f"--seed {EVAL_SEED} is the evaluation's; the demonstrations need other episodes")
    config = mpc_config(args.overrides)
    work = Path(args.work) if args.work else ROOT / "runs" / "mpc_bc" / args.task
    work.mkdir(parents=True, exist_ok=True)
    record = {"task": args.task, "command": "python experiments/studies/mpc_behaviour_cloning.py "
              + " ".join(sys.argv[1:]), "episodes": args.episodes, "seed": args.seed,
              "controller": mpc.describe(config), "load_before": os.getloadavg()}
    record["collect"] = collect(args.task, args.episodes, args.batch, args.seed, config, work)
    demos = load_demos(work)
    record["demo_mean_reward"] = float(np.mean(demos["reward"]))
    record["clone"] = clone(args.task, demos, work, args.epochs, args.seed)
    start = time.perf_counter()
    record["eval"] = evaluate.evaluate_run(work, work / "eval", args.eval, EVAL_SEED)
    record["eval"]["wall_s"] = time.perf_counter() - start
    record["ppo_defaults"] = ppo_defaults(args.task)
    record["load_after"] = os.getloadavg()
    _write(Path(args.json) if args.json else OUT / f"{args.task}.json", record)
    print(make(args.task).summary(record["eval"]))


if __name__ == "__main__":
    main()
