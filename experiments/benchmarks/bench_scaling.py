"""Scaling of the simulator and of one PPO update.

1. batch: throws/s (the paper's swing to release with the task's default
   integration, 40 ars443 steps, T ~ U[0.5, 3] s, delta ~ U[0.85, 1]) and
   basketball env-steps/s (``env.step``: the throw plus the flight/cost; one
   step = one throw) vs batch size 1 ... 16384.
2. model size: RK4 steps/s at batch 1024 vs n_gauss (2 modes) and vs the number
   of strain modes (Legendre, n_gauss = max(5, n_modes + 2)), with each model's
   linearised RK4 stability limit and the throws/s that limit allows (a 3 s
   throw needs 3 s / dt_max steps; many modes are stiff).
3. dt: throws/s at batch 1024 vs the step (n_steps per throw) of ars443 and of
   RK4, with the worst release position error vs converged RK4 (3000 steps).
4. PPO: wall time of one update (``gvsjax.ppo.train.make_update``, the path
   ``python -m gvsjax.train`` runs; basketball defaults) vs num_envs, and XLA's
   planned memory of the compiled update (``compile().memory_analysis()``:
   arguments + outputs + temporaries) and the process's peak RSS.
5. compile time per task: the training program of ``python -m gvsjax.train task=...``
   (target <= 30 s) and the env's target tables.

    python experiments/benchmarks/bench_scaling.py [--quick]

Writes benchmarks/scaling_<section>.json (``--sections batch,model,dt,compile,ppo``; run
sections in separate processes if you like, ``--replot`` gathers them),
figures/bench_scaling_{batch,model,dt,ppo}.png and prints
Markdown tables.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_sim import actions, configurations, load_average, make_throws, timed  # noqa: E402

THETA_F = math.radians(210.0)
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FIG = os.path.join(ROOT, "figures")


def vs_batch(batches):
    from gvsjax.tasks import make

    integrator, n_steps = configurations()[0]
    throws = make_throws(n_steps, integrator)
    env = make("basketball")
    params = env.default_params()

    @jax.jit
    def env_steps(keys, actions_):
        obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
        return jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, state, actions_, params)  # all outputs: no DCE

    rows = []
    for b in batches:
        T, d = actions(b)
        reps = 3 if b <= 4096 else 1
        c, r = timed(throws, T, d, repeats=reps)
        keys = jax.random.split(jax.random.PRNGKey(1), b)
        acts = jax.random.uniform(jax.random.PRNGKey(2), (b, 2), minval=-1.0, maxval=1.0)
        ce, re = timed(env_steps, keys, acts, repeats=reps)
        rows.append(dict(batch=b, integrator=integrator, n_steps=n_steps, throws_per_s=b / r,
                         steps_per_s=b * n_steps / r, compile_s=c,
                         env_steps_per_s=b / re, env_compile_s=ce))
        print(f"batch {b}: {b / r:,.0f} throws/s, {b / re:,.0f} env-steps/s", flush=True)
    return rows


def vs_model(configs, batch=1024, n_steps=100):
    rows = []
    for n_modes, n_gauss in configs:
        basis = "monomial" if n_modes <= 2 else "legendre"
        arm = gv.paper_arm(tip_force=5.886, n_modes=n_modes, n_gauss=n_gauss, basis=basis)
        dt_max = gv.stable_step_estimate(arm, "rk4", np.zeros(n_modes + 1))
        dt = 0.5 * min(dt_max, 0.01)
        # the swing scaled so that n_steps steps of dt stay stable (speed only: cost per step
        # does not depend on the values)

        def rel(T, arm=arm, dt=dt):  # bound now (B023); traced within this iteration anyway
            tr = gv.simulate(arm, n_steps * dt, n_steps=n_steps, save_every=n_steps, check_stability=False,
                             base_angle=lambda t: THETA_F * (t / T) ** 2)
            return tr.tip[-1]

        T = jnp.linspace(1.0, 1.2, batch) * n_steps * dt
        c, r = timed(jax.jit(jax.vmap(rel)), T)
        steps_s = batch * n_steps / r
        n_needed = max(1, math.ceil(3.0 / dt_max))
        rows.append(dict(n_modes=n_modes, n_gauss=n_gauss, basis=basis, rk4_steps_per_s=steps_s,
                         compile_s=c, dt_max_s=dt_max, steps_for_3s_throw=n_needed,
                         throws_per_s_at_dt_max=steps_s / max(n_needed, 300)))
        print(f"modes {n_modes} gauss {n_gauss}: {steps_s:.3g} RK4 steps/s, dt_max {dt_max:.2e} s", flush=True)
    return rows


DT_STEPS = {"ars443": (20, 24, 32, 40, 48, 60, 80), "rk4": (150, 200, 217, 240, 300, 400, 600)}


def vs_dt(step_counts=DT_STEPS, batch=1024):
    T, d = actions(batch)
    probe = actions(128, seed=3)
    converged = np.asarray(make_throws(3000)(*probe)[0])
    rows = []
    for integrator, counts in step_counts.items():
        for n in counts:
            fn = make_throws(n, integrator)
            c, r = timed(fn, T, d)
            err = float(np.max(np.linalg.norm(np.asarray(fn(*probe)[0]) - converged, axis=-1)))
            rows.append(dict(integrator=integrator, n_steps=n, dt_max_ms=3e3 / n, throws_per_s=batch / r,
                             release_error_m=err, compile_s=c))
            print(f"{integrator} n_steps {n}: {batch / r:,.0f} throws/s, error {err * 1e3:.2e} mm", flush=True)
    return rows


def vs_ppo(num_envs_list):
    from gvsjax.ppo import build_config
    from gvsjax.ppo.train import init, make_update, num_updates
    from gvsjax.tasks import make
    from gvsjax.train import task_defaults

    env = make("basketball")
    env_params = env.default_params()
    rows = []
    for n in num_envs_list:
        config = build_config(task_defaults("basketball"), "none", dict(num_envs=n))
        state = init(config, env, env_params, jax.random.PRNGKey(0))
        upd = make_update(config, env, env_params, updates_per_call=1)
        t0 = time.perf_counter()
        compiled = upd.lower(state).compile()
        compile_s = time.perf_counter() - t0
        mem = compiled.memory_analysis()
        planned = (mem.argument_size_in_bytes + mem.output_size_in_bytes + mem.temp_size_in_bytes
                   - mem.alias_size_in_bytes)
        s = state
        s, _ = compiled(s)
        jax.block_until_ready(s)
        runs = []
        for _ in range(3):
            t0 = time.perf_counter()
            s, _ = compiled(s)
            jax.block_until_ready(s)
            runs.append(time.perf_counter() - t0)
        run = float(np.median(runs))
        rows.append(dict(num_envs=n, update_s=run, episodes_per_s=n * config.num_steps / run, compile_s=compile_s,
                         xla_planned_bytes=int(planned), xla_temp_bytes=int(mem.temp_size_in_bytes),
                         peak_rss_bytes_so_far=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
                         minibatch_steps=config.update_epochs * config.num_minibatches,
                         num_updates_default=num_updates(config, env.episode_length)))
        print(f"num_envs {n}: update {run:.3f} s, XLA planned {planned / 2**20:.1f} MiB", flush=True)
    return rows


def compile_times(tasks=("basketball", "pickplace")):
    """Compile time of the training program ``python -m gvsjax.train task=...`` runs
    (``update_fn`` with the CLI's updates per call) and of the env's parameter tables."""
    from gvsjax.ppo import build_config
    from gvsjax.ppo.train import init
    from gvsjax.tasks import make
    from gvsjax.train import default_updates_per_call, task_defaults, update_fn

    rows = []
    for task in tasks:
        env = make(task)
        t0 = time.perf_counter()
        env_params = env.default_params()
        jax.block_until_ready(env_params)
        params_s = time.perf_counter() - t0
        config = build_config(task_defaults(task), "none", {})
        state = init(config, env, env_params, jax.random.PRNGKey(0))
        per_call = default_updates_per_call(config, env.episode_length)
        fn = update_fn(task, config, env, env_params, per_call)
        t0 = time.perf_counter()
        fn.lower(state).compile()
        compile_s = time.perf_counter() - t0
        rows.append(dict(task=task, env_params_s=params_s, update_compile_s=compile_s, updates_per_call=per_call,
                         num_envs=config.num_envs))
        print(f"{task}: env tables {params_s:.1f} s, update program compile {compile_s:.1f} s", flush=True)
    return rows


def read_sections(folder):
    """{section: rows, section + '_load': (start, end)} from the scaling_<section>.json files."""
    res = {}
    for name in ("batch", "model", "dt", "compile", "ppo"):
        path = os.path.join(folder, f"scaling_{name}.json")
        if os.path.exists(path):
            with open(path) as fh:
                d = json.load(fh)
            res[name], res[name + "_load"] = d["rows"], (d["load_start"], d["load_end"])
    return res


def plot(res):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(FIG, exist_ok=True)
    if "batch" in res:
        _plot_batch(plt, res["batch"])
    if "model" in res:
        _plot_model(plt, res["model"])
    if "dt" in res:
        _plot_dt(plt, res["dt"])
    if "ppo" in res:
        _plot_ppo(plt, res["ppo"])


def _plot_batch(plt, b):
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    ax.loglog([r["batch"] for r in b], [r["throws_per_s"] for r in b], "o-", label="throws/s (simulate)")
    ax.loglog([r["batch"] for r in b], [r["env_steps_per_s"] for r in b], "s--", label="env-steps/s (env.step)")
    ax.axhline(3000, color="gray", lw=0.8, ls=":", label="target 3,000/s")
    ax.set_xlabel("batch")
    ax.set_ylabel("per second")
    ax.set_title(f"Basketball throws, {b[0].get('n_steps', 300)} {b[0].get('integrator', 'rk4')} steps each")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(FIG, "bench_scaling_batch.png"), dpi=130)
    plt.close(fig)


def _plot_model(plt, m):
    fig, axs = plt.subplots(1, 2, figsize=(9, 3.6))
    g = [r for r in m if r["n_modes"] == 2]
    k = [r for r in m if r["n_gauss"] == max(5, r["n_modes"] + 2)]
    axs[0].plot([r["n_gauss"] for r in g], [r["rk4_steps_per_s"] for r in g], "o-")
    axs[0].set_xlabel("n_gauss (2 modes)")
    axs[0].set_ylabel("RK4 steps/s, batch 1024")
    axs[1].semilogy([r["n_modes"] for r in k], [r["rk4_steps_per_s"] for r in k], "o-", label="RK4 steps/s")
    axs[1].semilogy([r["n_modes"] for r in k], [r["throws_per_s_at_dt_max"] for r in k], "s--",
                    label="3 s throws/s at the stable dt")
    axs[1].set_xlabel("strain modes (n_gauss = max(5, n + 2))")
    axs[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(FIG, "bench_scaling_model.png"), dpi=130)
    plt.close(fig)


def _plot_dt(plt, d):
    """Cost against accuracy, one line per integrator (rows without the key: RK4)."""
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    for name in dict.fromkeys(r.get("integrator", "rk4") for r in d):
        rows = [r for r in d if r.get("integrator", "rk4") == name and np.isfinite(r["release_error_m"])]
        ax.loglog([max(r["release_error_m"], 1e-12) * 1e3 for r in rows], [r["throws_per_s"] for r in rows], "o-",
                  label=name)
        for r in rows:
            ax.annotate(str(r["n_steps"]), (max(r["release_error_m"], 1e-12) * 1e3, r["throws_per_s"]), fontsize=7)
    ax.axvline(1.0, color="gray", lw=0.8, ls=":", label="1 mm target")
    ax.set_xlabel("worst release error vs converged RK4 (mm)")
    ax.set_ylabel("throws/s, batch 1024")
    ax.set_title("Accuracy per cost (labels: steps per throw)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(FIG, "bench_scaling_dt.png"), dpi=130)
    plt.close(fig)


def _plot_ppo(plt, p):
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    ax.loglog([r["num_envs"] for r in p], [r["update_s"] for r in p], "o-", label="update wall s")
    ax2 = ax.twinx()
    ax2.loglog([r["num_envs"] for r in p], [r["xla_planned_bytes"] / 2**20 for r in p], "s--", color="C1")
    ax.set_xlabel("num_envs")
    ax.set_ylabel("one PPO update (s)")
    ax2.set_ylabel("XLA planned memory (MiB)", color="C1")
    ax.set_title("Basketball PPO update (8 epochs x 8 minibatches)")
    fig.tight_layout()
    fig.savefig(os.path.join(FIG, "bench_scaling_ppo.png"), dpi=130)
    plt.close(fig)


def print_tables(res):
    for name in ("batch", "model", "dt", "compile", "ppo"):
        if name + "_load" in res:
            print(f"{name}: load {res[name + '_load'][0]} -> {res[name + '_load'][1]}")
    res = {k: res.get(k, []) for k in ("batch", "model", "dt", "ppo", "compile")}
    print("\n| batch | throws/s | integrator steps/s | env-steps/s | compile s |")
    print("|---|---|---|---|---|")
    for r in res["batch"]:
        print(f"| {r['batch']} | {r['throws_per_s']:,.0f} | {r['steps_per_s']:.3g} | "
              f"{r['env_steps_per_s']:,.0f} | {r['compile_s']:.1f} |")
    print("\n| n_modes | n_gauss | RK4 steps/s (batch 1024) | stable dt (ms) | 3 s throws/s at that dt | compile s |")
    print("|---|---|---|---|---|---|")
    for r in res["model"]:
        print(f"| {r['n_modes']} | {r['n_gauss']} | {r['rk4_steps_per_s']:.3g} | {r['dt_max_s'] * 1e3:.3g} | "
              f"{r['throws_per_s_at_dt_max']:,.1f} | {r['compile_s']:.1f} |")
    print("\n| integrator | steps per throw | largest dt (ms) | throws/s (batch 1024) | release error (mm) |")
    print("|---|---|---|---|---|")
    for r in res["dt"]:
        print(f"| {r['integrator']} | {r['n_steps']} | {r['dt_max_ms']:.1f} | {r['throws_per_s']:,.0f} | "
              f"{r['release_error_m'] * 1e3:.2e} |")
    print("\n| num_envs | one update (s) | episodes/s | XLA planned MiB | peak RSS so far MiB | compile s |")
    print("|---|---|---|---|---|---|")
    for r in res["ppo"]:
        print(f"| {r['num_envs']} | {r['update_s']:.3f} | {r['episodes_per_s']:,.0f} | "
              f"{r['xla_planned_bytes'] / 2**20:.1f} | {r['peak_rss_bytes_so_far'] / 2**20:.0f} | "
              f"{r['compile_s']:.1f} |")
    print("\n| task | env tables s | training-program compile s | updates per call |")
    print("|---|---|---|---|")
    for r in res["compile"]:
        print(f"| {r['task']} | {r['env_params_s']:.1f} | {r['update_compile_s']:.1f} | {r['updates_per_call']} |")



def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer points")
    ap.add_argument("--out", default=os.path.join(ROOT, "benchmarks"), help="folder of scaling_<section>.json")
    ap.add_argument("--sections", default="batch,model,dt,compile,ppo")
    ap.add_argument("--ppo-envs", default=None, help="comma-separated num_envs for the ppo section")
    ap.add_argument("--replot", action="store_true", help="only plot and print the saved JSON files")
    args = ap.parse_args()
    if args.replot:
        res = read_sections(args.out)
        plot(res)
        print_tables(res)
        return
    print("load at start:", load_average())
    q = args.quick
    sections = [
        ("batch", lambda: vs_batch([1, 16, 256, 1024, 4096] if q else [1, 4, 16, 64, 256, 1024, 4096, 16384])),
        ("model", lambda: vs_model([(2, 3), (2, 5), (2, 8), (2, 12), (1, 5), (3, 5), (4, 6), (6, 8)] if q else
                                   [(2, 3), (2, 5), (2, 8), (2, 12), (2, 16), (1, 5), (3, 5), (4, 6), (6, 8)])),
        ("dt", lambda: vs_dt({"ars443": (32, 40, 60), "rk4": (240, 300, 600)} if q else DT_STEPS)),
        ("compile", compile_times),
        ("ppo", lambda: vs_ppo([int(n) for n in args.ppo_envs.split(",")] if args.ppo_envs else
                               [256, 1024, 4096] if q else [64, 256, 1024, 4096, 16384])),
    ]
    os.makedirs(args.out, exist_ok=True)
    for name, run in sections:  # one JSON per section: sections can run in separate processes
        if name not in args.sections.split(","):
            continue
        out = dict(load_start=load_average(), jax=jax.__version__, rows=run())
        out["load_end"] = load_average()
        with open(os.path.join(args.out, f"scaling_{name}.json"), "w") as fh:
            json.dump(out, fh, indent=2)
    res = read_sections(args.out)
    plot(res)
    print_tables(res)


if __name__ == "__main__":
    main()
