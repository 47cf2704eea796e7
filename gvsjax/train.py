"""Train a PPO agent on a gvsjax task from the command line.

    python -m gvsjax.train task=basketball [key=value ...]
    python -m gvsjax.train --help

Every ``PPOConfig`` field is a ``key=value`` override (``--help`` lists them
with the task's defaults); the run options are listed in ``RUN_DOCS``. The
run folder ``out`` receives ``config.json``, ``metrics.csv`` (one row per PPO
update; also TensorBoard events when ``tensorboardX`` or ``torch`` is
installed), ``checkpoint.ckpt`` (see ``gvsjax.checkpoint``) and, at the end,
the evaluation of ``gvsjax.evaluate`` (``eval.json``, ``eval_throws.csv``, PNG
figures). ``resume=true out=DIR`` continues the run in DIR from its last
checkpoint (optimizer state, PRNG key and update counter included); command
line overrides then apply on top of the saved config (e.g. a larger
``total_episodes``); the keys that fix the saved state's shapes or meaning
(``RESUME_FIXED``) cannot change.

Reliability: after every jitted call the losses, the other optimisation metrics
and the network weights must be finite; otherwise training stops (exit code 3)
with a message naming the metric and the update, after saving the last good
state (the one before that call) as the checkpoint, so nothing non-finite is
ever saved. A resumed run continues bit-identically to an uninterrupted one
(same metrics.csv apart from ``wall_s``): the whole ``TrainState`` (weights,
Adam moments, PRNG key, update and episode counters, env states) is
checkpointed, and rows of ``metrics.csv`` past the checkpoint are dropped.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import jax
import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax import checkpoint
from gvsjax.ppo import FIELD_DOCS, MATLAB_LIKE, PPOConfig, describe, init, make_update, num_updates
from gvsjax.ppo.config import parse_value
from gvsjax.tasks import make, registered

# Tuned per task for the least wall time to the acceptance quality (README).
TASK_DEFAULTS: dict[str, dict[str, Any]] = {
    # One throw per env step is the cost (~0.3-0.6 ms of CPU), network updates are cheap:
    # large batches, 8 epochs x 8 minibatches of reuse per batch, a high learning rate
    # annealed to 0 (a constant 1e-3 collapses once the std is small), no entropy bonus so
    # the std can shrink to the cm-level precision the task asks for. The last 0.1-0.5% of
    # targets (sparse top corners, 1 cm needs delta to 3e-4) need more: mirrored pairs (the
    # critic's error leaves the gradient), a KL-adaptive rate (the mean otherwise jumps by
    # several stds per update, KL up to 200), clipped-action log-probs (the top-right corner
    # needs T = 0.5 s, the box's edge, where the plain density feeds noise into the trunk),
    # 1.2M episodes, and training targets "mixed" (basketball.TRAIN_TARGETS).
    # Issue 7's note has the ablation.
    "basketball": dict(
        num_envs=1024, num_steps=1, num_minibatches=8, update_epochs=8,
        learning_rate=1e-3, anneal_lr=True, clip_eps=0.2, ent_coef=0.0,
        init_log_std=-1.0, min_log_std=-7.0, finetune_fraction=0.0, total_episodes=1_200_000,
        antithetic=True, adaptive_kl=0.02, clipped_log_prob=True,
    ),
}
# Named override sets applied before the user's own overrides.
PRESETS: dict[str, dict[str, Any]] = {
    "none": {},
    # the paper's two phases: lr 1e-4 / clip 0.1, then fine-tuning at 1e-5 / 0.02
    "paper": dict(learning_rate=1e-4, clip_eps=0.1, finetune_learning_rate=1e-5,
                  finetune_clip_eps=0.02, finetune_fraction=0.3, anneal_lr=False),
    "matlab": {**MATLAB_LIKE, "learning_rate": 1e-4, "clip_eps": 0.1},
}
RUN_DOCS: dict[str, tuple[Any, str]] = {
    "task": ("basketball", f"task to train: one of {registered()}"),
    "out": ("", "run folder (default runs/<task>-<date>-<time>)"),
    "resume": (False, "continue the run in `out` from its last checkpoint"),
    "preset": ("none", f"override set applied before yours: {sorted(PRESETS)}"),
    "train_targets": ("", "training target distribution of a task with several (basketball: action, area "
                          "or mixed; empty: the task's own choice, basketball mixed); evaluation always "
                          "uses the task's default params"),
    "sim_dtype": ("", "simulator precision in training: float64 or float32 (float32: ~2.7x the throws/s of a "
                      "batch; issue 4); empty: float64, or the resumed run's. The final evaluation always "
                      "simulates in float64"),
    "checkpoint_every": (60.0, "seconds of training between checkpoints"),
    "eval_targets": (1000, "targets of the final evaluation (0 skips it)"),
    "eval_seed": (-1, "seed of the final evaluation's targets (-1: 1_000_003 + seed)"),
    "progress": (True, "show a tqdm progress bar"),
    "updates_per_call": (0, "PPO updates per jitted call (0: ~8k episodes per call); "
                            "checkpoints and the finiteness check happen between calls"),
}
# Config keys that fix the shapes or the meaning of a saved TrainState.
RESUME_FIXED = ("seed", "num_envs", "network", "shared_hidden", "actor_hidden", "critic_hidden",
                "activation", "std_mode")
# Allowed ranges of the numeric run options: (check, text).
_RUN_RANGES: dict[str, tuple[Any, str]] = {
    "checkpoint_every": (lambda v: v >= 0, "seconds >= 0 (0: after every call; inf: only at the end)"),
    "eval_targets": (lambda v: v >= 0, "an int >= 0"),
    "eval_seed": (lambda v: v >= -1, "an int >= -1"),
    "updates_per_call": (lambda v: v >= 0, "an int >= 0"),
    "sim_dtype": (lambda v: v in ("", "float64", "float32"), "float64, float32 or empty (float64)"),
}


class TrainingDiverged(RuntimeError):
    """A loss, an optimisation metric or the weights became NaN/inf."""


def _parse_run(key: str, text: str) -> Any:
    default = RUN_DOCS[key][0]
    try:
        if isinstance(default, bool):
            if text.lower() in ("1", "true", "yes", "on"):
                return True
            if text.lower() in ("0", "false", "no", "off"):
                return False
            raise ValueError
        value = type(default)(text)
    except ValueError:
        raise ValueError(f"{key}={text!r} is invalid; expected {type(default).__name__}") from None
    if key in _RUN_RANGES and not _RUN_RANGES[key][0](value):  # NaN fails every comparison
        raise ValueError(f"{key}={text!r} is invalid; expected {_RUN_RANGES[key][1]}")
    return value


def parse_args(argv: list[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``key=value`` words -> (run options, PPOConfig overrides). Errors list valid keys."""
    run = {k: v for k, (v, _) in RUN_DOCS.items()}
    ppo: dict[str, Any] = {}
    for item in argv:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep:
            raise ValueError(f"argument {item!r} is not of the form key=value (see --help)")
        if key in RUN_DOCS:
            run[key] = _parse_run(key, text)
        elif key in FIELD_DOCS:
            ppo[key] = parse_value(key, text)
        else:
            raise ValueError(f"unknown key {key!r}; valid keys: {sorted(RUN_DOCS) + sorted(FIELD_DOCS)}")
    if run["task"] not in registered():
        raise ValueError(f"task={run['task']!r} is unknown; choose one of {registered()}")
    if run["preset"] not in PRESETS:
        raise ValueError(f"preset={run['preset']!r} is unknown; choose one of {sorted(PRESETS)}")
    if "seed" in ppo and not (isinstance(ppo["seed"], int) and 0 <= ppo["seed"] < 2**63):
        # PPOConfig accepts any int >= 0, but jax.random.PRNGKey overflows at 2**63
        raise ValueError(f"seed={ppo['seed']!r} is invalid; expected an int in [0, 2**63)")
    if run["resume"] and not run["out"]:
        raise ValueError("resume=true needs out=<run folder> (the folder holding checkpoint.ckpt)")
    choices = getattr(make(run["task"]), "train_target_choices", ())
    if run["train_targets"] and run["train_targets"] not in choices:
        allowed = f"choose one of {list(choices)} or leave it empty" if choices else \
            "this task has a single target distribution: leave it empty"
        raise ValueError(f"train_targets={run['train_targets']!r} is invalid for task={run['task']!r}; {allowed}")
    return run, ppo


def training_params(env, targets: str = "", sim_dtype: str = "") -> Any:
    """The env params training uses: ``env.train_params(targets)`` if the task has it, simulating
    in ``sim_dtype`` (empty: float64)."""
    if hasattr(env, "train_params"):
        params = env.train_params(targets)
    elif targets:
        raise ValueError(f"train_targets={targets!r} is invalid for task={env.name!r}: it has a single "
                         "target distribution (leave train_targets empty)")
    else:
        params = env.default_params()
    if sim_dtype and sim_dtype != "float64":
        if not hasattr(params, "sim_dtype"):
            raise ValueError(f"sim_dtype={sim_dtype!r} is invalid for task={env.name!r}: it simulates in "
                             "float64 only (leave sim_dtype empty)")
        params = params.replace(sim_dtype=sim_dtype)
    return params


def task_defaults(task: str) -> dict[str, Any]:
    """``TASK_DEFAULTS[task]``, else the task module's ``PPO_DEFAULTS`` (if any)."""
    if task in TASK_DEFAULTS:
        return TASK_DEFAULTS[task]
    return dict(getattr(sys.modules[type(make(task)).__module__], "PPO_DEFAULTS", {}))


def build_config(task: str, preset: str, overrides: dict[str, Any]) -> PPOConfig:
    """Task defaults, then the preset, then the user's overrides (validated)."""
    return PPOConfig().replace(**{**task_defaults(task), **PRESETS[preset], **overrides})


def config_from_json(d: dict, source: str = "config") -> PPOConfig:
    """PPOConfig from a saved dict (``task`` and ``preset`` are ignored; other
    unknown keys and invalid values raise ValueError naming ``source``)."""
    if not isinstance(d, dict):
        raise ValueError(f"{source} is invalid: expected a JSON object of PPOConfig fields, "
                         f"got {type(d).__name__}")
    unknown = sorted(set(d) - set(FIELD_DOCS) - {"task", "preset", "train_targets", "sim_dtype"})
    if unknown:
        raise ValueError(f"{source} has unknown key(s) {unknown}; valid keys: {sorted(FIELD_DOCS)}")
    d = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items() if k in FIELD_DOCS}
    try:
        return PPOConfig(**d)
    except ValueError as e:
        raise ValueError(f"{source} is invalid: {e}") from None


_STEP_CACHE: dict[tuple, Any] = {}  # jitted update functions, reused within one process


def default_updates_per_call(config: PPOConfig, episode_length: int) -> int:
    """~8k env steps per jitted call: a responsive progress bar without Python overhead per update."""
    total = num_updates(config, episode_length)
    return max(1, min(total, 8192 // (config.num_envs * config.num_steps)))


def _update_fn(task: str, config: PPOConfig, env, env_params, per_call: int, targets: str = "",
               sim_dtype: str = ""):
    # The update never reads the seed (the PRNG key is in TrainState), so runs differing only
    # in seed share one program: a seed sweep in one process compiles once (soak: each new
    # program held ~100 MB of RSS).
    config = config.replace(seed=0)
    key = (task, config, per_call, targets, sim_dtype or "float64")
    if key not in _STEP_CACHE:
        _STEP_CACHE[key] = make_update(config, env, env_params, updates_per_call=per_call)
    return _STEP_CACHE[key]


def help_text() -> str:
    lines = [__doc__.strip(), "", "Run options:"]
    for key, (default, doc) in RUN_DOCS.items():
        lines.append(f"  {key}={default}".ljust(34) + f"  {doc}")
    for task in registered():
        lines += ["", f"PPO config (defaults for task={task}):", describe(build_config(task, "none", {}))]
    return "\n".join(lines)


class MetricsLog:
    """metrics.csv (append, columns fixed by the first row) and optional TensorBoard."""

    def __init__(self, out: Path, resume_update: int | None):
        self.path = out / "metrics.csv"
        self.columns: list[str] | None = None
        if resume_update is not None and self.path.exists():
            with open(self.path, newline="") as f:  # drop rows past the checkpoint
                text = f.read()
            if not text.endswith("\n"):  # a row cut short by a kill is dropped whole
                text = text[: text.rfind("\n") + 1]
            rows = list(csv.DictReader(text.splitlines()))
            if rows:
                self.columns = list(rows[0].keys())
                rows = [r for r in rows if None not in r.values() and _int(r["update"]) < resume_update]
                with open(self.path, "w", newline="") as f:
                    w = csv.DictWriter(f, self.columns)
                    w.writeheader()
                    w.writerows(rows)
        elif self.path.exists():
            self.path.unlink()
        self.tb = _tensorboard(out)

    def write(self, rows: list[dict[str, float]]) -> None:
        if not rows:
            return
        if self.columns is None:
            self.columns = list(rows[0].keys())
            with open(self.path, "w", newline="") as f:
                csv.DictWriter(f, self.columns).writeheader()
        with open(self.path, "a", newline="") as f:
            w = csv.DictWriter(f, self.columns, extrasaction="ignore")
            w.writerows(rows)
        if self.tb is not None:
            for r in rows:
                for k, v in r.items():
                    if k not in ("update", "episodes") and math.isfinite(v):
                        self.tb.add_scalar(k, v, int(r["episodes"]))
            self.tb.flush()


def _int(text: str) -> float:
    """An int from a CSV cell; inf (dropped) when garbled."""
    try:
        return int(text)
    except (TypeError, ValueError):
        return math.inf


def _tensorboard(out: Path):
    import importlib.util

    for module, needs in (("tensorboardX", ("tensorboardX",)),
                          ("torch.utils.tensorboard", ("torch", "tensorboard"))):
        # look before importing: importing torch only to fail on a missing tensorboard
        # took seconds and ~0.3 GB of RSS per process (soak, issue 6)
        if any(importlib.util.find_spec(m) is None for m in needs):
            continue
        try:
            mod = __import__(module, fromlist=["SummaryWriter"])
            return mod.SummaryWriter(str(out / "tb"))
        except Exception:  # not installed (or broken): CSV only
            continue
    return None


def _rows(metrics: dict, wall: float) -> list[dict[str, float]]:
    m = {k: np.asarray(v) for k, v in jax.device_get(metrics).items()}
    rows = []
    for i in range(len(m["update"])):
        if int(m["update"][i]) < 0:  # skipped past the budget
            continue
        row = {"update": int(m["update"][i]), "episodes": int(m["episodes"][i]), "wall_s": wall}
        row.update({k: float(v[i]) for k, v in m.items() if k not in ("update", "episodes")})
        rows.append(row)
    return rows


def non_finite(rows: list[dict[str, float]], state) -> str | None:
    """What became NaN/inf in a call's metric rows or the new weights/optimizer state, else None.

    Checked: every loss/optimisation metric, and ``episode_reward`` when an
    episode completed. Not checked: the other ``episode_<info>`` means (NaN
    whenever no episode ended in the rollout; diagnostics, not learned from).
    """
    for r in rows:
        for k, v in r.items():
            if k.startswith("episode_") and (k != "episode_reward" or r.get("episodes_completed", 0) == 0):
                continue
            if not math.isfinite(v):
                return f"metric {k}={v} at update {int(r['update'])}"
    for name in ("params", "opt_state"):
        leaves = jax.tree_util.tree_leaves_with_path(getattr(state, name))
        for where, x in leaves:
            x = np.asarray(x)
            if np.issubdtype(x.dtype, np.floating) and not np.all(np.isfinite(x)):
                return f"{name}{jax.tree_util.keystr(where)} became non-finite by update {int(state.update) - 1}"
    return None


def train(run: dict[str, Any], overrides: dict[str, Any]) -> Path:
    """Run (or resume) training; returns the run folder."""
    task = run["task"]
    out = Path(run["out"] or f"runs/{task}-{time.strftime('%Y%m%d-%H%M%S')}")
    ckpt_path = out / "checkpoint.ckpt"
    env = make(task)
    if run["resume"]:
        if not run["out"]:
            raise ValueError("resume=true needs out=<run folder>")
        meta = checkpoint.load_raw(ckpt_path)
        if meta["task"] != task:
            raise ValueError(f"resume: {ckpt_path} is a task={meta['task']!r} run; pass task={meta['task']}")
        checkpoint.remove_stale_temps(ckpt_path)  # left by a write the kill interrupted
        saved = config_from_json(meta["config"], f"the config saved in {ckpt_path}")
        for key in RESUME_FIXED:
            if key in overrides and overrides[key] != getattr(saved, key):
                raise ValueError(f"resume: {key}={overrides[key]!r} differs from the checkpoint's "
                                 f"{getattr(saved, key)!r}; it cannot change on resume "
                                 "(it fixes the saved state); start a new run instead")
        config = saved.replace(**overrides)
        saved_targets = meta["config"].get("train_targets", "")
        if run["train_targets"] and run["train_targets"] != saved_targets:
            raise ValueError(f"resume: train_targets={run['train_targets']!r} differs from the checkpoint's "
                             f"{saved_targets!r}; start a new run instead")
        run = {**run, "train_targets": saved_targets}
        saved_dtype = meta["config"].get("sim_dtype", "") or "float64"
        if run["sim_dtype"] and run["sim_dtype"] != saved_dtype:
            raise ValueError(f"resume: sim_dtype={run['sim_dtype']!r} differs from the checkpoint's "
                             f"{saved_dtype!r}; start a new run instead")
        run = {**run, "sim_dtype": saved_dtype}
    else:
        config = build_config(task, run["preset"], overrides)
        run = {**run, "sim_dtype": run["sim_dtype"] or "float64"}
    out.mkdir(parents=True, exist_ok=True)
    (out / "config.json").write_text(json.dumps(
        {"task": task, "preset": run["preset"], "train_targets": run["train_targets"],
         "sim_dtype": run["sim_dtype"], **dataclasses.asdict(config)}, indent=2))

    t0 = time.perf_counter()
    env_params = training_params(env, run["train_targets"], run["sim_dtype"])
    state = init(config, env, env_params, jax.random.PRNGKey(config.seed))
    if run["resume"]:
        state = checkpoint.restore_state(state, meta["train_state"])
    total = num_updates(config, env.episode_length)
    per_call = run.get("updates_per_call") or default_updates_per_call(config, env.episode_length)
    step_fn = _update_fn(task, config, env, env_params, per_call, run["train_targets"], run["sim_dtype"])
    log = MetricsLog(out, int(state.update) if run["resume"] else None)
    setup_s = time.perf_counter() - t0

    bar = None
    if run["progress"]:
        from tqdm import tqdm
        bar = tqdm(total=config.total_episodes, initial=min(int(state.episodes), config.total_episodes),
                   unit="ep", desc=f"train {task}", dynamic_ncols=True)
    config_dict = {"task": task, "train_targets": run["train_targets"], "sim_dtype": run["sim_dtype"],
                   **dataclasses.asdict(config)}
    last_save, compile_s, t_train = time.perf_counter(), None, time.perf_counter()
    saved_update = int(state.update) if run["resume"] else None
    while int(state.update) < total:
        t_call = time.perf_counter()
        good = state  # finite (checked below, or fresh/restored); kept in case this call diverges
        state, metrics = step_fn(state)
        jax.block_until_ready(state)
        if compile_s is None:
            compile_s = time.perf_counter() - t_call  # first call: compile + run
        rows = _rows(metrics, time.perf_counter() - t0)
        log.write(rows)
        problem = non_finite(rows, state)
        if problem is not None:
            if bar is not None:
                bar.close()
            if saved_update != int(good.update):
                checkpoint.save(ckpt_path, good, config_dict, task, int(good.update))
            raise TrainingDiverged(
                f"training stopped: {problem}. Nothing non-finite was saved: {ckpt_path} holds the "
                f"last good state (update {int(good.update)} of {total}); metrics.csv has the rows up "
                f"to the failure. Resume from it with a smaller learning_rate or max_grad_norm: "
                f"python -m gvsjax.train task={task} out={out} resume=true learning_rate=...")
        if bar is not None and rows:
            bar.n = min(rows[-1]["episodes"], config.total_episodes)
            bar.set_postfix(reward=f"{np.nanmean([r['episode_reward'] for r in rows]):.3f}",
                            cost_cm=f"{100 * np.nanmean([r.get('episode_cost', np.nan) for r in rows]):.1f}")
            bar.refresh()
        if time.perf_counter() - last_save >= run["checkpoint_every"]:
            checkpoint.save(ckpt_path, state, config_dict, task, int(state.update))
            last_save, saved_update = time.perf_counter(), int(state.update)
    if saved_update != int(state.update):
        checkpoint.save(ckpt_path, state, config_dict, task, int(state.update))
    if bar is not None:
        bar.close()
    train_s = time.perf_counter() - t_train
    timing = {"setup_s": setup_s, "first_call_s": compile_s, "train_s": train_s,
              "episodes": int(state.episodes), "updates": int(state.update)}
    (out / "timing.json").write_text(json.dumps(timing, indent=2))
    print(f"trained {timing['episodes']} episodes in {train_s:.1f} s "
          f"(setup {setup_s:.1f} s, first call incl. compile {compile_s or 0:.1f} s)")

    if run["eval_targets"] > 0:
        from gvsjax import evaluate
        seed = run["eval_seed"] if run["eval_seed"] >= 0 else 1_000_003 + config.seed
        result = evaluate.evaluate_run(ckpt_path, out, n_targets=run["eval_targets"], seed=seed)
        print(evaluate.summary(result))
    written = sorted(p.name for p in out.iterdir() if p.is_file())
    print(f"outputs in {out}/: {', '.join(written)}")
    figures = [n for n in written if n.endswith(".png")]
    print(f"open {', '.join(f'{out}/{n}' for n in figures) or out}; "
          f"re-evaluate with: python -m gvsjax.evaluate task={task} checkpoint={ckpt_path}")
    return out


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if any(a in ("-h", "--help", "help") for a in argv):
        print(help_text())
        return 0
    try:
        run, overrides = parse_args(argv)
        train(run, overrides)
    except (ValueError, checkpoint.CheckpointError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except TrainingDiverged as e:
        print(f"error: {e}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
