"""Closing the model gap without training again: identify E and eta, then correct the policy's throws.

**Identification.** Young's modulus E and the Kelvin-Voigt damping eta of the paper's arm are
fitted (``gv.fit_parameters``: Levenberg-Marquardt in log space, the Jacobian by ``jax.jacfwd``
through the task's own swing, ``basketball.swing``) so that gvsjax's tip path matches observed
tip paths: x-y at 20 times up to release of a few throws (``THROWS``). The observations:

* ``pyelastica``: PyElastica throws (``bench_pyelastica.pyelastica_throw``, 100 shearable
  elements) of an arm with E x ``--true-E`` and damping x ``--true-eta`` (the "real" arm);
* ``pyelastica nominal``: the same with the paper's E and eta (what gvsjax "identifies" there is
  its model-form bias);
* ``gvsjax``: gvsjax's task model (2 modes) at the true factors, at 4x the steps (a check, and the
  identified values used by the correction below).

Each is fitted with the task's 2-mode arm and a converged 6-mode Legendre arm (``--ss`` adds the
Legendre arm with in-plane stretch and shear, the strains PyElastica's rod has). Reported per fit:
the values against the truth, the tip residual (rms) at the nominal values, at the true values
(what no parameter can remove: the model-form error) and at the fitted ones.

**Correction.** The trained policy chooses (T, delta) for the evaluation's held-out targets
(``reset`` keys of seed 1_000_003, as ``python -m gvsjax.evaluate``); the true arm is gvsjax's task
model with E and eta at the true factors. Each action is refined by ``--gn-iters`` line-searched
Gauss-Newton steps on the miss (``basketball.baseline.gauss_newton``: the task's ``throw_cost``,
differentiated through the simulator) in a model with (a) the nominal, (b) the identified and (c)
the true parameters, and the refined action is thrown on the true arm (``Basketball.step``).

    pip install pyelastica          # or pip install -e ".[bench]"
    python experiments/transfer/identify_and_correct.py --checkpoint runs/bb-ident
    python experiments/transfer/identify_and_correct.py --checkpoint runs/bb-ident --reuse-fits --pyelastica-targets 100
    python experiments/transfer/identify_and_correct.py --replot

``--reuse-fits`` keeps the fits and the correction already in ``--json`` (delete its "correct" entry to
redo the correction, e.g. for another checkpoint); ``--no-legendre`` fits only the task's 2-mode model.

``--pyelastica-targets N`` also throws the first N targets in PyElastica's true arm: the policy's
actions and those refined (in gvsjax's 2-mode model) with the nominal, the true and the parameters
the 2-mode model identified from the PyElastica throws; ``--legendre-correction`` adds those N actions
refined in the 6-mode Legendre arm (with its PyElastica fit and with the true parameters; this
refinement compiles for ~30 min and ~17 GB).

Writes benchmarks/identify_and_correct.json, benchmarks/identify_pyelastica_throws.json (the
PyElastica throws, reused by a rerun) and figures/identify_and_correct.png. Differentiating the
ars443 swing compiles for minutes; ``--jit-cache`` keeps the programs for a rerun.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation
from gvsjax.core.model import StrainBasis
from gvsjax.tasks import basketball as bb
from gvsjax.tasks.basketball.baseline import gauss_newton

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.append(os.path.join(ROOT, "experiments", "benchmarks"))  # bench_pyelastica, in the benchmarks folder
E0, ETA0 = gv.PAPER_ARM["youngs_modulus"], gv.PAPER_ARM["damping"]
EVAL_N, EVAL_SEED = 1000, 1_000_003  # python -m gvsjax.evaluate's targets for a seed-0 run
# (T s, delta): a fast, two middle and a slow swing; the fast ones carry the damping
THROWS = ((0.7, 0.95), (1.0, 0.9), (1.6, 0.92), (2.5, 0.9))
N_SAMPLES = 20  # tip samples per throw, uniform in time up to release


# ----------------------------------------------------------------------------- models

def arm(kind: str, E, eta):
    """The arm of model ``kind`` with Young's modulus E and damping eta (may be traced)."""
    base = dict(tip_force=bb.BALL_WEIGHT, youngs_modulus=E, damping=eta)
    if kind == "2 modes":
        return gv.paper_arm(**base)
    robot = gv.paper_arm(**base, n_modes=6, n_gauss=8, basis="legendre")
    if kind == "6 Legendre":
        return robot
    assert kind == "6 Legendre + stretch/shear", kind
    basis = StrainBasis(orders=(-1, -1, 5, 2, 2, -1), kind="legendre")  # as transfer_pyelastica.py
    return robot.replace(links=(robot.links[0].replace(basis=basis),))


def tip_paths(kind: str, p: dict, n_steps: int = 40):
    """(len(THROWS), N_SAMPLES, 2) tip x-y of the task's swing (40 ars443 steps by default)."""
    params = bb.BasketballParams(arm=arm(kind, p["E"], p["eta"]))
    T, delta = (jnp.array(x) for x in zip(*THROWS))
    swing = lambda T, d: bb.swing(params, T, d, n_steps=n_steps, save_every=n_steps // N_SAMPLES)  # noqa: E731
    return jax.vmap(lambda T, d: swing(T, d).tip[1:, :2])(T, delta)


def pyelastica_paths(E_factor: float, eta_factor: float, cache_path: str) -> np.ndarray:
    """The same samples from PyElastica throws (cached), linearly interpolated from every step."""
    from bench_pyelastica import pyelastica_throw

    cache = json.load(open(cache_path)) if os.path.exists(cache_path) else {}
    out = []
    for T, delta in THROWS:
        key = f"{T}|{delta}|{E_factor}|{eta_factor}"
        if key not in cache:
            t0 = time.perf_counter()
            r = pyelastica_throw(T, delta, 1e-4, 100, record_every=1, youngs_modulus=E0 * E_factor,
                                 eta=ETA0 * eta_factor)
            t = r["dt"] * (np.arange(r["n_steps"]) + 1.0)  # the path is recorded after every step
            ts = delta * T * np.arange(1, N_SAMPLES + 1) / N_SAMPLES
            cache[key] = [[float(np.interp(s, t, r["path"][:, i])) for i in range(2)] for s in ts]
            print(f"PyElastica T={T} delta={delta} E x{E_factor} eta x{eta_factor}: "
                  f"{time.perf_counter() - t0:.1f} s", flush=True)
            with open(cache_path, "w") as fh:
                json.dump(cache, fh)
        out.append(cache[key])
    return np.array(out)


# ----------------------------------------------------------------------------- identification

def identify(args, kinds: list[str], done: dict | None = None) -> dict:
    truth = {"E": E0 * args.true_E, "eta": ETA0 * args.true_eta}
    nominal = {"E": E0, "eta": ETA0}
    data = {
        "pyelastica": (pyelastica_paths(args.true_E, args.true_eta, args.cache), truth),
        "pyelastica nominal": (pyelastica_paths(1.0, 1.0, args.cache), nominal),
        "gvsjax": (np.asarray(jax.jit(lambda p: tip_paths("2 modes", p, 160))(truth)), truth),
    }
    fits = list(done["fits"]) if done else []
    for kind in kinds:
        if any(f["model"] == kind for f in fits):
            continue
        fit_fn = jax.jit(lambda obs, kind=kind: gv.fit_parameters(lambda p: tip_paths(kind, p), obs, nominal,
                                                                   n_iters=args.fit_iters))
        paths = jax.jit(lambda p, kind=kind: tip_paths(kind, p))
        for name, (obs, true) in data.items():
            if name == "gvsjax" and kind != "2 modes":
                continue
            t0 = time.perf_counter()
            fit = fit_fn(jnp.asarray(obs))
            jax.block_until_ready(fit.cost)
            wall = time.perf_counter() - t0

            def rms(p, paths=paths, obs=obs):
                return float(np.sqrt(np.mean(np.sum((np.asarray(paths(p)) - obs) ** 2, -1))))

            row = dict(model=kind, data=name, truth={k: float(v) for k, v in true.items()},
                       values={k: float(v) for k, v in fit.values.items()},
                       relative_error={k: float(fit.values[k]) / true[k] - 1.0 for k in true},
                       history={k: np.asarray(v).tolist() for k, v in fit.history.items()},
                       cost=np.asarray(fit.cost).tolist(), log_std=np.asarray(fit.log_std).tolist(),
                       correlation=float(fit.correlation[0, 1]),
                       rms_nominal_m=rms(nominal), rms_truth_m=rms(true), rms_fit_m=rms(fit.values),
                       max_fit_m=float(np.max(np.linalg.norm(np.asarray(paths(fit.values)) - obs, axis=-1))),
                       wall_s=wall)
            fits.append(row)
            print(f"{kind} on {name}: E {row['relative_error']['E']:+.2%}, eta {row['relative_error']['eta']:+.2%} "
                  f"vs truth; rms {1e3 * row['rms_nominal_m']:.2f} (nominal) / {1e3 * row['rms_truth_m']:.2f} "
                  f"(truth) / {1e3 * row['rms_fit_m']:.2f} mm (fit); {wall:.0f} s", flush=True)
    return dict(throws=THROWS, n_samples=N_SAMPLES, true_factors=dict(E=args.true_E, eta=args.true_eta),
                fit_iters=args.fit_iters, fits=fits)


# ----------------------------------------------------------------------------- correction

def correct(args, ident: dict) -> dict:
    from gvsjax.ppo import load_policy
    from gvsjax.ppo.checkpoint import make_policy, resolve

    config, env, params, net = load_policy(resolve(args.checkpoint))
    policy = make_policy(config, env.action_size, net)
    keys = jax.random.split(jax.random.PRNGKey(EVAL_SEED), EVAL_N)[: args.n_targets]
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    actions = jax.jit(policy)(obs)
    targets = state.target
    fit = next(f for f in ident["fits"] if f["model"] == "2 modes" and f["data"] == "gvsjax")
    models = {"nominal": (E0, ETA0), "identified": (fit["values"]["E"], fit["values"]["eta"]),
              "true": (E0 * args.true_E, ETA0 * args.true_eta)}
    with_arm = lambda E, eta: dataclasses.replace(params, arm=arm("2 modes", E, eta))  # noqa: E731
    true_params = with_arm(*models["true"])

    @jax.jit
    def thrown(p, actions):  # the task's step: the miss on the arm p, inf where not valid
        st = bb.BasketballState(target=targets, source_action=actions, step=jnp.zeros(len(keys), jnp.int32))
        _, _, _, _, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, st, actions, p)
        return jnp.where(info["valid"], info["cost"], jnp.inf)

    refine = jax.jit(lambda p, a: gauss_newton(p, a, targets, args.gn_iters))
    out = {"policy on the nominal arm": bb.miss_metrics(np.asarray(thrown(params, actions))),
           "policy on the true arm": bb.miss_metrics(np.asarray(thrown(true_params, actions)))}
    misses = {"policy": np.asarray(thrown(true_params, actions))}
    refined = {"policy": np.asarray(actions)}
    timing = {}
    for name, (E, eta) in models.items():
        t0 = time.perf_counter()
        a, model_miss = jax.block_until_ready(refine(with_arm(E, eta), actions))
        timing[name] = time.perf_counter() - t0
        m = np.asarray(thrown(true_params, a))
        misses[name] = m
        refined[name] = np.asarray(a)
        out[f"corrected with {name} parameters"] = dict(
            **bb.miss_metrics(m), model_median_m=float(np.median(np.asarray(model_miss))),
            action_change_median=float(np.median(np.linalg.norm(np.asarray(a - actions), axis=-1))))
        print(f"corrected with {name} ({E:.4g}, {eta:.4g}): {env.summary(bb.miss_metrics(m))}; "
              f"{timing[name]:.1f} s", flush=True)
    t0 = time.perf_counter()
    jax.block_until_ready(refine(with_arm(*models["nominal"]), actions))
    batch_s = time.perf_counter() - t0
    pe = None
    if args.pyelastica_targets:
        # the "real" arm is PyElastica's: correct with what the 2-mode model identified from its throws
        pfit = next(f for f in ident["fits"] if f["model"] == "2 modes" and f["data"] == "pyelastica")
        sets = {k: refined[k] for k in ("policy", "nominal", "true")}
        sets["identified"] = np.asarray(refine(with_arm(pfit["values"]["E"], pfit["values"]["eta"]), actions)[0])
        pe = pyelastica_correction(args, np.asarray(targets), sets, params)
    return dict(pyelastica=pe,
                checkpoint=str(resolve(args.checkpoint)), n_targets=args.n_targets, gn_iters=args.gn_iters,
                models={k: dict(E=v[0], eta=v[1]) for k, v in models.items()}, metrics=out,
                first_call_s=timing, batch_s=batch_s, per_target_ms=1e3 * batch_s / args.n_targets,
                misses={k: v.tolist() for k, v in misses.items()})


def legendre_correction(args, res: dict) -> None:
    """The first ``--pyelastica-targets`` actions refined instead in the 6-mode Legendre arm (the
    converged bending basis), with the parameters it identified from the PyElastica throws and with
    the true ones, and thrown in PyElastica's true arm; added to ``res["correct"]["pyelastica"]``."""
    from gvsjax.ppo import load_policy
    from gvsjax.ppo.checkpoint import make_policy, resolve

    pe = res["correct"]["pyelastica"]
    n = pe["n_targets"]
    config, env, params, net = load_policy(resolve(args.checkpoint))
    policy = make_policy(config, env.action_size, net)
    keys = jax.random.split(jax.random.PRNGKey(EVAL_SEED), EVAL_N)[:n]
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    actions = jax.jit(policy)(obs)
    pfit = next(f for f in res["identify"]["fits"] if f["model"] == "6 Legendre" and f["data"] == "pyelastica")
    models = {"identified, 6 Legendre": (pfit["values"]["E"], pfit["values"]["eta"]),
              "true, 6 Legendre": (E0 * args.true_E, ETA0 * args.true_eta)}
    refine = jax.jit(lambda p, a: gauss_newton(p, a, state.target, args.gn_iters))
    sets, timing = {}, {}
    for name, (E, eta) in models.items():
        t0 = time.perf_counter()
        a, model_miss = jax.block_until_ready(refine(dataclasses.replace(params, arm=arm("6 Legendre", E, eta)),
                                                     actions))
        timing[name] = time.perf_counter() - t0
        sets[name] = np.asarray(a)
        print(f"refined in 6 Legendre modes, {name}: model miss median "
              f"{100 * np.median(np.asarray(model_miss)):.3f} cm; {timing[name]:.1f} s", flush=True)
    out = pyelastica_correction(args, np.asarray(state.target), sets, params)
    pe["throws"].update(out["throws"])
    pe["legendre_refine_s"] = timing


def pyelastica_correction(args, targets: np.ndarray, actions: dict, params) -> dict:
    """The first ``--pyelastica-targets`` targets thrown in PyElastica's true arm, for each action
    set (the policy's; refined with nominal, identified (from PyElastica) and true parameters in
    gvsjax's 2-mode model). Releases are cached; the flight and the miss are the task's."""
    from bench_pyelastica import is_stable, pyelastica_throw

    cache = json.load(open(args.cache)) if os.path.exists(args.cache) else {}
    n, out = args.pyelastica_targets, {}
    t_start = time.perf_counter()
    for name, a in actions.items():
        T, delta = (np.asarray(x) for x in bb.action_to_physical(jnp.asarray(a[:n]), params))
        p0, v0, ok = [], [], []
        for Ti, di in zip(T, delta):
            key = f"release|{Ti!r}|{di!r}|{args.true_E}|{args.true_eta}"
            if key not in cache:
                r = pyelastica_throw(float(Ti), float(di), 1e-4, 100, youngs_modulus=E0 * args.true_E,
                                     eta=ETA0 * args.true_eta)
                cache[key] = dict(tip=r["tip"][:2].tolist(), tip_velocity=r["tip_velocity"][:2].tolist(),
                                  stable=is_stable(r))
                if time.perf_counter() - t_start > 30:
                    with open(args.cache, "w") as fh:
                        json.dump(cache, fh)
                    t_start = time.perf_counter()
            p0.append(cache[key]["tip"])
            v0.append(cache[key]["tip_velocity"])
            ok.append(cache[key]["stable"])
        p0, v0 = jnp.asarray(p0), jnp.asarray(v0)
        miss, _ = bb.closest_approach(p0, v0, jnp.asarray(targets[:n]), params.g,
                                      bb.floor_time(p0, v0, params.g, params.y_floor))
        m = np.where(np.array(ok) & np.isfinite(np.asarray(miss)), np.asarray(miss), np.inf)
        out[name] = dict(metrics=bb.miss_metrics(m), misses=m.tolist())
        print(f"PyElastica, {name}: {bb.Basketball().summary(bb.miss_metrics(m))}", flush=True)
    with open(args.cache, "w") as fh:
        json.dump(cache, fh)
    return dict(n_targets=n, true_factors=dict(E=args.true_E, eta=args.true_eta), throws=out)


# ----------------------------------------------------------------------------- report

def plot(res: dict, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = res.get("correct")
    pe = c.get("pyelastica") if c else None
    fig, axes = plt.subplots(1, 4 if pe else 3, figsize=(21.5 if pe else 16, 4.2))
    styles = {"2 modes": "-", "6 Legendre": "--", "6 Legendre + stretch/shear": ":"}
    colors = {"pyelastica": "C0", "pyelastica nominal": "C1", "gvsjax": "C2"}
    for f in res["identify"]["fits"]:
        it = np.arange(len(f["cost"]))
        for ax, k in zip(axes[:2], ("E", "eta")):
            ax.plot(it, 100 * (np.array(f["history"][k]) / f["truth"][k] - 1.0), styles[f["model"]], marker="o",
                    ms=3, color=colors[f["data"]], label=f"{f['model']} on {f['data']}")
    for ax, k in zip(axes[:2], ("Young's modulus E", "damping eta")):
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set(xlabel="Levenberg-Marquardt step", ylabel=f"{k}: error vs the truth (%)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[0].set_title(f"identification from {len(res['identify']['throws'])} throws' tip paths", fontsize=9)
    f = res["identify"]["true_factors"]
    if not c:
        axes[2].axis("off")
    panels = [(axes[2], {k: m for k, m in c["misses"].items()}, c["n_targets"], "gvsjax (2 modes)")] if c else []
    if pe:
        panels.append((axes[3], {k: v["misses"] for k, v in pe["throws"].items()}, pe["n_targets"],
                       "PyElastica (100 elements)"))
    set_colors = {"policy": "C0", "nominal": "C1", "identified": "C2", "true": "C3"}
    for ax, misses, n, what in panels:
        names = [k for k in set_colors if k in misses] + [f"{k}, 6 Legendre" for k in set_colors
                                                            if f"{k}, 6 Legendre" in misses]
        for name in names:  # the same order and colour in each panel; dashed: refined in 6 Legendre modes
            m = np.sort(np.asarray(misses[name], float))
            base = name.split(",")[0]
            label = "policy alone" if name == "policy" else f"+ Gauss-Newton, {base} parameters"
            if base == "identified":
                label += "\n  (from the true arm's throws)"
            if name != base:
                label = label.replace("Gauss-Newton,", "Gauss-Newton in 6 Legendre modes,")
            ax.plot(100 * m, 100 * np.arange(1, len(m) + 1) / len(m), "--" if name != base else "-",
                    label=label, color=set_colors[base])
        for x in (1.0, 10.0):
            ax.axvline(x, color="0.6", lw=0.8, ls=":")
        ax.set(xscale="log", xlabel="miss on the true arm (cm)", ylabel=f"targets (%, of {n})")
        dashed = any("6 Legendre" in k for k in misses)
        ax.set_title(f"true arm: {what}, E x{f['E']}, eta x{f['eta']}; {c['gn_iters']} Gauss-Newton steps\n"
                     "in gvsjax's 2-mode model" + (" (dashed: 6 Legendre modes)" if dashed else ""), fontsize=8)
        ax.grid(alpha=0.3)
    # one legend (the same sets and colours in both panels), right of the last panel: it covers no curve
    if panels:
        panels[-1][0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.tight_layout()
    os.makedirs(os.path.dirname(out), exist_ok=True)
    fig.savefig(out, dpi=130, bbox_inches="tight")
    plt.close(fig)


def print_tables(res: dict) -> None:
    print("\n| model | data | E: fit (truth) | eta: fit (truth) | rms nominal | rms truth | rms fit | max fit |")
    print("|---|---|---|---|---|---|---|---|")
    for f in res["identify"]["fits"]:
        v, t, e = f["values"], f["truth"], f["relative_error"]
        print(f"| {f['model']} | {f['data']} | {v['E'] / 1e6:.3f} MPa ({t['E'] / 1e6:.2f}; {e['E']:+.1%}) | "
              f"{v['eta'] / 1e3:.1f} kPa s ({t['eta'] / 1e3:.0f}; {e['eta']:+.1%}) | "
              f"{1e3 * f['rms_nominal_m']:.2f} mm | {1e3 * f['rms_truth_m']:.2f} mm | "
              f"{1e3 * f['rms_fit_m']:.2f} mm | {1e3 * f['max_fit_m']:.2f} mm |")
    c = res.get("correct")
    if c:
        print(f"\n{c['n_targets']} held-out targets, {c['gn_iters']} Gauss-Newton steps, "
              f"{c['per_target_ms']:.2f} ms per target in a batch\n")
        print("| throws | < 10 cm | < 1 cm | median | p95 | max |")
        print("|---|---|---|---|---|---|")
        for name, m in c["metrics"].items():
            print(f"| {name} | {100 * m['success_rate_10cm']:.1f}% | {100 * m['within_1cm']:.1f}% | "
                  f"{100 * m['median_m']:.2f} cm | {100 * m['p95_m']:.2f} cm | {100 * m['max_m']:.2f} cm |")
        pe = c.get("pyelastica")
        if pe:
            print(f"\nPyElastica true arm, first {pe['n_targets']} targets\n")
            for name, v in pe["throws"].items():
                m = v["metrics"]
                print(f"| {name} | {100 * m['success_rate_10cm']:.1f}% | {100 * m['within_1cm']:.1f}% | "
                      f"{100 * m['median_m']:.2f} cm | {100 * m['p95_m']:.2f} cm | {100 * m['max_m']:.2f} cm |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", default="runs/basketball-default", help="run folder or checkpoint file")
    ap.add_argument("--true-E", type=float, default=1.1, help="the true arm's E, times the nominal")
    ap.add_argument("--true-eta", type=float, default=0.8, help="the true arm's damping, times the nominal")
    ap.add_argument("--fit-iters", type=int, default=8)
    ap.add_argument("--gn-iters", type=int, default=4)
    ap.add_argument("--n-targets", type=int, default=1000)
    ap.add_argument("--pyelastica-targets", type=int, default=0,
                    help="also throw the first N targets' actions in PyElastica's true arm")
    ap.add_argument("--ss", action="store_true", help="also fit the Legendre arm with stretch and shear")
    ap.add_argument("--no-legendre", action="store_true",
                    help="fit only the task's 2-mode model (the Legendre arm's differentiated swing compiles longest)")
    ap.add_argument("--skip-correction", action="store_true")
    ap.add_argument("--legendre-correction", action="store_true",
                    help="also refine the PyElastica targets' actions in the 6-mode Legendre arm (with its "
                         "parameters identified from PyElastica and the true ones) and throw them in PyElastica")
    ap.add_argument("--reuse-fits", action="store_true",
                    help="keep the fits and the correction already in --json (compute only what is missing)")
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "identify_and_correct.json"))
    ap.add_argument("--cache", default=os.path.join(ROOT, "benchmarks", "identify_pyelastica_throws.json"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "figures", "identify_and_correct.png"))
    ap.add_argument("--jit-cache", default=os.path.join(ROOT, "runs", "jit-cache"),
                    help="JAX's persistent compilation cache ('' for none)")
    ap.add_argument("--replot", action="store_true", help="only the figure and tables from --json")
    args = ap.parse_args()
    if args.replot:
        with open(args.json) as fh:
            res = json.load(fh)
    else:
        if args.jit_cache:
            jax.config.update("jax_compilation_cache_dir", args.jit_cache)
            jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
        res = json.load(open(args.json)) if os.path.exists(args.json) and args.reuse_fits else {}
        res["jax"] = jax.__version__
        # the task's model first: the correction needs only its fits; the Legendre arm compiles longest
        legendre = [] if args.no_legendre else ["6 Legendre"] + (["6 Legendre + stretch/shear"] if args.ss else [])
        for kinds in (["2 modes"], ["2 modes"] + legendre):
            res["identify"] = identify(args, kinds, res.get("identify"))
            with open(args.json, "w") as fh:
                json.dump(res, fh, indent=1)
            if not args.skip_correction and "correct" not in res:
                res["correct"] = correct(args, res["identify"])
                with open(args.json, "w") as fh:
                    json.dump(res, fh, indent=1)
        pe = (res.get("correct") or {}).get("pyelastica")
        if args.legendre_correction and pe and "identified, 6 Legendre" not in pe["throws"]:
            legendre_correction(args, res)
            with open(args.json, "w") as fh:
                json.dump(res, fh, indent=1)
    plot(res, args.figure)
    print_tables(res)


if __name__ == "__main__":
    main()
