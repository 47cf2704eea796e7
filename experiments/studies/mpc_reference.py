"""The MPC (gvsjax.mpc: by gradients, or by sampling with planner=mppi) as a reference for a task's trained
policy, on the same episodes.

    python experiments/studies/mpc_reference.py --task balance --episodes 100 [--checkpoint RUN_DIR]
        [-- horizon=10 iterations=10 gradient=forward learning_rate=0.2]
    python experiments/studies/mpc_reference.py --task balance --checkpoint RUN_DIR --policy-only

Writes benchmarks/mpc_reference/<task>.json (``--variant V``: <task>_V.json): the controller's settings,
its evaluation (the task's metrics, from ``reset`` keys of ``--seed``), its wall time (compilation
included) and the machine's load; with ``--checkpoint``, the policy's evaluation on the same keys
beside it (``--policy-only``: added to the committed file, the controller's run kept; ``--policy-from
FILE``: copied from another committed file on the same episodes). ``--table``
prints the committed results (the docs' ``mpc_reference`` table, docs/gen_results.py).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax import evaluate, mpc
from gvsjax.utils import keyvalue

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks" / "mpc_reference"


def _path(task: str, variant: str) -> Path:
    return OUT / (f"{task}_{variant}.json" if variant else f"{task}.json")


def add_policy(task: str, checkpoint: str, variant: str = "") -> dict:
    """The committed file of ``task`` with the policy ``checkpoint`` evaluated on its episodes."""
    path = _path(task, variant)
    record = json.loads(path.read_text())
    start = time.perf_counter()
    work = ROOT / "runs" / "mpc_reference" / _path(task, variant).stem
    record["policy"] = evaluate.evaluate_run(checkpoint, work / "policy", record["episodes"], record["seed"])
    record["policy"]["wall_s"] = time.perf_counter() - start
    record["policy_command"] = "python experiments/studies/mpc_reference.py " + " ".join(sys.argv[1:])
    _write(path, record)
    return record


def policy_from(task: str, variant: str, source: str) -> dict:
    """The committed ``<task>_<variant>.json`` with the policy evaluation of another committed file of
    the task, whose episodes (``seed``, ``episodes``) must be the same: a deterministic policy on the same
    ``reset`` keys gives the same episodes, so its evaluation is copied with the file it came from."""
    path, other = _path(task, variant), Path(source)
    record, theirs = json.loads(path.read_text()), json.loads(other.read_text())
    if "policy" not in theirs:
        raise ValueError(f"{other} holds no policy evaluation")
    same = ("task", "seed", "episodes")
    if any(record[k] != theirs[k] for k in same):
        raise ValueError(f"{other} ran other episodes: {[theirs[k] for k in same]} against {[record[k] for k in same]}")
    record["policy"] = {**theirs["policy"], "copied_from": os.path.relpath(other, ROOT)}
    record["policy_command"] = theirs.get("policy_command", theirs["command"])
    _write(path, record)
    return record


def _write(path: Path, record: dict) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(record, indent=2))
    tmp.replace(path)
    print(f"wrote {path}")


def mpc_config(overrides: list[str]) -> mpc.MPCConfig:
    """The controller's settings: ``gvsjax.evaluate``'s defaults with ``key=value`` overrides."""
    types = {k: keyvalue.typed(evaluate.KEYS[k]) for k in evaluate.MPC_KEYS}
    return mpc.MPCConfig(**{**{k: evaluate.KEYS[k] for k in evaluate.MPC_KEYS}, **keyvalue.parse(overrides, types)})


def run(task: str, episodes: int, seed: int, overrides: list[str], checkpoint: str, variant: str = "") -> dict:
    config = mpc_config(overrides)
    load_before = os.getloadavg()
    work = ROOT / "runs" / "mpc_reference" / _path(task, variant).stem
    controller = evaluate.evaluate_controller(task, work / "mpc", config, episodes, seed)
    record = {"task": task, "command": "python experiments/studies/mpc_reference.py " + " ".join(sys.argv[1:]),
              "episodes": episodes, "seed": seed, "controller": controller,
              "load_before": load_before, "load_after": os.getloadavg()}
    if checkpoint:
        start = time.perf_counter()
        record["policy"] = evaluate.evaluate_run(checkpoint, work / "policy", episodes, seed)
        record["policy"]["wall_s"] = time.perf_counter() - start
    OUT.mkdir(parents=True, exist_ok=True)
    _write(_path(task, variant), record)
    return record


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", default="balance")
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1_000_003)
    ap.add_argument("--checkpoint", default="", help="a trained policy's run folder, evaluated on the same keys")
    ap.add_argument("--policy-only", action="store_true",
                    help="add the --checkpoint policy's evaluation to the committed file, on its episodes")
    ap.add_argument("--policy-from", default="",
                    help="copy the policy evaluation of another committed file of the task on the same episodes")
    ap.add_argument("--variant", default="", help="a second run on a task: written to <task>_<variant>.json")
    ap.add_argument("--table", action="store_true", help="print the committed results")
    ap.add_argument("overrides", nargs="*", help="MPC settings as key=value (after --)")
    args = ap.parse_args()
    if args.table:
        sys.path.insert(0, str(ROOT / "docs"))
        from gen_results import mpc_reference

        print(mpc_reference(ROOT))
        return
    if args.policy_from:
        policy_from(args.task, args.variant, args.policy_from)
        return
    if args.policy_only:
        if not args.checkpoint:
            ap.error("--policy-only needs --checkpoint RUN_DIR")
        add_policy(args.task, args.checkpoint, args.variant)
        return
    run(args.task, args.episodes, args.seed, args.overrides, args.checkpoint, args.variant)


if __name__ == "__main__":
    main()
