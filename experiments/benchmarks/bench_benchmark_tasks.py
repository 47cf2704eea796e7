"""Environment steps per second of the four benchmark tasks: gvsjax against their PyElastica twins.

* gvsjax: the task's default env on its training params in its training dtype (float32, as ``gvsjax.train``),
  ``jit(vmap(env.step))`` over a batch of 1, 500 and 1024 environments, ``--steps`` steps inside one
  ``lax.scan`` per call with uniform random actions; the time is the median of ``--repeats`` calls after
  a compiling one. No auto-reset: the steps of one episode, env.step alone. Each batch is timed on one
  JAX device and, split in equal parts (``gvsjax.utils.sharding``), on ``--devices`` CPU devices, one
  per core (``XLA_FLAGS=--xla_force_host_platform_device_count``, set by this script), as PPO
  training splits its envs when started with that flag (docs/scale_out.md).
* PyElastica: one twin (``elastica_twins.ElasticaTwin``) in this process, ``--pe-steps`` control steps
  of random actions after a first one (numba compiles); twins share nothing, so 2 processes on the 2
  cores give at most twice that: the reported PyElastica throughput is 2 x the one-process rate.

Ratio = gvsjax's steps/s at the batch / PyElastica's 2-core steps/s, measured one after the other in
the same process. The field's claim (Choi & Tong, arXiv 2511.06667): DisMech ~6x Elastica without contact,
~40x with contact, at 500 environments; issue 48's target for gvsjax: >= 60x and >= 400x.

    python experiments/benchmarks/bench_benchmark_tasks.py            # ~25 min on 2 idle cores

Writes benchmarks/benchmark_tasks_speed.json (os.getloadavg() before and after each measurement).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path[:0] = [HERE, ROOT, os.path.join(ROOT, "experiments", "transfer")]  # elastica_twins

# the CPU device count is fixed when JAX starts: read before anything imports it
_early = argparse.ArgumentParser(add_help=False)
_early.add_argument("--devices", type=int, default=os.cpu_count() or 1,
                    help="CPU devices to split the batch over, besides one (default: the cores)")
_DEVICES = _early.parse_known_args()[0].devices
os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                           + f" --xla_force_host_platform_device_count={_DEVICES}").strip()

import elastica_twins as et  # noqa: I001,E402  (imports gvsjax first: it configures JAX)
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from gvsjax.tasks import make  # noqa: E402
from gvsjax.utils import sharding  # noqa: E402

TASKS = ("follow_target", "ik_4d", "obstacles_2d", "obstacles_3d")
CONTACT = {"follow_target": False, "ik_4d": False, "obstacles_2d": True, "obstacles_3d": True}


def gvsjax_rate(name: str, batch: int, steps: int, repeats: int, devices: int) -> dict:
    """env steps/s of ``jit(vmap(env.step))`` at ``batch`` split over ``devices`` devices, ``steps`` steps per
    timed call."""
    env = make(name)
    params = env.with_sim_dtype(env.train_params(), env.train_sim_dtype)  # as gvsjax.train simulates
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))
    mesh = sharding.mesh_for(batch) if devices > 1 else None
    if devices > 1 and (mesh is None or mesh.size != devices):
        raise ValueError(f"batch {batch} cannot be split over {devices} devices")

    def rollout(env_keys, state):  # every env draws its actions from its own key: any split of the batch
        def body(state, t):
            keys = jax.vmap(lambda k: jax.random.split(jax.random.fold_in(k, t)))(env_keys)
            action = jax.vmap(lambda k: jax.random.uniform(k, (env.action_size,), minval=-1.0, maxval=1.0))(
                keys[:, 0])
            _, state, reward, _, _ = step(keys[:, 1], state, action, params)
            return state, reward

        state, rewards = jax.lax.scan(body, state, jnp.arange(steps))
        return state, rewards.T

    run = jax.jit(sharding.split_batch(rollout, mesh, (0, 0)))
    keys = [sharding.put(jax.random.split(jax.random.PRNGKey(1 + r), batch), sharding.batch_spec(mesh))
            for r in range(repeats + 1)]
    _, state = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(jax.random.split(jax.random.PRNGKey(0), batch), params)
    state = sharding.put(state, sharding.batch_spec(mesh))
    load = os.getloadavg()
    t0 = time.perf_counter()
    jax.block_until_ready(run(keys[0], state))
    first = time.perf_counter() - t0
    times = []
    for r in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(run(keys[r + 1], state))
        times.append(time.perf_counter() - t0)
    med = statistics.median(times)
    return {"batch": batch, "devices": devices, "steps_per_call": steps, "median_call_s": med, "calls_s": times,
            "compile_s": first - med, "env_steps_per_s": batch * steps / med, "sim_dtype": params.arm.sim_dtype,
            "loadavg_before": list(load), "loadavg_after": list(os.getloadavg())}


def pyelastica_rate(name: str, n_steps: int) -> dict:
    """env steps/s of one PyElastica twin in this process (random actions, after a first step)."""
    env = make(name)
    twin = et.ElasticaTwin(env, env.default_params())
    key = jax.random.PRNGKey(0)
    twin.reset(key)
    actions = np.asarray(jax.random.uniform(jax.random.PRNGKey(1), (n_steps + 1, env.action_size), minval=-1.0,
                                            maxval=1.0))
    twin.step(jax.random.fold_in(key, 0), actions[0])  # numba compiles
    load = os.getloadavg()
    t0 = time.perf_counter()
    for t in range(1, n_steps + 1):
        twin.step(jax.random.fold_in(key, t), actions[t])
    wall = time.perf_counter() - t0
    rate = n_steps / wall
    return {"env_steps": n_steps, "wall_s": wall, "verlet_steps_per_env_step": twin.n_sub,
            "verlet_step_us": 1e6 * wall / (n_steps * twin.n_sub), "env_steps_per_s_1_process": rate,
            "env_steps_per_s_2_cores": 2.0 * rate, "loadavg_before": list(load), "loadavg_after": list(os.getloadavg())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
                                 parents=[_early])
    ap.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    ap.add_argument("--batches", default="1,500,1024")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--pe-steps", type=int, default=0, help="PyElastica control steps (default: ~10 s of each)")
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "benchmark_tasks_speed.json"))
    args = ap.parse_args()
    from bench_sim import load_average

    out: dict = {"command": "python experiments/benchmarks/bench_benchmark_tasks.py " + " ".join(sys.argv[1:]),
                 "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
                 "jax": jax.__version__, "uptime_before": load_average(), "tasks": {}}
    for name in args.tasks:
        contact = CONTACT[name]
        pe = pyelastica_rate(name, args.pe_steps or (4 if contact else 20))
        print(f"{name}: PyElastica {pe['env_steps_per_s_1_process']:.2f} env steps/s in one process "
              f"({pe['verlet_step_us']:.0f} us per Verlet step)", flush=True)
        rows = []
        for b in (int(x) for x in args.batches.split(",")):
            for d in sorted({1, args.devices}):
                if b % d:
                    continue
                g = gvsjax_rate(name, b, 2 if contact else 8, args.repeats, d)
                g["ratio_to_pyelastica_2_cores"] = g["env_steps_per_s"] / pe["env_steps_per_s_2_cores"]
                rows.append(g)
                print(f"  gvsjax batch {b} on {d} device(s): {g['env_steps_per_s']:.1f} env steps/s "
                      f"({g['sim_dtype']}), {g['ratio_to_pyelastica_2_cores']:.1f}x PyElastica on 2 cores", flush=True)
        out["tasks"][name] = {"contact": contact, "pyelastica": pe, "gvsjax": rows,
                              "target_ratio": 400.0 if contact else 60.0,
                              "field_claim_dismech_over_elastica": 40.0 if contact else 6.0}
    out["uptime_after"] = load_average()
    with open(args.json, "w") as fh:
        json.dump(out, fh, indent=1)
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
