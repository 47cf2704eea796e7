"""GIF animations of a task, drawn by the task itself.

    python -m gvsjax.animate task=basketball T=2 delta=0.9 out=throw.gif
    python -m gvsjax.animate task=pickplace action=0.5,0.6,-0.7,0.2 out=pickplace.gif
    python -m gvsjax.animate checkpoint=RUN_DIR out=episode.gif   # a closed-loop task's trained policy
    python -m gvsjax.animate task=NAME --help        # the task's keys and defaults

Each task lists its keys in ``Environment.animation_keys``; the shapes come
from the simulator's saved states, frames uniform in simulated time.
"""

from __future__ import annotations

import gc
import sys
from pathlib import Path
from typing import Any

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax.ppo import checkpoint as ckpt
from gvsjax.tasks import DEFAULT_TASK, make, registered
from gvsjax.utils import keyvalue

USAGE = __doc__.strip()


def parse_args(argv: list[str]) -> tuple[str, Path, dict]:
    """(task, GIF path, the task's animation keys) from ``key=value`` words; with
    ``checkpoint=`` the keys hold the checkpoint file and the task is the checkpoint's."""
    early = keyvalue.parse([a for a in argv if a.startswith(("task=", "checkpoint="))],
                           {"task": str, "checkpoint": str})
    checkpoint = ckpt.resolve(early["checkpoint"]) if early.get("checkpoint") else None
    task = ckpt.load_raw(checkpoint)["task"] if checkpoint else early.get("task", DEFAULT_TASK)
    if early.get("task") and early["task"] != task:
        raise ValueError(f"checkpoint is for task={task!r}, not {early['task']!r}")
    if task not in registered():
        raise ValueError(f"task={task!r} is unknown; choose one of {registered()}")
    env = make(task)
    if not env.animation_keys:
        raise ValueError(f"task={task!r} has no animation")
    if checkpoint and not env.animates_policy:
        raise ValueError(f"task={task!r} animates the keys {sorted(env.animation_keys)}, not a checkpoint's policy")
    options: dict[str, Any] = {"task": str, "out": str, "checkpoint": str,
                               **{k: keyvalue.typed(v) for k, v in env.animation_keys.items()}}
    args = keyvalue.parse(argv, options)
    args.pop("task", None)
    args.pop("checkpoint", None)
    if checkpoint:
        args["checkpoint"] = checkpoint
    out = Path(args.pop("out", "") or f"{task}.gif")
    return task, out, args


def _policy(checkpoint: Path):
    config, env, _, net = ckpt.load_policy(checkpoint)
    return ckpt.make_policy(config, env.action_size, net)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if any(a in ("-h", "--help", "help") for a in argv):
        print(USAGE)
        for task in registered():
            keys = make(task).animation_keys
            if keys:
                print(f"  task={task}: " + " ".join(f"{k}={v}" for k, v in keys.items()))
        return 0
    try:
        task, out, keys = parse_args(argv)
        if "checkpoint" in keys:
            keys["policy"] = _policy(keys.pop("checkpoint"))
        path = make(task).animate(out, **keys)
    except (ValueError, ckpt.CheckpointError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    # a run traces programs of ~10^5 long-lived objects; Python's full collections would rescan
    # every imported module's objects each time (~20% of the trace time)
    gc.freeze()
    sys.exit(main())
