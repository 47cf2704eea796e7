"""Throws per second of the paper's basketball swing, batched.

Each throw: theta(t) = theta_F (t/T)^2, theta_F = 210 deg, a 5.886 N tip force,
T ~ U[0.5, 3] s, simulated to release t = delta T, delta ~ U[0.85, 1], with a
fixed number of steps per throw (dt = t_rel / n_steps, so every episode of a
batch has the same length). Three configurations, measured in the same run:
the basketball task's default (40 ``ars443`` steps), the same in float32
(``simulate(dtype=jnp.float32)``), and its peer, 300 RK4
steps (the fewest round number RK4 is stable with for a 3 s throw). The accuracy column is the worst release tip
position error over 256 throws against converged RK4 (3000 steps).

    python experiments/benchmarks/bench_sim.py [--repeats 5] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import time

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation

THETA_F = np.deg2rad(210.0)


def make_throws(n_steps: int, integrator: str = "rk4", dtype=jnp.float64):
    """Batched throws (T, delta) -> (release tip, tip velocity), in float64 whatever ``dtype`` runs."""
    arm = gv.paper_arm(tip_force=5.886)
    theta_f = float(THETA_F)  # a Python float: a numpy float64 would lift a float32 law to float64

    def throw(T, delta):
        T, delta = T.astype(dtype), delta.astype(dtype)
        traj = gv.simulate(arm, delta * T, n_steps=n_steps, save_every=n_steps, integrator=integrator,
                           check_stability=False, base_angle=lambda t: theta_f * (t / T) ** 2, dtype=dtype)
        return traj.tip[-1].astype(jnp.float64), traj.tip_velocity[-1].astype(jnp.float64)

    return jax.jit(jax.vmap(throw))


def actions(batch: int, seed: int = 0):
    k1, k2 = jax.random.split(jax.random.PRNGKey(seed))
    return (jax.random.uniform(k1, (batch,), minval=0.5, maxval=3.0),
            jax.random.uniform(k2, (batch,), minval=0.85, maxval=1.0))


def load_average() -> str:
    """``uptime``'s line, recorded beside every benchmark figure (shared by the bench scripts)."""
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def timed(fn, *args, repeats: int = 3) -> tuple[float, float]:
    """(compile + first run - median run, median of ``repeats`` runs) in s; shared by the bench scripts."""
    t0 = time.perf_counter()
    jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t0
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        runs.append(time.perf_counter() - t0)
    return first - float(np.median(runs)), float(np.median(runs))


def configurations() -> list[tuple[str, int]]:
    """(integrator, n_steps): the basketball task's default, then the RK4 peer."""
    from gvsjax.tasks.basketball import BasketballParams

    fields = BasketballParams.__dataclass_fields__
    return [(fields["integrator"].default, fields["n_steps"].default), ("rk4", 300)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--batches", type=str, default="1,256,1024,4096")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", type=str, default=None)
    args = ap.parse_args()
    print(load_average())

    T, d = actions(256, seed=1)
    converged = make_throws(3000)(T, d)[0]
    mean_t = float(jnp.mean(T * d))
    results = []
    (default, n_default), peer = configurations()
    for integrator, n_steps, dtype in ((default, n_default, jnp.float64), (default, n_default, jnp.float32),
                                       (*peer, jnp.float64)):
        throws = make_throws(n_steps, integrator, dtype)
        err = float(jnp.max(jnp.linalg.norm(throws(T, d)[0] - converged, axis=-1)))
        print(f"\n{integrator}, {n_steps} steps per throw (dt <= {3.0 / n_steps * 1e3:.1f} ms), "
              f"{jnp.dtype(dtype).name}, max release-position error vs converged RK4 (float64): {err * 1e3:.2e} mm")
        rows = []
        for batch in [int(b) for b in args.batches.split(",")]:
            compile_s, run_s = timed(throws, *actions(batch), repeats=args.repeats)
            rows.append(dict(batch=batch, throws_per_s=batch / run_s,
                             steps_per_s=batch * n_steps / run_s,
                             sim_seconds_per_wall_second=batch * mean_t / run_s,
                             median_run_s=run_s, compile_s=compile_s))
        base = rows[0]["throws_per_s"]
        print(f"{'batch':>6} {'throws/s':>10} {'steps/s':>12} {'sim s/wall s':>13} {'vs batch 1':>10} "
              f"{'compile s':>9}")
        for r in rows:
            print(f"{r['batch']:>6} {r['throws_per_s']:>10.0f} {r['steps_per_s']:>12.3g} "
                  f"{r['sim_seconds_per_wall_second']:>13.0f} {r['throws_per_s'] / base:>9.1f}x "
                  f"{r['compile_s']:>9.1f}")
        results.append(dict(integrator=integrator, n_steps=n_steps, dtype=jnp.dtype(dtype).name,
                            release_error_m=err, rows=rows))
    first, f32, peer = (r["rows"] for r in results)
    print("\ntask default vs RK4 peer, throws/s ratio: " + ", ".join(
        f"batch {a['batch']}: {a['throws_per_s'] / b['throws_per_s']:.2f}x" for a, b in zip(first, peer)))
    print("task default in float32 vs float64, throws/s ratio: " + ", ".join(
        f"batch {a['batch']}: {a['throws_per_s'] / b['throws_per_s']:.2f}x" for a, b in zip(f32, first)))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(dict(configurations=results, load_average=load_average(),
                           cpu_count=jax.local_device_count(), jax=jax.__version__), fh, indent=2)


if __name__ == "__main__":
    main()
