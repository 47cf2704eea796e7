"""Soak test (not part of the default suite): many throws and many trainings in one process.

    python experiments/benchmarks/soak.py            # 100,000 throws + 20 trainings
    python experiments/benchmarks/soak.py --quick    # 20,000 throws + 5 trainings

Phase 1 throws random actions at random targets through the basketball env
(jitted, vmapped ``reset`` + ``step``) in fixed-size batches. Phase 2 runs
consecutive short trainings through ``gvsjax.train.train`` (the CLI's code
path: new run folder, checkpoints, final evaluation with figures), each with
its own seed, like a seed sweep in one process.

Checked (exit code 1 if any fails):
* no NaN: every throw valid with a finite cost; every training's metrics and
  evaluation finite (a non-finite loss would also stop ``train`` itself);
* no recompilation after the warm-up (the first max(2, n/5) batches / trainings):
  XLA compilations are counted with a ``jax.monitoring`` listener;
* memory flat: the trend of the resident set size (VmRSS) after the warm-up
  (least-squares slope x iterations) is at most ``--rss-tolerance-mb``
  (default 64 MB) per phase: a compiled update program leaked per training
  (e.g. one per seed) is ~100 MB, well above it.

Writes a JSON summary (``--out``, default ``soak.json`` in the working folder).
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax import train
from gvsjax.tasks import make

COMPILES = [0]


def _count(event: str, duration: float, **kwargs) -> None:
    if event == "/jax/core/compile/backend_compile_duration":
        COMPILES[0] += 1


jax.monitoring.register_event_duration_secs_listener(_count)


def rss_mb() -> float:
    """Resident set size of this process (MB), from /proc (Linux); ru_maxrss elsewhere.

    Collects cyclic garbage first: matplotlib figures are reference cycles that Python
    frees only at its next cyclic collection, so without it each training's plots
    show as a few MB of "growth" that plateaus. A real leak survives the collection.
    """
    gc.collect()
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # peak, KB on Linux


def live_arrays_mb() -> float:
    """Bytes held by live JAX arrays (MB): a device-buffer leak shows here, allocator noise does not."""
    return sum(a.nbytes for a in jax.live_arrays()) / 2**20


def throws(n_throws: int, batch: int, seed: int = 0) -> dict:
    env = make("basketball")
    params = env.default_params()

    @jax.jit
    def run(key):
        k_reset, k_act, k_step = jax.random.split(key, 3)
        obs, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(k_reset, batch), params)
        action = jax.random.uniform(k_act, (batch, env.action_size), minval=-1.0, maxval=1.0)
        _, _, reward, _, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
            jax.random.split(k_step, batch), state, action, params)
        return jnp.sum(~info["valid"]), jnp.sum(~jnp.isfinite(info["cost"])), jnp.sum(~jnp.isfinite(reward))

    n_batches = math.ceil(n_throws / batch)
    rss, compiles, live, bad = [], [], [], np.zeros(3, int)
    t0 = time.perf_counter()
    for i, key in enumerate(jax.random.split(jax.random.PRNGKey(seed), n_batches)):
        bad += np.asarray(jax.device_get(run(key)), int)
        rss.append(rss_mb())
        compiles.append(COMPILES[0])
        live.append(live_arrays_mb())
        if i == 0:
            t_first = time.perf_counter() - t0
    wall = time.perf_counter() - t0
    return {"throws": n_batches * batch, "batch": batch, "invalid": int(bad[0]), "nonfinite_cost": int(bad[1]),
            "nonfinite_reward": int(bad[2]), "first_batch_s": t_first,
            "throws_per_s_after_first": (n_batches - 1) * batch / max(wall - t_first, 1e-9),
            "rss_mb": rss, "compiles_cumulative": compiles, "live_arrays_mb": live}


def trainings(n_runs: int, folder: Path) -> dict:
    rss, compiles, walls, finals, live = [], [], [], [], []
    for i in range(n_runs):
        t0 = time.perf_counter()
        run, overrides = train.parse_args([
            "task=basketball", "num_envs=64", "num_minibatches=4", "update_epochs=2",
            "total_episodes=1024", f"seed={i}", "progress=false", "checkpoint_every=0",
            "eval_targets=64", f"out={folder / f'run{i}'}"])
        out = train.train(run, overrides)
        result = json.loads((out / "eval.json").read_text())
        with open(out / "metrics.csv") as f:
            rows = [line.split(",") for line in f.read().splitlines()[1:]]
        finals.append({"eval_median_m": result["median_m"], "rows": len(rows),
                       "nan_cells": sum(c.strip().lower() in ("nan", "inf", "-inf") for r in rows for c in r)})
        walls.append(time.perf_counter() - t0)
        rss.append(rss_mb())
        compiles.append(COMPILES[0])
        live.append(live_arrays_mb())
    return {"runs": n_runs, "wall_s": walls, "rss_mb": rss, "compiles_cumulative": compiles, "finals": finals,
            "live_arrays_mb": live}


def verdict(phase: dict, tolerance_mb: float) -> dict:
    """RSS trend and compilations after the warm-up (the first max(2, n/5) iterations).

    Flat: the least-squares slope of RSS over the later iterations, times their
    number (the trend accumulated over the phase), is at most ``tolerance_mb``;
    allocator noise (a batch's buffers come and go) does not trend.
    """
    rss, comp = np.asarray(phase["rss_mb"]), phase["compiles_cumulative"]
    w = min(max(2, len(rss) // 5), len(rss) - 1)
    later = rss[w - 1:]
    slope = float(np.polyfit(np.arange(len(later)), later, 1)[0]) if len(later) >= 2 else 0.0
    trend = slope * (len(later) - 1)
    return {"warmup_iterations": w, "rss_after_warmup_mb": float(rss[w - 1]), "rss_end_mb": float(rss[-1]),
            "rss_max_growth_mb": float(later.max() - later[0]), "rss_slope_mb_per_iter": slope,
            "rss_trend_mb": trend, "live_arrays_mb_after_warmup": phase["live_arrays_mb"][w - 1],
            "live_arrays_mb_end": phase["live_arrays_mb"][-1], "compiles_warmup": comp[w - 1],
            "compiles_after_warmup": comp[-1] - comp[w - 1],
            "flat": trend <= tolerance_mb, "no_recompile": comp[-1] == comp[w - 1]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="20,000 throws and 5 trainings")
    ap.add_argument("--throws", type=int, default=None, help="throws in phase 1 (default 100,000)")
    ap.add_argument("--batch", type=int, default=4000, help="throws per jitted batch")
    ap.add_argument("--trainings", type=int, default=None, help="trainings in phase 2 (default 20)")
    ap.add_argument("--rss-tolerance-mb", type=float, default=64.0)
    ap.add_argument("--out", default="soak.json")
    args = ap.parse_args(argv)
    n_throws = args.throws or (20_000 if args.quick else 100_000)
    n_runs = args.trainings or (5 if args.quick else 20)

    t0 = time.perf_counter()
    print(f"start: RSS {rss_mb():.0f} MB, {COMPILES[0]} compilations")
    phase1 = throws(n_throws, args.batch)
    v1 = verdict(phase1, args.rss_tolerance_mb)
    print(f"throws: {phase1['throws']} in batches of {phase1['batch']}, invalid {phase1['invalid']}, "
          f"non-finite cost {phase1['nonfinite_cost']}; {phase1['throws_per_s_after_first']:.0f} throws/s; "
          f"RSS {v1['rss_after_warmup_mb']:.0f} -> {v1['rss_end_mb']:.0f} MB after {v1['warmup_iterations']} "
          f"warm-up batches (trend {v1['rss_trend_mb']:+.1f} MB, max growth {v1['rss_max_growth_mb']:.1f}; live JAX "
          f"arrays {v1['live_arrays_mb_after_warmup']:.1f} -> {v1['live_arrays_mb_end']:.1f} MB); "
          f"compilations {v1['compiles_warmup']} in the warm-up, then +{v1['compiles_after_warmup']}")
    with tempfile.TemporaryDirectory() as tmp:
        phase2 = trainings(n_runs, Path(tmp))
    v2 = verdict(phase2, args.rss_tolerance_mb)
    nan_cells = sum(f["nan_cells"] for f in phase2["finals"])
    medians = [f["eval_median_m"] for f in phase2["finals"]]
    print(f"trainings: {n_runs} x 16 updates + eval, {np.mean(phase2['wall_s'][1:] or [0]):.1f} s each after "
          f"the first ({phase2['wall_s'][0]:.1f} s); RSS {v2['rss_after_warmup_mb']:.0f} -> "
          f"{v2['rss_end_mb']:.0f} MB after {v2['warmup_iterations']} warm-up runs (trend "
          f"{v2['rss_trend_mb']:+.1f} MB, max growth {v2['rss_max_growth_mb']:.1f}; live JAX arrays "
          f"{v2['live_arrays_mb_after_warmup']:.1f} -> {v2['live_arrays_mb_end']:.1f} MB); compilations "
          f"+{v2['compiles_after_warmup']} after the warm-up; NaN/inf cells in metrics {nan_cells}")
    checks = {
        "throws_valid_and_finite": phase1["invalid"] == phase1["nonfinite_cost"] == phase1["nonfinite_reward"] == 0,
        "throws_memory_flat": v1["flat"], "throws_no_recompile": v1["no_recompile"],
        "trainings_finite": nan_cells == 0 and all(math.isfinite(m) for m in medians),
        "trainings_memory_flat": v2["flat"], "trainings_no_recompile": v2["no_recompile"],
    }
    summary = {"args": vars(args), "wall_s": time.perf_counter() - t0, "checks": checks,
               "throws": {**phase1, **v1}, "trainings": {**phase2, **v2}}
    Path(args.out).write_text(json.dumps(summary, indent=1))
    print(f"checks (RSS tolerance {args.rss_tolerance_mb:.0f} MB): "
          + ", ".join(f"{k} {'ok' if v else 'FAILED'}" for k, v in checks.items()))
    print(f"total {summary['wall_s']:.0f} s; summary in {args.out}")
    return 0 if all(checks.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
