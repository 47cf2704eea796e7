"""Sim-to-sim transfer of the trained pick-and-place policy: gvsjax -> PyElastica.

The policy (trained on the task's model: ``paper_arm(tendon_offset=0.025)``, 2 monomial bending
modes, 5 Gauss points, 60 ``ars443`` steps per 5 s step) chooses both steps' actions for held-out
target pairs (the first ``--n-pairs`` of ``python -m gvsjax.evaluate``'s 1000: ``eval_targets`` of
seed 1_000_003), in its own closed loop on the task's model (``rollout``, the mean actions). The
same four numbers (theta_F, tension per step) are then replayed open-loop by other models of the
arm; the metric is the task's: the tip-to-target distance at the end of each step.

* ``gvsjax 2 modes``: the task's model, the training model;
* ``gvsjax 2 modes, 8 Gauss``: the same basis with finer quadrature;
* ``gvsjax K Legendre``: K Legendre bending modes (basis truncation; K = ``--modes``, checked
  against ``--fine-modes``);
* ``gvsjax K Legendre + stretch/shear``: in-plane stretch and shear active too (Legendre order
  ``--ss-order``), damped with eta (3A, A) (SoRoSim's convention), and a variant with them undamped
  as in PyElastica;
* ``PyElastica``: a shearable, extensible ``CosseratRod`` (``--elements``), position Verlet at
  ``--dt``, the base held and its frame turned by the task's cycloidal angle law
  (``bench_pyelastica.SwingingBase``), gravity, Kelvin-Voigt bending/torsion damping with gvsjax's
  law (``bench_pyelastica``'s ``KelvinVoigtDamper``), and the tendon (``TendonForce`` below).

The gvsjax models run through the task's ``motion.episode_distances`` (``episode``, ``run_step``)
with ``params.arm`` replaced (the transfer helpers of ``transfer_pyelastica.py`` build them), each
checked against itself at 4x the steps.

**The tendon in PyElastica.** A cable at ``offset`` from the midline in the bending plane (on the
side of gvsjax's local +y, i.e. -d2 of PyElastica's frame), anchored at the tip and sliding without
friction through a guide at every node. Its point at node i is p_i = x_i + offset e_i (e_i: -d2 of
the adjacent elements, averaged); with u_i the unit vector from p_i to p_{i+1}, it pulls node i by
T (u_i - u_{i-1}) and the tip by -T u_last, applied at p_i: the force on the node and the couple
(p_i - x_i) x F (split between the adjacent elements, in their material frames). Node 0 and
element 0 are held by the base. ``--validate`` checks it against the closed form (a straight rod
without gravity under a constant tension bends into an arc of curvature T offset / (E I), shortened
by T / (E A)) and against gvsjax's statics (``gv.equilibrium``) of the horizontal arm under gravity.

PyElastica episodes (both steps, 10 s of simulated time each) are cached one by one in ``--cache``
(a rerun resumes); a subset is rerun at ``--dt``/2 (``--check-dt``) and with ``--check-elements``
elements (at dt/2). ``--pause-file F``: while F exists, wait (polling every 20 s) before each model and episode.

    pip install pyelastica          # or pip install -e ".[bench]"
    python -m gvsjax.train task=pickplace out=runs/pp-default
    python experiments/transfer/transfer_pickplace_pyelastica.py --checkpoint runs/pp-default --validate
    python experiments/transfer/transfer_pickplace_pyelastica.py --replot

The PyElastica model, its episodes' cache and the tendon's validation are in
``pickplace_pyelastica.py``.

(The committed JSON: one run computed the tendon validation and the gvsjax models; the PyElastica
episodes, their checks and ``validate_elements`` ran in two processes side by side through this
script's functions, their caches merged; a last run read everything from the cache.)

Writes benchmarks/transfer_pickplace_pyelastica.json (summary and per-pair distances and tips),
benchmarks/transfer_pickplace_pyelastica_episodes.json (the cache) and
figures/transfer_pickplace_pyelastica.png.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[1] / "benchmarks"))  # bench_pyelastica
from pickplace_pyelastica import (  # this folder
    OFFSET,
    check_laws,
    pyelastica_episodes,
    pyelastica_tips,
    validate_elements,
    validate_tendon,
    wait_for,
)
from transfer_pyelastica import add_model_options, names, variants

import gvsjax  # noqa: F401  (configures JAX: XLA flag, x64, before any computation)
from gvsjax.ppo import load_policy
from gvsjax.ppo.checkpoint import make_policy, resolve
from gvsjax.tasks import pickplace as pp

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
EVAL_N, EVAL_SEED = 1000, 1_000_003  # python -m gvsjax.evaluate's pairs


# ----------------------------------------------------------------------------- gvsjax

def replay_fn(params):
    """``(actions (n, 2, 2), targets (n, 2, 2)) -> (tips (n, 2, 2), distances (n, 2))``: the actions
    replayed through the task's ``motion.episode_distances`` (both steps from rest, ``motion.run_step``)."""

    @jax.jit
    def run(actions, targets):
        d, tips = jax.vmap(lambda a, t: pp.episode_distances(params, a, t))(actions, targets)
        return tips, d

    return run


def summary(d: np.ndarray) -> list[dict]:
    return [pp.error_summary(d[:, k]) for k in range(2)]


# ----------------------------------------------------------------------------- the experiment

def save_json(res: dict, path: str) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(res, fh)
    os.replace(tmp, path)


def run(args) -> dict:
    wait_for(args.pause_file)
    config, env, params, net = load_policy(resolve(args.checkpoint))
    policy = make_policy(config, env.action_size, net)
    targets_all = pp.eval_targets(params, EVAL_N, EVAL_SEED)
    acts, tips_eval, d_eval, _ = (np.asarray(x) for x in jax.jit(lambda t: pp.rollout(params, policy, t))(
        jnp.asarray(targets_all)))
    n = args.n_pairs
    actions, targets = acts[:n], targets_all[:n]
    theta, tension = (np.asarray(x) for x in pp.action_to_physical(jnp.asarray(actions), params))
    idx = np.arange(n)
    out: dict = dict(checkpoint=str(resolve(args.checkpoint)), n_pairs=n, eval_seed=EVAL_SEED,
                     targets=targets.tolist(), actions=actions.tolist(), theta=theta.tolist(),
                     tension=tension.tolist(), eval_all=dict(step1=pp.error_summary(d_eval[:, 0]),
                                                             step2=pp.error_summary(d_eval[:, 1])),
                     laws_vs_task=check_laws(params, theta[0], tension[0]), models={})
    print(f"PyElastica's laws vs the task's controls: {out['laws_vs_task']:.2e}", flush=True)
    previous = {}
    if os.path.exists(args.json):
        with open(args.json) as fh:
            prev = json.load(fh)
        if prev.get("actions") == out["actions"]:
            previous = prev["models"]
            out["tendon_validation"] = prev.get("tendon_validation")
    if args.validate and not out.get("tendon_validation"):
        wait_for(args.pause_file)
        out["tendon_validation"] = validate_tendon(args)
        save_json(out, args.json)
    # --- gvsjax
    arm = dict(tendon_offset=OFFSET, tip_force=0.0)
    for name, robot in variants(args.modes, args.fine_modes, args.ss_order, args.elements, **arm).items():
        if name in previous and (previous[name].get("vs_4x_steps_tip_mm") or args.no_step_check):
            out["models"][name] = previous[name]
            print(f"{name}: from {args.json}", flush=True)
            continue
        wait_for(args.pause_file)
        p = params if robot is None else dataclasses.replace(params, arm=robot)
        t0 = time.perf_counter()
        tips, d = (np.asarray(x) for x in replay_fn(p)(jnp.asarray(actions), jnp.asarray(targets)))
        wall = time.perf_counter() - t0
        d = np.where(np.isfinite(d), d, np.inf)
        step_err = None
        if not args.no_step_check:
            fine = dataclasses.replace(p, n_steps=4 * p.n_steps)
            tips_f, _ = (np.asarray(x) for x in replay_fn(fine)(jnp.asarray(actions), jnp.asarray(targets)))
            step_err = [1e3 * float(np.max(np.linalg.norm(tips[:, k] - tips_f[:, k], axis=1))) for k in range(2)]
        link = p.arm.links[0]
        out["models"][name] = dict(tips=tips.tolist(), distance=d.tolist(), wall_s=wall, n_steps=p.n_steps,
                                   strain_dofs=link.basis.n_dofs, orders=list(link.basis.orders),
                                   n_gauss=link.n_gauss, vs_4x_steps_tip_mm=step_err, metrics=summary(d))
        if robot is None:
            out["task_vs_evaluate_m"] = float(np.max(np.abs(d - d_eval[:n])))
            print(f"  the task's replay vs its closed-loop evaluation: {out['task_vs_evaluate_m']:.1e} m")
        m = summary(d)
        print(f"{name}: median {100 * m[0]['median_m']:.2f} / {100 * m[1]['median_m']:.2f} cm; "
              f"4x steps: {step_err}", flush=True)
        save_json(out, args.json)  # a rerun reuses the models done
    # --- PyElastica
    eps = pyelastica_episodes(theta, tension, idx, args.dt, args.elements, args.cache, args.pause_file)
    tips, stable = pyelastica_tips(eps, idx)
    d = np.where(stable[:, None], np.linalg.norm(tips - targets, axis=2), np.inf)
    name = names(args.modes, args.fine_modes, args.elements)["pyelastica"]
    out["models"][name] = dict(tips=tips.tolist(), distance=d.tolist(), dt=args.dt,
                               wall_s=float(sum(eps[i]["wall_s"] for i in idx)),
                               max_stretch=float(max(eps[i]["stretch"] for i in idx)),
                               max_base_angle_error=float(max(eps[i]["base_angle_error"] for i in idx)),
                               metrics=summary(d))
    m = summary(d)
    print(f"{name}: median {100 * m[0]['median_m']:.2f} / {100 * m[1]['median_m']:.2f} cm", flush=True)
    if args.check_dt:
        change = np.abs(theta[:, 0]) + np.abs(theta[:, 1] - theta[:, 0])  # the fastest motions first
        order = np.argsort(-change)
        chk = np.unique(np.concatenate([order[: args.check_dt // 2], idx[:: max(1, n // (args.check_dt // 2))]]))
        half = pyelastica_episodes(theta, tension, chk, args.dt / 2, args.elements, args.cache, args.pause_file)
        t_half, _ = pyelastica_tips(half, chk)
        dd = np.linalg.norm(t_half - tips[chk], axis=2)
        out["models"][name]["vs_half_dt"] = dict(n_pairs=int(len(chk)), pairs=chk.tolist(), tips=t_half.tolist(),
                                                  tip_mm_max=[1e3 * float(np.max(dd[:, k])) for k in range(2)])
        print(f"  vs dt/2 on {len(chk)} pairs: {out['models'][name]['vs_half_dt']['tip_mm_max']} mm", flush=True)
        if args.check_elements:
            fine = pyelastica_episodes(theta, tension, chk, args.dt / 2, args.check_elements, args.cache,
                                       args.pause_file)
            t_fine, _ = pyelastica_tips(fine, chk)
            de = np.linalg.norm(t_fine - t_half, axis=2)
            out["models"][name]["vs_elements"] = dict(
                n_elements=args.check_elements, n_pairs=int(len(chk)), pairs=chk.tolist(), tips=t_fine.tolist(),
                tip_mm_median=[1e3 * float(np.median(de[:, k])) for k in range(2)],
                tip_mm_max=[1e3 * float(np.max(de[:, k])) for k in range(2)])
            n1, n2 = args.elements, args.check_elements
            out["models"][name]["vs_elements"]["extrapolated_tips"] = ((n2 * t_fine - n1 * t_half) / (n2 - n1)).tolist()
            print(f"  {args.check_elements} vs {args.elements} elements (dt/2): "
                  f"{out['models'][name]['vs_elements']['tip_mm_median']} mm (median)", flush=True)
    out["roles"] = names(args.modes, args.fine_modes, args.elements)
    out["decomposition"] = decomposition(out)
    if args.validate and args.check_elements and "elements" not in out["tendon_validation"]:
        save_json(out, args.json)
        wait_for(args.pause_file)
        out["tendon_validation"]["elements"] = validate_elements(args)
    return out


def _radial_tangential(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Components of a - b (n, 2) along b's radius (outwards) and along the circle (counter-clockwise)."""
    u = b / np.linalg.norm(b, axis=-1, keepdims=True)
    dv = a - b
    return np.sum(dv * u, -1), dv[..., 1] * u[..., 0] - dv[..., 0] * u[..., 1]


def decomposition(out: dict) -> list[dict]:
    """End-of-step tip differences between pairs of models (median / max over the pairs), per step."""
    r = out["roles"]
    pairs = [("quadrature", "task", "gauss8"), ("basis truncation", "task", "bend"),
             ("basis convergence", "bend", "bend_fine"), ("stretch/shear", "bend", "ss"),
             ("stretch/shear damping", "ss", "ss_undamped"), ("the rest", "ss", "pyelastica"),
             ("the rest (undamped stretch/shear)", "ss_undamped", "pyelastica"),
             ("bending only vs PyElastica", "bend", "pyelastica"), ("total", "task", "pyelastica")]
    rows = []
    for what, a, b in pairs:
        if r[a] not in out["models"] or r[b] not in out["models"]:
            continue
        A, B = out["models"][r[a]], out["models"][r[b]]
        for k in range(2):
            ta, tb = np.array(A["tips"])[:, k], np.array(B["tips"])[:, k]
            dp = np.linalg.norm(tb - ta, axis=1)
            rad, tan = _radial_tangential(tb, ta)
            dd = np.array(B["distance"])[:, k] - np.array(A["distance"])[:, k]
            rows.append(dict(what=what, a=r[a], b=r[b], step=k + 1, tip_mm_median=1e3 * float(np.median(dp)),
                             tip_mm_max=1e3 * float(np.max(dp)), radial_mm_median=1e3 * float(np.median(rad)),
                             radial_abs_mm_median=1e3 * float(np.median(np.abs(rad))),
                             tangential_abs_mm_median=1e3 * float(np.median(np.abs(tan))),
                             distance_change_cm_median=1e2 * float(np.median(dd))))
    return rows


# ----------------------------------------------------------------------------- output

def plot(res: dict, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models, r = res["models"], res["roles"]
    targets = np.array(res["targets"])
    fig, axes = plt.subplots(2, 2, figsize=(13, 9.5))
    shown = [("task", "-", "C0"), ("gauss8", ":", "C4"), ("bend", "--", "C2"), ("ss", "-.", "C1"),
             ("ss_undamped", ":", "C3"), ("pyelastica", "-", "k")]
    for k in range(2):
        ax = axes[0, k]
        for role, ls, c in shown:
            if r[role] not in models:
                continue
            d = np.sort(np.array(models[r[role]]["distance"])[:, k])
            med = 100 * np.median(d)
            ax.plot(100 * d, np.arange(1, len(d) + 1) / len(d) * 100, ls, color=c, lw=1.6,
                    label=f"{r[role]}: median {med:.2f} cm")
        ax.set_xscale("log")
        ax.set_xlabel(f"step {k + 1}: tip-to-target distance (cm)")
        ax.set_ylabel(f"pairs with a smaller distance (%, of {res['n_pairs']})")
        ax.set_title(f"({'ab'[k]}) step {k + 1} ({'pick' if k == 0 else 'place'}): CDF of the distance", fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="upper left")
        bx = axes[1, k]
        pe = np.array(models[r["pyelastica"]]["tips"])[:, k]
        ang = np.degrees(np.arctan2(targets[:, k, 0], -targets[:, k, 1]))
        K = r["bend"].split()[1]
        short = {"task": "gvsjax 2 modes (task)", "bend": f"gvsjax {K} Legendre",
                 "ss": f"gvsjax {K} Leg. + stretch/shear", "ss_undamped": "the same, undamped"}
        for role, mk, c in (("task", "o", "C0"), ("bend", "s", "C2"), ("ss", "^", "C1"), ("ss_undamped", "v", "C3")):
            if r[role] not in models:
                continue
            tips = np.array(models[r[role]]["tips"])[:, k]
            bx.plot(ang, 1e3 * np.linalg.norm(tips - pe, axis=1), mk, ms=3.5, color=c, mfc="none",
                    label=short[role])
        chk = models[r["pyelastica"]].get("vs_elements")
        if chk:
            j = np.array(chk["pairs"])
            n1 = r["pyelastica"].split()[1]
            bx.plot(ang[j], 1e3 * np.linalg.norm(np.array(chk["tips"])[:, k] - pe[j], axis=1), "kx", ms=7, mew=1.5,
                    label=f"PyElastica {chk['n_elements']} (dt/2) vs {n1} el.")
            if r["ss"] in models and "extrapolated_tips" in chk:
                ss = np.array(models[r["ss"]]["tips"])[j, k]
                bx.plot(ang[j], 1e3 * np.linalg.norm(ss - np.array(chk["extrapolated_tips"])[:, k], axis=1), "P",
                        ms=7, color="C1", label=f"{short['ss']} vs PyElastica extrap.")
        bx.set_yscale("log")
        bx.set_xlabel(f"step {k + 1} target's angle from hanging (deg)")
        bx.set_ylabel("end-of-step tip difference (mm)")
        bx.set_title(f"({'cd'[k]}) step {k + 1}: tip differences per pair, from PyElastica "
                     f"{r['pyelastica'].split()[1]} elements unless marked", fontsize=10)
        bx.grid(alpha=0.3, which="both")
        bx.legend(fontsize=7, loc="upper center", ncol=2)
        lo, hi = bx.get_ylim()
        bx.set_ylim(lo, hi * 60)  # room for the legend above the points
    fig.tight_layout()
    os.makedirs(os.path.dirname(out), exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def print_tables(res: dict) -> None:
    models, r = res["models"], res["roles"]
    pe = np.array(models[r["pyelastica"]]["tips"])
    print(f"\n{res['n_pairs']} held-out pairs (seed {res['eval_seed']}), the policy's actions replayed in each model\n")
    print("| model | strain DoFs | step | median | p95 | max | < 2 cm | tip vs PyElastica: median / max (mm) "
          "| own time error (mm) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, m in models.items():
        for k in range(2):
            s = m["metrics"][k]
            dp = np.linalg.norm(np.array(m["tips"])[:, k] - pe[:, k], axis=1)
            err = m.get("vs_4x_steps_tip_mm")
            e = f"{err[k]:.3f} (4x steps)" if err else ""
            if "vs_half_dt" in m:
                e = f"{m['vs_half_dt']['tip_mm_max'][k]:.3f} (dt/2, {m['vs_half_dt']['n_pairs']} pairs)"
            print(f"| {name} | {m.get('strain_dofs', '')} | {k + 1} | {100 * s['median_m']:.2f} cm | "
                  f"{100 * s['p95_m']:.2f} cm | {100 * s['max_m']:.2f} cm | {100 * s['within_2cm']:.0f}% | "
                  f"{1e3 * np.median(dp):.2f} / {1e3 * np.max(dp):.2f} | {e} |")
    print("\n| what | from | to | step | tip: median / max (mm) | radial: median, median abs (mm) "
          "| along the circle: median abs (mm) | distance change, median (cm) |")
    print("|---|---|---|---|---|---|---|---|")
    for x in res["decomposition"]:
        print(f"| {x['what']} | {x['a']} | {x['b']} | {x['step']} | {x['tip_mm_median']:.2f} / {x['tip_mm_max']:.2f} "
              f"| {x['radial_mm_median']:+.2f}, {x['radial_abs_mm_median']:.2f} | "
              f"{x['tangential_abs_mm_median']:.2f} | {x['distance_change_cm_median']:+.2f} |")
    pm = models[r["pyelastica"]]
    if "vs_elements" in pm:
        v = pm["vs_elements"]
        chk = np.array(v["pairs"])
        fine, extra = np.array(v["tips"]), np.array(v["extrapolated_tips"])
        print(f"\nAgainst PyElastica with {v['n_elements']} elements (dt/2) and extrapolated in the element count "
              f"((n2 P_n2 - n1 P_n1) / (n2 - n1)), on {v['n_pairs']} pairs (end-of-step tip, median / max, mm)\n")
        print(f"| model | step 1 vs {v['n_elements']} | step 2 vs {v['n_elements']} | step 1 vs extrapolated "
              "| step 2 vs extrapolated |")
        print("|---|---|---|---|---|")
        for name, m in models.items():
            cells = []
            for ref in (fine, extra):
                dp = np.linalg.norm(np.array(m["tips"])[chk] - ref, axis=2)
                cells += [f"{1e3 * np.median(dp[:, k]):.2f} / {1e3 * np.max(dp[:, k]):.2f}" for k in range(2)]
            print(f"| {name} | {' | '.join(cells[:2] + cells[2:])} |")
        print(f"\nPyElastica max element stretch {pm['max_stretch']:.2e}, base angle error "
              f"{pm['max_base_angle_error']:.1e} rad")
    tv = res.get("tendon_validation")
    if tv:
        print("\nTendon validation (tip, mm)\n")
        for c in tv["cases"]:
            print({k: (np.round(np.array(v) * 1e3, 3).tolist() if isinstance(v, list) and k != "converged" else v)
                   for k, v in c.items()})
        print(tv["tendon_effect_horizontal"])
        if "elements" in tv:
            print(tv["elements"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", default="runs/pp-default", help="run folder or checkpoint file")
    ap.add_argument("--n-pairs", type=int, default=100, help=f"the first n of the {EVAL_N} evaluation pairs")
    add_model_options(ap)
    ap.add_argument("--check-dt", type=int, default=6, help="pairs rerun at dt/2 (about; 0: none)")
    ap.add_argument("--no-step-check", action="store_true", help="skip the gvsjax models' 4x-steps check")
    ap.add_argument("--validate", action="store_true", help="validate PyElastica's tendon first (statics)")
    ap.add_argument("--pause-file", default=None, help="wait before each model and episode while this file exists")
    ap.add_argument("--cache", default=os.path.join(ROOT, "benchmarks", "transfer_pickplace_pyelastica_episodes.json"))
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "transfer_pickplace_pyelastica.json"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "figures", "transfer_pickplace_pyelastica.png"))
    ap.add_argument("--replot", action="store_true", help="only redraw the figure and tables from --json")
    args = ap.parse_args()
    if args.replot:
        with open(args.json) as fh:
            res = json.load(fh)
    else:
        if not 0 < args.n_pairs <= EVAL_N:
            ap.error(f"--n-pairs must be in 1..{EVAL_N}")
        res = run(args)
        save_json(res, args.json)
    plot(res, args.figure)
    print_tables(res)


if __name__ == "__main__":
    main()
