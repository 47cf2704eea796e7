"""Sim-to-sim transfer of the trained basketball policy: gvsjax -> PyElastica.

The policy (trained on the task's model: ``gv.paper_arm(tip_force=5.886)``, 2 monomial bending
modes, 40 ``ars443`` steps) chooses (T, delta) for held-out targets (the first ``--n-targets``
of ``python -m gvsjax.evaluate``'s 1000, i.e. ``reset`` keys of seed 1_000_003). The same
actions are then thrown by other models of the arm, up to release; the ball's flight and the
miss are the task's own (``floor_time``, ``closest_approach``: the exact closest distance
between the ballistic path and the target):

* ``gvsjax 2 modes``: the task itself (``Basketball.step``), the model the policy was trained on;
* ``gvsjax 2 modes, 8 Gauss``: the same basis with finer quadrature (quadrature error);
* ``gvsjax K Legendre``: K Legendre bending modes (``paper_arm(n_modes=K, basis="legendre")``,
  as ``contact_pyelastica.py`` builds them), bending only: the basis truncation (K = ``--modes``,
  checked against ``--fine-modes``);
* ``gvsjax K Legendre + stretch/shear``: the same link with the in-plane stretch and shear
  strains active too (Legendre order ``--ss-order``), which PyElastica's rod has: the share
  of shear and stretch. gvsjax damps them with eta (3A, A) (SoRoSim's convention), PyElastica
  leaves them undamped (``bench_pyelastica.py``), and a variant without their damping;
* ``PyElastica``: ``bench_pyelastica.pyelastica_throw``: a 100-element shearable, extensible
  ``CosseratRod``, position Verlet at ``--dt``, the base prescribed, gravity, the ball's weight
  on the tip, Kelvin-Voigt bending/torsion damping with gvsjax's law.

The gvsjax variants run through ``Basketball.step`` with ``params.arm`` (and the step count)
replaced; every variant's release is checked against the same model at 4x the steps.
PyElastica throws (~0.3-1.5 s each) are cached one by one in ``--cache`` (a rerun resumes;
``--workers N`` runs them in N spawned processes; keep 1 on a shared machine); the cached
throws at ``--dt``/2 (``--check-dt``, the fastest throws first) bound PyElastica's time error,
and the same throws with ``--check-elements`` elements its discretisation error. A model already in
``--json`` for the same throws is not recomputed; ``--no-step-check`` skips the 4x-steps check of the
others (it doubles their compile time).

    pip install pyelastica          # or pip install -e ".[bench]"
    python experiments/transfer/transfer_pyelastica.py --checkpoint runs/basketball-default [--n-targets 200]
    python experiments/transfer/transfer_pyelastica.py --replot

(The committed JSON: a first run computed the task, 8 Gauss points, 6 Legendre and 6 Legendre +
stretch/shear models with their 4x-steps checks and all PyElastica throws; a second, with
``--no-step-check``, added the 8-mode and the undamped models and the 200-element check.)

Writes benchmarks/transfer_pyelastica.json (summary), benchmarks/transfer_pyelastica_throws.json
(the cache: one PyElastica release per target) and figures/transfer_pyelastica.png.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation
from gvsjax.core.model import StrainBasis
from gvsjax.ppo import load_policy
from gvsjax.ppo.checkpoint import make_policy, resolve
from gvsjax.tasks import basketball as bb
from gvsjax.tasks.base import bounded

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.append(os.path.join(ROOT, "experiments", "benchmarks"))  # bench_pyelastica, in the benchmarks folder
EVAL_N, EVAL_SEED = 1000, 1_000_003  # python -m gvsjax.evaluate's targets for a seed-0 run


# ----------------------------------------------------------------------------- models

def bending_arm(n_modes: int, n_gauss: int, basis: str = "legendre", **arm):
    """The paper's arm with ``n_modes`` bending modes; ``arm``: other ``paper_arm`` overrides
    (default: the ball's weight on the tip)."""
    return gv.paper_arm(**{"tip_force": bb.BALL_WEIGHT, **arm}, n_modes=n_modes, n_gauss=n_gauss, basis=basis)


def cosserat_arm(n_modes: int, ss_order: int, n_gauss: int, **arm):
    """``bending_arm`` with the in-plane stretch (local x) and shear (local y) strains active,
    Legendre order ``ss_order`` each (the paper's arm bends about z in the x-y plane)."""
    robot = bending_arm(n_modes, n_gauss, **arm)
    link = robot.links[0]
    basis = StrainBasis(orders=(-1, -1, n_modes - 1, ss_order, ss_order, -1), kind="legendre")
    return robot.replace(links=(link.replace(basis=basis),))


def cosserat_arm_undamped(n_modes: int, ss_order: int, n_gauss: int, **arm):
    """``cosserat_arm`` with stretch and shear undamped, as in PyElastica's rod here."""
    robot = cosserat_arm(n_modes, ss_order, n_gauss, **arm)
    return robot.replace(links=(robot.links[0].replace(damping_factors=(1.0, 3.0, 3.0, 0.0, 0.0, 0.0)),))


# the models' names, by role (the decomposition and the figure refer to them)
TASK, GAUSS8 = "gvsjax 2 modes (the task)", "gvsjax 2 modes, 8 Gauss points"
BEND = "gvsjax {K} Legendre modes"
BEND_FINE = "gvsjax {K2} Legendre modes"
SS = "gvsjax {K} Legendre + stretch/shear"
SS_UNDAMPED = "gvsjax {K} Legendre + undamped stretch/shear"
PYELASTICA = "PyElastica {n} elements"


def names(K: int, K2: int, n_elements: int) -> dict:
    return dict(task=TASK, gauss8=GAUSS8, bend=BEND.format(K=K), bend_fine=BEND_FINE.format(K2=K2),
                ss=SS.format(K=K), ss_undamped=SS_UNDAMPED.format(K=K), pyelastica=PYELASTICA.format(n=n_elements))


def variants(K: int, K2: int, ss_order: int, n_elements: int, **arm) -> dict:
    """gvsjax models: name -> arm (None: the task's own); the task's first. ``arm``: ``paper_arm``
    overrides shared by all (default: the ball's weight on the tip)."""
    nm = names(K, K2, n_elements)
    return {
        nm["task"]: None,
        nm["gauss8"]: bending_arm(2, 8, "monomial", **arm),
        nm["bend"]: bending_arm(K, max(8, K + 2), **arm),
        nm["bend_fine"]: bending_arm(K2, max(8, K2 + 2), **arm),
        nm["ss"]: cosserat_arm(K, ss_order, max(8, K + 2), **arm),
        nm["ss_undamped"]: cosserat_arm_undamped(K, ss_order, max(8, K + 2), **arm),
    }


def release_fn(env: bb.Basketball, params):
    """``(actions (n, 2), targets (n, 2)) -> (miss, p0, v0)`` through ``Basketball.step``."""

    @jax.jit
    def run(actions, targets):
        n = actions.shape[0]
        state = bb.BasketballState(target=targets, source_action=actions, step=jnp.zeros((n,), jnp.int32))
        keys = jax.random.split(jax.random.PRNGKey(0), n)  # step ignores its key
        _, _, _, _, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, state, actions, params)
        T, delta = bb.action_to_physical(actions, params)
        p0, v0 = jax.vmap(lambda T, d: bb.release_state(params, T, d))(T, delta)
        return jnp.where(info["valid"], info["cost"], jnp.inf), p0, v0

    return run


# ----------------------------------------------------------------------------- PyElastica

def _pe_one(job):
    """One PyElastica release (run in this process or a spawned worker)."""
    from bench_pyelastica import is_stable, pyelastica_throw

    i, T, delta, dt, n_elements = job
    r = pyelastica_throw(T, delta, dt, n_elements)
    return i, dict(T=T, delta=delta, dt=dt, n_elements=n_elements, tip=r["tip"].tolist(),
                   tip_velocity=r["tip_velocity"].tolist(), stable=is_stable(r), stretch=r["stretch"],
                   wall_s=r["wall_s"] + r["setup_s"], n_steps=r["n_steps"])


def _key(i: int, dt: float, n_elements: int) -> str:
    return f"{i}|{dt:.6g}|{n_elements}"


def pyelastica_releases(T, delta, idx, dt, n_elements, cache_path, workers=1) -> dict:
    """Cached PyElastica releases of throws ``idx`` (indices into T, delta); resumes from the cache."""
    cache = {}
    if os.path.exists(cache_path):
        with open(cache_path) as fh:
            cache = json.load(fh)
    jobs = []
    for i in idx:
        c = cache.get(_key(i, dt, n_elements))
        if c is None or not (math.isclose(c["T"], float(T[i]), rel_tol=1e-12)
                             and math.isclose(c["delta"], float(delta[i]), rel_tol=1e-12)):
            jobs.append((int(i), float(T[i]), float(delta[i]), dt, n_elements))
    print(f"PyElastica dt={dt:.3g}: {len(idx) - len(jobs)} throws cached, {len(jobs)} to run", flush=True)

    def save():
        tmp = cache_path + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(cache, fh)
        os.replace(tmp, cache_path)

    t0, last = time.perf_counter(), time.perf_counter()
    if workers > 1 and jobs:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(workers) as pool:  # spawn: never fork a process running JAX
            results = pool.imap_unordered(_pe_one, jobs)
            for k, (i, r) in enumerate(results, 1):
                cache[_key(i, dt, n_elements)] = r
                if time.perf_counter() - last > 20 or k == len(jobs):
                    save()
                    last = time.perf_counter()
                    print(f"  {k}/{len(jobs)} ({time.perf_counter() - t0:.0f} s)", flush=True)
    else:
        for k, job in enumerate(jobs, 1):
            i, r = _pe_one(job)
            cache[_key(i, dt, n_elements)] = r
            if time.perf_counter() - last > 20 or k == len(jobs):
                save()
                last = time.perf_counter()
                print(f"  {k}/{len(jobs)} ({time.perf_counter() - t0:.0f} s)", flush=True)
    return {int(i): cache[_key(i, dt, n_elements)] for i in idx}


def pyelastica_misses(rel: dict, idx, targets, g, y_floor):
    """(miss, p0, v0) of cached releases: the task's flight and closest approach."""
    p0 = jnp.asarray([rel[i]["tip"][:2] for i in idx])
    v0 = jnp.asarray([rel[i]["tip_velocity"][:2] for i in idx])
    tau_end = bb.floor_time(p0, v0, g, y_floor)
    cost, _ = bb.closest_approach(p0, v0, jnp.asarray(targets[idx]), g, tau_end)
    ok = (np.array([rel[i]["stable"] for i in idx]) & np.isfinite(np.asarray(cost))
          & np.asarray(jax.vmap(lambda v: bounded(v, bb.RELEASE_SPEED_BOUND))(v0)))
    return np.where(ok, np.asarray(cost), np.inf), np.asarray(p0), np.asarray(v0)


# ----------------------------------------------------------------------------- the experiment

def run(args) -> dict:
    config, env, params, net = load_policy(resolve(args.checkpoint))
    policy = make_policy(config, env.action_size, net)
    keys = jax.random.split(jax.random.PRNGKey(EVAL_SEED), EVAL_N)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    actions = jax.jit(policy)(obs)
    targets = np.asarray(state.target)
    T, delta = (np.asarray(x) for x in bb.action_to_physical(actions, params))
    n = args.n_targets
    idx = np.arange(n)

    out: dict = dict(checkpoint=str(resolve(args.checkpoint)), n_targets=n, eval_seed=EVAL_SEED,
                     targets=targets[:n].tolist(), T=T[:n].tolist(), delta=delta[:n].tolist(), models={})
    # --- gvsjax: the task's model and richer ones, each checked at 4x the steps; a model already in
    # --json for the same throws is reused
    previous = {}
    if os.path.exists(args.json):
        with open(args.json) as fh:
            prev = json.load(fh)
        if prev.get("T") == out["T"] and prev.get("delta") == out["delta"]:
            previous = prev["models"]
    for name, arm in variants(args.modes, args.fine_modes, args.ss_order, args.elements).items():
        if name in previous and ("vs_4x_steps" in previous[name] or args.no_step_check):
            out["models"][name] = previous[name]
            print(f"{name}: from {args.json}", flush=True)
            continue
        p = params if arm is None else dataclasses.replace(params, arm=arm)
        t0 = time.perf_counter()
        miss, p0, v0 = (np.asarray(x) for x in release_fn(env, p)(actions[:n], jnp.asarray(targets[:n])))
        wall = time.perf_counter() - t0
        step_err = None
        if not args.no_step_check:
            fine = dataclasses.replace(p, n_steps=4 * p.n_steps)
            miss_f, p0_f, v0_f = (np.asarray(x) for x in release_fn(env, fine)(actions[:n], jnp.asarray(targets[:n])))
            step_err = dict(tip_mm=1e3 * float(np.max(np.linalg.norm(p0 - p0_f, axis=1))),
                            velocity_mm_s=1e3 * float(np.max(np.linalg.norm(v0 - v0_f, axis=1))),
                            miss_cm=1e2 * float(np.max(np.abs(miss - miss_f))))
        dofs = (p.arm.links[0].basis.n_dofs, p.arm.links[0].basis.orders, p.arm.links[0].n_gauss)
        out["models"][name] = dict(miss=miss.tolist(), p0=p0.tolist(), v0=v0.tolist(), wall_s=wall,
                                   n_steps=p.n_steps, strain_dofs=dofs[0], orders=list(dofs[1]), n_gauss=dofs[2],
                                   vs_4x_steps=step_err, metrics=bb.miss_metrics(miss))
        print(f"{name}: {env.summary(bb.miss_metrics(miss))}; 4x steps: {step_err}", flush=True)
    # --- PyElastica
    rel = pyelastica_releases(T, delta, idx, args.dt, args.elements, args.cache, args.workers)
    miss, p0, v0 = pyelastica_misses(rel, idx, targets, params.g, params.y_floor)
    name = PYELASTICA.format(n=args.elements)
    out["models"][name] = dict(miss=miss.tolist(), p0=p0.tolist(), v0=v0.tolist(), dt=args.dt,
                               wall_s=float(sum(rel[i]["wall_s"] for i in idx)),
                               max_stretch=float(max(rel[i]["stretch"] for i in idx)),
                               metrics=bb.miss_metrics(miss))
    print(f"{name}: {env.summary(bb.miss_metrics(miss))}", flush=True)
    # PyElastica's time error: the fastest throws (and some others) again at dt/2
    if args.check_dt:
        order = np.argsort(T[:n] * delta[:n])
        chk = np.unique(np.concatenate([order[: args.check_dt // 2], idx[:: max(1, n // (args.check_dt // 2))]]))
        half = pyelastica_releases(T, delta, chk, args.dt / 2, args.elements, args.cache, args.workers)
        m_half, p_half, v_half = pyelastica_misses(half, chk, targets, params.g, params.y_floor)
        out["models"][name]["vs_half_dt"] = dict(
            n_throws=int(len(chk)), tip_mm=1e3 * float(np.max(np.linalg.norm(p_half - p0[chk], axis=1))),
            velocity_mm_s=1e3 * float(np.max(np.linalg.norm(v_half - v0[chk], axis=1))),
            miss_cm=1e2 * float(np.max(np.abs(m_half - miss[chk]))))
        print(f"  vs dt/2 on {len(chk)} throws: {out['models'][name]['vs_half_dt']}", flush=True)
        # PyElastica's discretisation: the same throws with --check-elements elements (at dt/2)
        if args.check_elements:
            fine = pyelastica_releases(T, delta, chk, args.dt / 2, args.check_elements, args.cache, args.workers)
            m_fine, p_fine, v_fine = pyelastica_misses(fine, chk, targets, params.g, params.y_floor)
            ss = out["models"][names(args.modes, args.fine_modes, args.elements)["ss"]]
            d_ss = np.linalg.norm(np.array(ss["p0"])[chk] - p_half, axis=1)
            d_el = np.linalg.norm(p_fine - p_half, axis=1)
            out["models"][name]["vs_elements"] = dict(
                n_elements=args.check_elements, n_throws=int(len(chk)), throws=chk.tolist(),
                tip_mm_median=1e3 * float(np.median(d_el)), tip_mm_max=1e3 * float(np.max(d_el)),
                miss_cm_max=1e2 * float(np.max(np.abs(m_fine - m_half))),
                p0=p_fine.tolist(), v0=v_fine.tolist(), miss=m_fine.tolist(),
                gvsjax_ss_vs_pyelastica_tip_mm_median=1e3 * float(np.median(d_ss)))
            print(f"  {args.check_elements} vs {args.elements} elements (dt/2) on {len(chk)} throws: "
                  f"{ {k: v for k, v in out['models'][name]['vs_elements'].items() if not isinstance(v, list)} }",
                  flush=True)
    out["roles"] = names(args.modes, args.fine_modes, args.elements)
    out["decomposition"] = decomposition(out)
    return out


def decomposition(out: dict) -> list[dict]:
    """Release-state differences between pairs of models (median and max over the targets)."""
    r = out["roles"]
    pairs = [("quadrature", "task", "gauss8"), ("basis", "task", "bend"), ("basis convergence", "bend", "bend_fine"),
             ("stretch/shear", "bend", "ss"), ("stretch/shear damping", "ss", "ss_undamped"),
             ("the rest", "ss", "pyelastica"), ("the rest (undamped stretch/shear)", "ss_undamped", "pyelastica"),
             ("bending only vs PyElastica", "bend", "pyelastica"), ("total", "task", "pyelastica")]
    rows = []
    for what, a, b in pairs:
        if r[a] not in out["models"] or r[b] not in out["models"]:
            continue
        A, B = out["models"][r[a]], out["models"][r[b]]
        dp = np.linalg.norm(np.subtract(A["p0"], B["p0"]), axis=1)
        dv = np.linalg.norm(np.subtract(A["v0"], B["v0"]), axis=1)
        dm = np.abs(np.subtract(A["miss"], B["miss"]))
        rows.append(dict(what=what, a=r[a], b=r[b], tip_mm_median=1e3 * float(np.median(dp)),
                         tip_mm_max=1e3 * float(np.max(dp)), velocity_mm_s_median=1e3 * float(np.median(dv)),
                         velocity_mm_s_max=1e3 * float(np.max(dv)), miss_change_cm_median=1e2 * float(np.median(dm))))
    return rows


# ----------------------------------------------------------------------------- output

def plot(res: dict, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models, r = res["models"], res["roles"]
    T = np.array(res["T"])
    fig, ((ax, bx), (cx, dx)) = plt.subplots(2, 2, figsize=(13, 9))
    bins = np.logspace(-4, 0, 41)
    shown = [("task", "-", "C0"), ("bend", "--", "C2"), ("bend_fine", ":", "C2"), ("ss", "-.", "C1"),
             ("pyelastica", "-", "k")]
    for role, ls, c in shown:
        if r[role] not in models:
            continue
        name, m = r[role], models[r[role]]
        miss = np.sort(np.minimum(np.array(m["miss"]), 10.0))
        k = m["metrics"]
        label = f"{name}: {100 * k['within_1cm']:.1f}% < 1 cm, {100 * k['success_rate_10cm']:.1f}% < 10 cm"
        ax.plot(np.maximum(miss, 1e-4), np.arange(1, len(miss) + 1) / len(miss) * 100, ls, color=c, lw=1.6,
                label=label)
        if role in ("task", "bend", "pyelastica"):
            bx.hist(np.clip(miss, 1e-4, 1.0), bins=bins, histtype="step", color=c, lw=1.5, ls=ls, label=name)
            cx.plot(T, 100 * np.array(m["miss"]), "o" if role == "pyelastica" else ".", ms=3, color=c,
                    mfc="none" if role == "pyelastica" else c, label=name)
    for a in (ax, bx):
        a.set_xscale("log")
        for x in (0.01, 0.1):
            a.axvline(x, color="0.5", lw=0.8, ls=":")
        a.set_xlabel("miss (m)")
    ax.set_ylabel(f"held-out targets with a smaller miss (%, of {res['n_targets']})")
    ax.set_title("(a) CDF of the miss: the policy's actions in each model", fontsize=10)
    ax.legend(fontsize=7, loc="upper left")
    bx.set_ylabel("targets")
    bx.set_title("(b) miss histogram", fontsize=10)
    bx.legend(fontsize=7, loc="upper left")
    cx.set_yscale("log")
    cx.axhline(1.0, color="0.5", lw=0.8, ls=":")
    cx.axhline(10.0, color="0.5", lw=0.8, ls=":")
    cx.set_xlabel("swing time T (s) chosen by the policy")
    cx.set_ylabel("miss (cm)")
    cx.set_title("(c) miss per throw vs the swing time", fontsize=10)
    cx.legend(fontsize=7)
    P = {k: np.array(v["p0"]) for k, v in models.items()}
    for (a, b), c, lab in (((r["task"], r["bend"]), "C2", f"basis: 2 modes vs {r['bend'].split()[1]} Legendre"),
                           ((r["bend"], r["bend_fine"]), "C7", "basis convergence: "
                            f"{r['bend'].split()[1]} vs {r['bend_fine'].split()[1]} Legendre"),
                           ((r["bend"], r["ss"]), "C1", "stretch/shear on vs off"),
                           ((r["ss"], r["pyelastica"]), "k", "the rest: gvsjax (+ stretch, shear) vs PyElastica")):
        if a in P and b in P:
            dx.plot(T, 1e3 * np.linalg.norm(P[a] - P[b], axis=1), ".", ms=3, color=c, label=lab)
    pe = models[r["pyelastica"]].get("vs_elements")
    if pe:
        chk, p_fine = np.array(pe["throws"]), np.array(pe["p0"])
        n_el = pe["n_elements"]
        dx.plot(T[chk], 1e3 * np.linalg.norm(P[r["ss"]][chk] - p_fine, axis=1), "x", ms=7, mew=1.5, color="C3",
                label=f"gvsjax (+ stretch, shear) vs PyElastica {n_el} elements")
        dx.plot(T[chk], 1e3 * np.linalg.norm(P[r["pyelastica"]][chk] - p_fine, axis=1), "+", ms=8, mew=1.5,
                color="k", label=f"PyElastica {r['pyelastica'].split()[1]} vs {n_el} elements")
    dx.set_yscale("log")
    dx.set_xlabel("swing time T (s)")
    dx.set_ylabel("release position difference (mm)")
    dx.set_title("(d) where the models part: the release tip, per throw", fontsize=10)
    dx.legend(fontsize=7)
    fig.tight_layout()
    os.makedirs(os.path.dirname(out), exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)


def vs_fine_pyelastica(res: dict) -> list[dict]:
    """Every model's release against PyElastica with ``--check-elements`` elements (at dt/2), on the
    throws of that check: which model the finer discretisation moves towards."""
    pe = res["models"][res["roles"]["pyelastica"]].get("vs_elements")
    if not pe:
        return []
    chk, p_fine, m_fine = np.array(pe["throws"]), np.array(pe["p0"]), np.array(pe["miss"])
    rows = []
    for name, m in res["models"].items():
        p = np.array(m["p0"])[chk]
        d = np.linalg.norm(p - p_fine, axis=1)
        u = p / np.linalg.norm(p, axis=1)[:, None]
        along = (p - p_fine)[:, 0] * -u[:, 1] + (p - p_fine)[:, 1] * u[:, 0]  # along the swing (tangential)
        rows.append(dict(model=name, tip_mm_median=1e3 * float(np.median(d)), tip_mm_max=1e3 * float(np.max(d)),
                         along_swing_mm_median=1e3 * float(np.median(along)),
                         miss_change_cm_median=1e2 * float(np.median(np.abs(np.array(m["miss"])[chk] - m_fine)))))
    return rows


def print_tables(res: dict) -> None:
    print(f"\n{res['n_targets']} held-out targets (seed {res['eval_seed']}), the policy's actions in each model\n")
    print("| model | strain DoFs | < 10 cm | < 1 cm | median | p95 | max | release vs 4x steps (mm) |")
    print("|---|---|---|---|---|---|---|---|")
    for name, m in res["models"].items():
        k = m["metrics"]
        err = m.get("vs_4x_steps") or m.get("vs_half_dt")
        e = f"{err['tip_mm']:.3f}" if err else ""
        if "vs_half_dt" in m:
            e += f" (dt/2, {m['vs_half_dt']['n_throws']} throws)"
        print(f"| {name} | {m.get('strain_dofs', '')} | {100 * k['success_rate_10cm']:.1f}% | "
              f"{100 * k['within_1cm']:.1f}% | {100 * k['median_m']:.2f} cm | {100 * k['p95_m']:.2f} cm | "
              f"{100 * k['max_m']:.2f} cm | {e} |")
    print("\n| what | from | to | release tip: median / max (mm) | tip velocity: median / max (mm/s) "
          "| miss change, median (cm) |")
    print("|---|---|---|---|---|---|")
    for r in res["decomposition"]:
        print(f"| {r['what']} | {r['a']} | {r['b']} | {r['tip_mm_median']:.2f} / {r['tip_mm_max']:.2f} | "
              f"{r['velocity_mm_s_median']:.1f} / {r['velocity_mm_s_max']:.1f} | {r['miss_change_cm_median']:.2f} |")
    fine = vs_fine_pyelastica(res)
    if fine:
        pe = res["models"][res["roles"]["pyelastica"]]["vs_elements"]
        print(f"\nAgainst PyElastica with {pe['n_elements']} elements (dt/2), on {pe['n_throws']} throws "
              "(the fastest first)\n")
        print("| model | release tip: median / max (mm) | along the swing, median (mm) | miss change, median (cm) |")
        print("|---|---|---|---|")
        for r in fine:
            print(f"| {r['model']} | {r['tip_mm_median']:.2f} / {r['tip_mm_max']:.2f} | "
                  f"{r['along_swing_mm_median']:.2f} | {r['miss_change_cm_median']:.2f} |")


def add_model_options(ap: argparse.ArgumentParser) -> None:
    """The options both transfer scripts share: the gvsjax models' bases and PyElastica's rod."""
    ap.add_argument("--modes", type=int, default=6, help="Legendre bending modes of the converged basis")
    ap.add_argument("--fine-modes", type=int, default=8, help="Legendre bending modes of the check of the basis")
    ap.add_argument("--ss-order", type=int, default=2, help="Legendre order of stretch and shear")
    ap.add_argument("--dt", type=float, default=1e-4, help="PyElastica step (s)")
    ap.add_argument("--elements", type=int, default=100)
    ap.add_argument("--check-elements", type=int, default=200, help="elements of the discretisation check (0: none)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", default="runs/basketball-default", help="run folder or checkpoint file")
    ap.add_argument("--n-targets", type=int, default=200, help=f"the first n of the {EVAL_N} evaluation targets")
    add_model_options(ap)
    ap.add_argument("--check-dt", type=int, default=20, help="throws rerun at dt/2 (0: none)")
    ap.add_argument("--no-step-check", action="store_true",
                    help="skip the 4x-steps check of models not yet in --json (it doubles their compile time)")
    ap.add_argument("--workers", type=int, default=1, help="PyElastica processes")
    ap.add_argument("--cache", default=os.path.join(ROOT, "benchmarks", "transfer_pyelastica_throws.json"))
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "transfer_pyelastica.json"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "figures", "transfer_pyelastica.png"))
    ap.add_argument("--replot", action="store_true", help="only redraw the figure and tables from --json")
    args = ap.parse_args()
    if args.replot:
        with open(args.json) as fh:
            res = json.load(fh)
    else:
        if args.n_targets > EVAL_N:
            ap.error(f"--n-targets must be <= {EVAL_N}")
        res = run(args)
        os.makedirs(os.path.dirname(args.json), exist_ok=True)
        with open(args.json, "w") as fh:
            json.dump(res, fh)
    plot(res, args.figure)
    print_tables(res)


if __name__ == "__main__":
    main()
