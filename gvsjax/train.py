"""Train an agent on a gvsjax task from the command line: PPO (``gvsjax.ppo``) or, with
``algo=sac``, SAC (``gvsjax.sac``).

    python -m gvsjax.train task=basketball [key=value ...]
    python -m gvsjax.train task=follow_target algo=sac [key=value ...]
    python -m gvsjax.train --help

Every field of the algorithm's config (``PPOConfig``, ``SACConfig``) is a ``key=value``
override (``--help`` lists them with each task's defaults); the run options are listed in
``RUN_DOCS``. The run folder ``out`` receives ``config.json``, ``metrics.csv`` (one row per PPO
update or SAC iteration, its ``train_*`` columns the discounted returns and failed fraction of
the last 500 finished training episodes, ``gvsjax.utils.episode_returns``; also TensorBoard
events when ``tensorboardX`` or ``torch`` is installed), ``checkpoint.ckpt``
(``gvsjax.ppo.checkpoint``) and, at the end,
the evaluation of ``gvsjax.evaluate`` (eval.json, the per-episode table and
the task's figures). ``resume=true out=DIR`` continues the run in DIR from its
last checkpoint (optimizer state, PRNG key and update counter included);
command-line overrides then apply on top of the saved config (e.g. a larger
``total_episodes``); the keys that fix the saved state's shapes or meaning
(``RESUME_FIXED``) cannot change.

Several processes (hosts): start the same command once per process with
``coordinator=HOST:PORT num_processes=N process_id=I`` (I = 0..N-1) and the
same ``out``; the env batch is split over all processes' devices, process 0
writes the run folder (the checkpoint gathered from all), and a resume reads
the checkpoint on every process (docs/scale_out.md).

Reliability: after every jitted call the losses, the other optimisation metrics
and the network weights must be finite; otherwise training stops (exit code 3)
with a message naming the metric and the update, after saving the last good
state as the checkpoint, so nothing non-finite is ever saved. A resumed run
continues bit-identically to an uninterrupted one (same metrics.csv apart from
``wall_s``): the whole ``TrainState`` is checkpointed, and rows of
``metrics.csv`` past the checkpoint are dropped.
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import json
import sys
import time
from pathlib import Path
from typing import Any

import jax
import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax import sac
from gvsjax.ppo import (
    FIELD_DOCS,
    PRESETS,
    PPOConfig,
    build_config,
    config_from_json,
    describe,
    init,
    make_update,
    num_updates,
    place,
)
from gvsjax.ppo import checkpoint as ckpt
from gvsjax.ppo.config import field_parsers
from gvsjax.sac import config as sac_config
from gvsjax.tasks import DEFAULT_TASK, Environment, make, randomized, registered
from gvsjax.utils import distributed, keyvalue, sharding
from gvsjax.utils.runlog import MetricsLog, non_finite, rows_of

RUN_DOCS: dict[str, tuple[Any, str]] = {
    "task": (DEFAULT_TASK, "task to train (one of the registered tasks, see below)"),
    "algo": ("", "learning algorithm: ppo, or sac (off-policy, with a replay buffer; the algorithm of the "
                 "soft-arm benchmark's published results); empty: ppo, or the resumed run's"),
    "out": ("", "run folder (default runs/<task>-<date>-<time>)"),
    "resume": (False, "continue the run in `out` from its last checkpoint"),
    "preset": ("none", f"override set applied before yours: {sorted(PRESETS)}"),
    "train_targets": ("", "training distribution of a task with several (its train_variants, listed "
                          "below); empty: the task's own choice. Evaluation uses the task's default params"),
    "randomize": ("", "domain randomisation: NAME:r,... draws each named physical parameter per episode "
                      "uniformly in nominal x [1-r, 1+r], 0 < r < 1 (names: the task's, listed below); "
                      "empty: none. Evaluation uses the nominal model"),
    "randomize_observe": (False, "append the episode's factors, as (factor - 1) / r, to the observation"),
    "sim_dtype": ("", "simulator precision in training: float64 or float32 (float32: ~1.8x the throws/s "
                      "of a batch); empty: the task's (listed below), or the resumed run's. Evaluation "
                      "simulates in float64"),
    "checkpoint_every": (60.0, "seconds of training between checkpoints"),
    "eval_targets": (1000, "episodes of the final evaluation (0 skips it)"),
    "eval_seed": (-1, "seed of the final evaluation (-1: 1_000_003 + seed)"),
    "progress": (True, "show a tqdm progress bar"),
    "updates_per_call": (0, "PPO updates per jitted call (0: ~8k episodes per call); "
                            "checkpoints and the finiteness check happen between calls"),
    "compile_cache": ("", "a folder for JAX's persistent compilation cache: a later run of the same program "
                          "loads its compiled code instead of compiling it; empty: off. Keep it private "
                          "to you and to this machine (its entries are native code)"),
    "coordinator": ("", "HOST:PORT of process 0 in a run over several processes (hosts); empty: one process"),
    "num_processes": (1, "processes of the run, each started with the same arguments but its own "
                         "process_id; num_envs must be a multiple of their total device count"),
    "process_id": (0, "this process's index in [0, num_processes); process 0 writes the run folder"),
}
# Config keys that fix the shapes or the meaning of a saved TrainState.
RESUME_FIXED = ("seed", "num_envs", "network", "shared_hidden", "actor_hidden", "critic_hidden",
                "activation", "std_mode")
SAC_RESUME_FIXED = ("seed", "num_envs", "hidden", "layer_norm", "buffer_size")
ALGOS = ("ppo", "sac")
_RUN_RANGES: dict[str, tuple[Any, str]] = {
    "checkpoint_every": (lambda v: v >= 0, "seconds >= 0 (0: after every call; inf: only at the end)"),
    "eval_targets": (lambda v: v >= 0, "an int >= 0"),
    "eval_seed": (lambda v: v >= -1, "an int >= -1"),
    "updates_per_call": (lambda v: v >= 0, "an int >= 0"),
    "sim_dtype": (lambda v: v in ("", "float64", "float32"), "float64, float32 or empty (the task's)"),
    "algo": (lambda v: v in ("", *ALGOS), "ppo, sac or empty (ppo, or the resumed run's)"),
    "num_processes": (lambda v: v >= 1, "an int >= 1"),
    "process_id": (lambda v: v >= 0, "an int >= 0 (and < num_processes)"),
}


class TrainingDiverged(RuntimeError):
    """A loss, an optimisation metric or the weights became NaN/inf."""


def _run_parser(key: str):
    base = keyvalue.typed(RUN_DOCS[key][0])

    def parse(text: str):
        value = base(text)
        if key in _RUN_RANGES and not _RUN_RANGES[key][0](value):  # NaN fails every comparison
            raise ValueError(f"{key}={text!r} is invalid; expected {_RUN_RANGES[key][1]}")
        return value

    parse.__name__ = type(RUN_DOCS[key][0]).__name__
    return parse


def parse_args(argv: list[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``key=value`` words -> (run options, the algorithm's config overrides). Errors list valid keys."""
    options = {**{k: _run_parser(k) for k in RUN_DOCS}, **sac_config.field_parsers(), **field_parsers()}
    given = keyvalue.parse(argv, options)
    run = {k: given.get(k, default) for k, (default, _) in RUN_DOCS.items()}
    if run["resume"] and run["out"] and not run["algo"]:
        run["algo"] = _saved_algo(run["out"])
    fields = sac.FIELD_DOCS if run["algo"] == "sac" else FIELD_DOCS
    foreign = sorted(set(given) - set(RUN_DOCS) - set(fields))
    if foreign:
        other = "ppo" if run["algo"] == "sac" else "sac"
        raise ValueError(f"{foreign} {'is' if len(foreign) == 1 else 'are'} {other} keys, not keys of "
                         f"algo={run['algo'] or 'ppo'}; its keys: {sorted(fields)}")
    ppo = {k: v for k, v in given.items() if k in fields}
    if run["algo"] == "sac" and run["preset"] != "none":
        raise ValueError(f"preset={run['preset']!r} is invalid with algo=sac; presets are PPO override sets")
    if run["algo"] == "sac" and run["num_processes"] > 1:
        raise ValueError(f"num_processes={run['num_processes']} is invalid with algo=sac; SAC runs in one process")
    if run["task"] not in registered():
        raise ValueError(f"task={run['task']!r} is unknown; choose one of {registered()}")
    if run["preset"] not in PRESETS:
        raise ValueError(f"preset={run['preset']!r} is unknown; choose one of {sorted(PRESETS)}")
    if run["resume"] and not run["out"]:
        raise ValueError("resume=true needs out=<run folder> (the folder holding checkpoint.ckpt)")
    distributed.check_args(run["coordinator"], run["num_processes"], run["process_id"])
    if run["num_processes"] > 1 and not run["out"]:
        raise ValueError(f"num_processes={run['num_processes']} needs out=<run folder>, the same on every process")
    env = make(run["task"])
    if run["train_targets"] and run["train_targets"] not in env.train_variants:
        Environment.train_params(env, run["train_targets"])  # raises, naming the choices
    randomized.wrap(env, run["randomize"], run["randomize_observe"])  # raises on a bad randomize=
    return run, ppo


def training_params(env: Environment, targets: str = "", sim_dtype: str = "") -> Any:
    """The env params training uses: the task's ``train_params(targets)`` in ``sim_dtype``
    (empty: the task's ``train_sim_dtype``)."""
    return env.with_sim_dtype(env.train_params(targets), sim_dtype or env.train_sim_dtype)


def task_defaults(task: str, algo: str = "ppo") -> dict[str, Any]:
    """The task's overrides of the algorithm's config (``Environment.ppo_defaults``, ``sac_defaults``)."""
    env = make(task)
    return dict(env.sac_defaults if algo == "sac" else env.ppo_defaults)


def _algo(algo: str):
    """``(init, num_updates)`` of ``algo``."""
    return (sac.init, sac.num_updates) if algo == "sac" else (init, num_updates)


def _saved_algo(out: str) -> str:
    """The algorithm of the run in folder ``out`` (its config.json), "" when there is none."""
    try:
        return str(json.loads((Path(out) / "config.json").read_text()).get("algo", "ppo"))
    except (OSError, ValueError, AttributeError):
        return ""


_STEP_CACHE: dict[tuple, Any] = {}  # jitted update functions, reused within one process


def default_updates_per_call(config: PPOConfig | sac.SACConfig, episode_length: int) -> int:
    """~8k env steps per jitted call: a responsive progress bar without Python overhead per update."""
    if isinstance(config, sac.SACConfig):
        return max(1, min(sac.num_updates(config, episode_length), 8192 // config.num_envs))
    total = num_updates(config, episode_length)
    return max(1, min(total, 8192 // (config.num_envs * config.num_steps)))


def update_fn(task: str, config: PPOConfig | sac.SACConfig, env, env_params, per_call: int, targets: str = "",
              sim_dtype: str = ""):
    """The jitted update, cached per program: runs differing only in seed share one (the
    seed lives in the TrainState's key), so a seed sweep in one process compiles once."""
    config = config.replace(seed=0)
    randomization = (env.ranges, env.observe) if isinstance(env, randomized.Randomized) else ()
    key = (task, config, per_call, targets, sim_dtype or env.train_sim_dtype, randomization)
    if key not in _STEP_CACHE:
        if isinstance(config, sac.SACConfig):
            _STEP_CACHE[key] = sac.make_update(config, env, env_params, updates_per_call=per_call)
        else:
            _STEP_CACHE[key] = make_update(config, env, env_params, updates_per_call=per_call)
    return _STEP_CACHE[key]


def help_text() -> str:
    lines = [__doc__.strip(), "", "Run options:"]
    for key, (default, doc) in RUN_DOCS.items():
        lines.append(f"  {key}={default}".ljust(34) + f"  {doc}")
    for task in registered():
        env = make(task)
        variants = env.train_variants
        lines.append(f"  task={task}" + (f": train_targets in {list(variants)}; " if variants else ": ")
                     + f"randomize names {sorted(env.randomizable)}; sim_dtype {env.train_sim_dtype}")
    for task in registered():
        config = build_config(task_defaults(task), "none", {})
        lines += ["", f"PPO config (defaults for task={task}):", describe(config)]
    for task in registered():
        if task_defaults(task, "sac"):
            sac_defaults = sac.build_config(task_defaults(task, "sac"), {})
            lines += ["", f"SAC config, algo=sac (defaults for task={task}):", sac.describe(sac_defaults)]
    lines += ["", "SAC config, algo=sac (defaults of the other tasks):", sac.describe()]
    return "\n".join(lines)


def _resume_config(run: dict, overrides: dict, ckpt_path: Path) -> tuple[PPOConfig | sac.SACConfig, dict, dict]:
    meta = ckpt.load_raw(ckpt_path)
    task = run["task"]
    if meta["task"] != task:
        raise ValueError(f"resume: {ckpt_path} is a task={meta['task']!r} run; pass task={meta['task']}")
    if distributed.is_main():
        ckpt.remove_stale_temps(ckpt_path)  # left by a write the kill interrupted
    saved_algo = meta["config"].get("algo", "ppo")
    if run["algo"] and run["algo"] != saved_algo:
        raise ValueError(f"resume: algo={run['algo']!r} differs from the checkpoint's {saved_algo!r}; "
                         "start a new run instead")
    source = f"the config saved in {ckpt_path}"
    saved: Any = (sac.config_from_json(meta["config"], source, ckpt.RUN_KEYS) if saved_algo == "sac"
                  else config_from_json(meta["config"], source))
    for key in SAC_RESUME_FIXED if saved_algo == "sac" else RESUME_FIXED:
        if key in overrides and overrides[key] != getattr(saved, key):
            raise ValueError(f"resume: {key}={overrides[key]!r} differs from the checkpoint's "
                             f"{getattr(saved, key)!r}; it cannot change on resume "
                             "(it fixes the saved state); start a new run instead")
    saved_targets = meta["config"].get("train_targets", "")
    if run["train_targets"] and run["train_targets"] != saved_targets:
        raise ValueError(f"resume: train_targets={run['train_targets']!r} differs from the checkpoint's "
                         f"{saved_targets!r}; start a new run instead")
    saved_randomize = meta["config"].get("randomize", "")
    env = make(task)
    if run["randomize"] and randomized.parse(run["randomize"], env) != randomized.parse(saved_randomize, env):
        raise ValueError(f"resume: randomize={run['randomize']!r} differs from the checkpoint's "
                         f"{saved_randomize!r}; start a new run instead")
    saved_observe = bool(meta["config"].get("randomize_observe", False))
    if run["randomize_observe"] and not saved_observe:
        raise ValueError("resume: randomize_observe=true differs from the checkpoint's false (it fixes the "
                         "observation's width); start a new run instead")
    saved_dtype = meta["config"].get("sim_dtype", "") or "float64"
    if run["sim_dtype"] and run["sim_dtype"] != saved_dtype:
        raise ValueError(f"resume: sim_dtype={run['sim_dtype']!r} differs from the checkpoint's "
                         f"{saved_dtype!r}; start a new run instead")
    return saved.replace(**overrides), {**run, "train_targets": saved_targets, "sim_dtype": saved_dtype,
                                        "randomize": saved_randomize, "randomize_observe": saved_observe,
                                        "algo": saved_algo}, meta


def _process_envs(config: Any, state) -> str:
    """Which envs this process steps, e.g. ``process 1 of 2: envs 8:16 of 16``."""
    spans = sorted((s.index[0].start or 0, s.index[0].stop or config.num_envs)
                   for s in state.last_obs.addressable_shards)
    return (f"process {jax.process_index()} of {jax.process_count()}: envs "
            + ", ".join(f"{a}:{b}" for a, b in spans) + f" of {config.num_envs}")


def train(run: dict[str, Any], overrides: dict[str, Any]) -> Path:
    """Run (or resume) training; returns the run folder.

    With ``num_processes`` > 1 every process calls it (see the module's docstring).
    """
    distributed.initialize(run.get("coordinator", ""), run.get("num_processes", 1), run.get("process_id", 0))
    writer = distributed.is_main()  # the one process that writes files and prints the summary
    task = run["task"]
    out = Path(run["out"] or f"runs/{task}-{time.strftime('%Y%m%d-%H%M%S')}")
    ckpt_path = out / ckpt.FILE_NAME
    env = make(task)
    if run["resume"]:
        if not run["out"]:
            raise ValueError("resume=true needs out=<run folder>")
        config, run, meta = _resume_config(run, overrides, ckpt_path)
    else:
        algo = run.get("algo") or "ppo"
        config = (sac.build_config(task_defaults(task, "sac"), overrides) if algo == "sac"
                  else build_config(task_defaults(task), run["preset"], overrides))
        run = {**run, "sim_dtype": run["sim_dtype"] or env.train_sim_dtype, "algo": algo}
    start, iterations = _algo(run["algo"])
    # randomize= wraps the task (a no-op when empty); its canonical text is what the run records
    env = randomized.wrap(env, run.get("randomize", ""), run.get("randomize_observe", False))
    ranges, observe = (env.ranges, env.observe) if isinstance(env, randomized.Randomized) else ((), False)
    run = {**run, "randomize": randomized.text_of(ranges), "randomize_observe": observe}
    if jax.process_count() > 1 and config.num_envs % jax.device_count():
        raise ValueError(f"num_envs={config.num_envs} is invalid over {jax.process_count()} processes; "
                         f"expected a multiple of their {jax.device_count()} devices")
    if writer:
        out.mkdir(parents=True, exist_ok=True)
        (out / "config.json").write_text(json.dumps(
            {"task": task, "algo": run["algo"], "preset": run["preset"], "train_targets": run["train_targets"],
             "sim_dtype": run["sim_dtype"], "randomize": run["randomize"],
             "randomize_observe": run["randomize_observe"], **dataclasses.asdict(config)}, indent=2))

    t0 = time.perf_counter()
    env_params = training_params(env, run["train_targets"], run["sim_dtype"])
    with sharding.unsharded():  # the whole state on each process, then each keeps its part
        state = start(config, env, env_params, jax.random.PRNGKey(config.seed))
        if run["resume"]:
            state = ckpt.restore_state(state, meta["train_state"])
    if isinstance(config, PPOConfig):  # SAC runs on one device
        state = place(config, state)
    if jax.process_count() > 1:
        print(_process_envs(config, state), flush=True)
    total = iterations(config, env.episode_length)
    per_call = run.get("updates_per_call") or default_updates_per_call(config, env.episode_length)
    step_fn = update_fn(task, config, env, env_params, per_call, run["train_targets"], run["sim_dtype"])
    log = MetricsLog(out, int(state.update) if run["resume"] else None) if writer else None
    setup_s = time.perf_counter() - t0

    bar = None
    if run["progress"] and writer:
        from tqdm import tqdm
        bar = tqdm(total=config.total_episodes, initial=min(int(state.episodes), config.total_episodes),
                   unit="ep", desc=f"train {task}", dynamic_ncols=True)
    config_dict = {"task": task, "algo": run["algo"], "train_targets": run["train_targets"],
                   "sim_dtype": run["sim_dtype"],
                   "randomize": run["randomize"], "randomize_observe": run["randomize_observe"],
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
        rows = rows_of(metrics, time.perf_counter() - t0)
        if log is not None:
            log.write(rows)
        problem = non_finite(rows, state)
        if problem is not None:
            if bar is not None:
                bar.close()
            if saved_update != int(good.update):
                ckpt.save(ckpt_path, good, config_dict, task, int(good.update))
            raise TrainingDiverged(
                f"training stopped: {problem}. Nothing non-finite was saved: {ckpt_path} holds the "
                f"last good state (update {int(good.update)} of {total}); metrics.csv has the rows up "
                f"to the failure. Resume from it with a smaller learning_rate or max_grad_norm: "
                f"python -m gvsjax.train task={task} out={out} resume=true learning_rate=...")
        if bar is not None and rows:
            bar.n = min(rows[-1]["episodes"], config.total_episodes)
            finished = [r["episode_reward"] for r in rows if np.isfinite(r["episode_reward"])]
            if finished:  # long episodes: the first updates may end none
                last = rows[-1]  # the discounted returns of the last finished episodes, sampled actions
                bar.set_postfix(reward=f"{np.mean(finished):.3f}",
                                disc_avg=f"{last['train_discounted_return_average']:.1f}",
                                failed=f"{last['train_failed_fraction']:.1%}")
            bar.refresh()
        if distributed.agree(time.perf_counter() - last_save >= run["checkpoint_every"]):
            ckpt.save(ckpt_path, state, config_dict, task, int(state.update))
            last_save, saved_update = time.perf_counter(), int(state.update)
    if saved_update != int(state.update):
        ckpt.save(ckpt_path, state, config_dict, task, int(state.update))
    if bar is not None:
        bar.close()
    train_s = time.perf_counter() - t_train
    timing = {"setup_s": setup_s, "first_call_s": compile_s, "train_s": train_s,
              "episodes": int(state.episodes), "updates": int(state.update)}
    if not writer:
        print(f"process {jax.process_index()}: trained in {train_s:.1f} s; process 0 writes {out}")
        return out
    (out / "timing.json").write_text(json.dumps(timing, indent=2))
    print(f"trained {timing['episodes']} episodes in {train_s:.1f} s "
          f"(setup {setup_s:.1f} s, first call incl. compile {compile_s or 0:.1f} s)")

    if run["eval_targets"] > 0:
        from gvsjax import evaluate
        seed = run["eval_seed"] if run["eval_seed"] >= 0 else 1_000_003 + config.seed
        # process 0 alone, on its own devices: the others do not join its computations
        with sharding.unsharded() if jax.process_count() > 1 else contextlib.nullcontext():
            result = evaluate.evaluate_run(ckpt_path, out, n_episodes=run["eval_targets"], seed=seed)
        print(f"{env.summary(result)} ({result['what']})")
        if "training" in result:
            t = result["training"]
            print(f"training, {t['what']}: discounted return {t['discounted_return_average']:.4g} averaged over "
                  f"start steps, {t['discounted_return_start']:.4g} from the first; failed {t['failed_fraction']:.1%}")
    written = sorted(p.name for p in out.iterdir() if p.is_file())
    print(f"outputs in {out}/: {', '.join(written)}")
    figures = [n for n in written if n.endswith(".png")]
    print(f"open {', '.join(f'{out}/{n}' for n in figures) or out}; "
          f"re-evaluate with: python -m gvsjax.evaluate checkpoint={out}")
    return out


def use_compile_cache(folder: str) -> None:
    """Store and reuse compiled programs in ``folder`` (JAX's persistent cache). Call it before
    anything compiles: JAX reads the setting once."""
    path = Path(folder).expanduser()
    path.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if any(a in ("-h", "--help", "help") for a in argv):
        print(help_text())
        return 0
    try:
        run, overrides = parse_args(argv)
        if run["compile_cache"]:
            use_compile_cache(run["compile_cache"])
        train(run, overrides)
    except (ValueError, ckpt.CheckpointError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except TrainingDiverged as e:
        print(f"error: {e}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    # a run traces programs of ~10^5 long-lived objects; Python's full collections would rescan
    # every imported module's objects each time (~20% of the trace time)
    gc.freeze()
    sys.exit(main())
