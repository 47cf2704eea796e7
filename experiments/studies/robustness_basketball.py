"""Robustness of a trained basketball policy to model error.

The policy was trained on the nominal model (``gv.paper_arm(tip_force=5.886)``). Here the
*evaluation* model differs from it in one physical parameter at a time, swept over a range:

* Young's modulus E (nominal 5 MPa): +-30 %;
* material damping eta (nominal 1e5 Pa s, SoRoSim's convention): +-30 %;
* ball mass (nominal 0.6 kg): +-20 %. In the task the ball is not an inertia but a constant
  tip force, its weight m g = 5.886 N until release; the mass enters only through it;
* arm length (nominal 1 m; same section, density and material, so the arm's own mass
  scales with it): +-2 %.

The held-out targets stay those of the nominal model: the task's ``reset`` draws them from
the target tables built on the nominal arm (``make_params()``), and only ``params.arm``
(the physics of ``step``) is replaced. Every throw and every miss comes from the task's own
``Basketball.reset`` / ``Basketball.step`` (the simulated swing, the ballistic flight and the
exact closest approach) and the metrics from ``miss_metrics``, exactly as
``python -m gvsjax.evaluate`` computes them; the only difference is that the params are an
argument of the compiled function, so that the whole sweep compiles once. The nominal point
is checked against ``Basketball.evaluate``.

One more, structural, model error is reported beside the sweeps: the ball as a 0.6 kg
point mass on the tip (its weight and its inertia) instead of the task's weightless force.

    python experiments/studies/robustness_basketball.py --checkpoint runs/basketball-default
    python experiments/studies/robustness_basketball.py --replot       # the figure from the JSON

Writes benchmarks/robustness_basketball.json and figures/robustness_basketball.png and
prints Markdown tables. ~1-2 min on 2 shared cores.

Policies side by side (e.g. one trained with ``randomize=``): every checkpoint after
``--checkpoint`` given with ``--compare`` is swept the same way, and all of them go to
benchmarks/robustness_basketball_dr.json and figures/robustness_basketball_dr.png instead:

    python experiments/studies/robustness_basketball.py --checkpoint runs/nominal --compare runs/dr
    python experiments/studies/robustness_basketball.py --compare runs/dr --replot

A policy that observes its randomised factors (``randomize_observe=true``) is swept twice:
shown the nominal factors (it is not told the change) and shown the true one ("informed":
the swept parameter identified exactly; zero for a parameter it was not trained on).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time

import jax
import numpy as np

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation
from gvsjax.ppo import load_policy
from gvsjax.ppo.checkpoint import load_raw, make_policy, resolve
from gvsjax.tasks import basketball as bb
from gvsjax.tasks.randomized import Randomized, nominal

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
BALL_MASS = bb.BALL_WEIGHT / gv.PAPER_ARM["gravity"]  # kg, 0.6
# the sweep, times its half-width: denser near 0, where the within-1-cm share falls fastest
SHAPE = np.array([-1.0, -0.5, -0.25, -0.1, -0.04, 0.0, 0.04, 0.1, 0.25, 0.5, 1.0])
# parameter -> (label, half-width of the relative change, the arm for a relative change r)
SWEEPS = {
    "youngs_modulus": ("Young's modulus E", 0.30,
                       lambda r: gv.paper_arm(tip_force=bb.BALL_WEIGHT,
                                              youngs_modulus=gv.PAPER_ARM["youngs_modulus"] * (1 + r))),
    "damping": ("damping eta", 0.30,
                lambda r: gv.paper_arm(tip_force=bb.BALL_WEIGHT, damping=gv.PAPER_ARM["damping"] * (1 + r))),
    "ball_mass": ("ball mass (tip force m g)", 0.20,
                  lambda r: gv.paper_arm(tip_force=bb.BALL_WEIGHT * (1 + r))),
    "length": ("arm length L", 0.02,
               lambda r: gv.paper_arm(tip_force=bb.BALL_WEIGHT, length=gv.PAPER_ARM["length"] * (1 + r))),
}
# the sweeps' parameters by their randomize= names (the task's Environment.randomizable)
RANDOMIZE_NAME = {"youngs_modulus": "E", "damping": "damping", "ball_mass": "payload"}


def make_evaluator(env: bb.Basketball, policy, n: int, seed: int):
    """``(params, seen) -> misses (n,)`` (m; inf where ``info["valid"]`` is False): ``Basketball.evaluate``'s
    throws (``reset`` keys of ``seed``, the policy's mean actions, ``step``) with the params traced,
    so that every arm of one structure shares one compiled program. ``seen`` (k,) is appended to
    every observation (the factors a ``randomize_observe`` policy sees; empty for the others)."""
    keys = jax.random.split(jax.random.PRNGKey(seed), n)

    @jax.jit
    def run(params, seen):
        obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
        obs = jax.numpy.concatenate([obs, jax.numpy.broadcast_to(seen, (n,) + seen.shape)], -1)
        action = policy(obs)
        _, _, _, _, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, state, action, params)
        return state.target, action, info["cost"], info["valid"]

    def misses(params, seen=()):
        target, action, cost, valid = run(params, np.asarray(seen, float))
        return np.where(np.asarray(valid), np.asarray(cost, float), np.inf), np.asarray(target), np.asarray(action)

    return misses


def sweep(checkpoint: str, n: int, seed: int, informed: bool = False) -> dict:
    """The sweeps of one policy; ``informed``: a policy observing its factors is shown the true one."""
    config, trained, params, net = load_policy(resolve(checkpoint))
    policy = make_policy(config, trained.action_size, net)  # of the observation it was trained on
    env, _ = nominal(trained, policy)  # the task itself
    reference = trained.evaluate(params, policy, n, seed).metrics  # gvsjax.evaluate's: on the nominal model
    observed = trained.ranges if isinstance(trained, Randomized) and trained.observe else ()
    misses = make_evaluator(env, policy, n, seed)
    zeros = np.zeros(len(observed))
    nominal_misses, targets, _ = misses(params, zeros)
    nominal_metrics = bb.miss_metrics(nominal_misses)
    assert all(np.isclose(nominal_metrics[k], reference[k], rtol=1e-9, atol=1e-12) for k in reference), \
        (nominal_metrics, reference)

    def seen(name: str, r: float) -> np.ndarray:
        if not informed:
            return zeros
        return np.array([r / half if RANDOMIZE_NAME.get(name) == k else 0.0 for k, half in observed])

    results: dict = {}
    t0 = time.perf_counter()
    for name, (label, width, arm) in SWEEPS.items():
        rows = []
        for r in SHAPE * width:
            m, t, _ = misses(dataclasses.replace(params, arm=arm(float(r))), seen(name, float(r)))
            assert np.array_equal(t, targets)  # the held-out targets do not move with the physics
            rows.append(dict(relative_change=float(r), **bb.miss_metrics(m)))
        results[name] = dict(label=label, half_width=width, rows=rows)
        print(f"{name}: done ({time.perf_counter() - t0:.0f} s)", flush=True)
    # the ball as an inertial point mass instead of a force (a structural model error)
    ball_inertia = bb.miss_metrics(misses(dataclasses.replace(
        params, arm=gv.paper_arm(tip_mass=BALL_MASS, tip_force=0.0)), zeros)[0])
    randomize = load_raw(resolve(checkpoint))["config"].get("randomize", "")
    return dict(checkpoint=str(resolve(checkpoint)), randomize=randomize, observed=bool(observed),
                informed=informed, n_targets=n, seed=seed, nominal=nominal_metrics,
                evaluate_reference=reference, sweeps=results, ball_as_point_mass=ball_inertia,
                seconds=time.perf_counter() - t0, jax=jax.__version__)


def plot(res: dict, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sweeps = res["sweeps"]
    fig, axes = plt.subplots(1, len(sweeps), figsize=(3.3 * len(sweeps), 3.8), sharey=True)
    for ax, s in zip(axes, sweeps.values()):
        x = 100 * np.array([r["relative_change"] for r in s["rows"]])
        for key, label, style in (("success_rate_10cm", "within 10 cm", "o-"), ("within_1cm", "within 1 cm", "s-")):
            y = 100 * np.array([r[key] for r in s["rows"]])
            line, = ax.plot(x, y, style, ms=4, label=label)
            ax.plot([0.0], [100 * res["nominal"][key]], "*", ms=13, color=line.get_color(), mec="k",
                    zorder=5, label=f"nominal ({label})")
        ax.axvline(0.0, color="0.6", lw=0.8, ls=":")
        ax.set_xlabel(f"{s['label']}: change (%)")
        ax.set_ylim(-3, 103)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"held-out targets hit (%, of {res['n_targets']})")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    b = res["ball_as_point_mass"]
    fig.suptitle("Basketball policy trained on the nominal model, evaluated on a perturbed one "
                 f"(one parameter at a time; the ball as a 0.6 kg point mass instead of a force: "
                 f"{100 * b['success_rate_10cm']:.0f}% / {100 * b['within_1cm']:.1f}%)", fontsize=9)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    os.makedirs(os.path.dirname(out), exist_ok=True)
    fig.savefig(out, dpi=130)
    plt.close(fig)


def label_of(res: dict) -> str:
    if not res.get("randomize"):
        return "trained on the nominal model"
    return (f"randomize={res['randomize']}" + (", observed" if res.get("observed") else "")
            + (" (shown the true factor)" if res.get("informed") else ""))


def plot_compare(policies: list[dict], out: str) -> None:
    """Each policy's within-10-cm (solid) and within-1-cm (dashed) curves, one panel per parameter."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(policies[0]["sweeps"])
    fig, axes = plt.subplots(1, len(names), figsize=(3.4 * len(names), 4.0), sharey=True)
    for j, res in enumerate(policies):
        color = f"C{j}"
        for ax, name in zip(axes, names):
            s = res["sweeps"][name]
            x = 100 * np.array([r["relative_change"] for r in s["rows"]])
            for key, style, what in (("success_rate_10cm", "o-", "< 10 cm"), ("within_1cm", "s--", "< 1 cm")):
                ax.plot(x, 100 * np.array([r[key] for r in s["rows"]]), style, ms=3, color=color,
                        label=f"{label_of(res)}: {what}")
            half = dict(tuple(item.split(":")) for item in res["randomize"].split(",")) if res.get("randomize") else {}
            r = half.get(RANDOMIZE_NAME.get(name, ""))
            if r is not None:  # the training range of this parameter
                ax.axvspan(-100 * float(r), 100 * float(r), color=color, alpha=0.08)
    for ax, name in zip(axes, names):
        ax.axvline(0.0, color="0.6", lw=0.8, ls=":")
        ax.set_xlabel(f"{policies[0]['sweeps'][name]['label']}: change (%)")
        ax.set_ylim(-3, 103)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"held-out targets hit (%, of {policies[0]['n_targets']})")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=8, frameon=False)
    fig.suptitle("Basketball policies evaluated on a perturbed model (one parameter at a time); "
                 "shaded: a policy's training range", fontsize=9)
    fig.tight_layout(rect=(0, 0.04 + 0.035 * len(policies), 1, 1))
    os.makedirs(os.path.dirname(out), exist_ok=True)
    fig.savefig(out, dpi=130)
    plt.close(fig)


def print_compare(policies: list[dict]) -> None:
    """One table per parameter: each policy's within 10 cm / within 1 cm (median miss)."""
    print("\n| policy | nominal model: < 10 cm | < 1 cm | median | p95 | max |")
    print("|---|---|---|---|---|---|")
    for res in policies:
        n = res["nominal"]
        print(f"| {label_of(res)} | {100 * n['success_rate_10cm']:.1f}% | {100 * n['within_1cm']:.1f}% | "
              f"{100 * n['median_m']:.2f} cm | {100 * n['p95_m']:.2f} cm | {100 * n['max_m']:.2f} cm |")
    for name, s in policies[0]["sweeps"].items():
        print(f"\n{s['label']}: within 10 cm / within 1 cm (median miss)\n")
        print("| change | " + " | ".join(label_of(res) for res in policies) + " |")
        print("|---|" + "---|" * len(policies))
        for i, row in enumerate(s["rows"]):
            cells = [res["sweeps"][name]["rows"][i] for res in policies]
            print(f"| {100 * row['relative_change']:+.1f}% | " + " | ".join(
                f"{100 * c['success_rate_10cm']:.1f}% / {100 * c['within_1cm']:.1f}% ({100 * c['median_m']:.2f} cm)"
                for c in cells) + " |")


def print_tables(res: dict) -> None:
    n = res["nominal"]
    print(f"\nnominal ({res['n_targets']} held-out targets, seed {res['seed']}): "
          f"{100 * n['success_rate_10cm']:.1f}% < 10 cm, {100 * n['within_1cm']:.1f}% < 1 cm, "
          f"median {100 * n['median_m']:.2f} cm")
    for s in res["sweeps"].values():
        print(f"\n{s['label']}\n")
        print("| change | < 10 cm | < 1 cm | median | p95 | max |")
        print("|---|---|---|---|---|---|")
        for r in s["rows"]:
            print(f"| {100 * r['relative_change']:+.1f}% | {100 * r['success_rate_10cm']:.1f}% | "
                  f"{100 * r['within_1cm']:.1f}% | {100 * r['median_m']:.2f} cm | {100 * r['p95_m']:.2f} cm | "
                  f"{100 * r['max_m']:.2f} cm |")
    b = res["ball_as_point_mass"]
    print(f"\nball as a 0.6 kg point mass (weight and inertia): {100 * b['success_rate_10cm']:.1f}% < 10 cm, "
          f"{100 * b['within_1cm']:.1f}% < 1 cm, median {100 * b['median_m']:.2f} cm, max {100 * b['max_m']:.2f} cm")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", default="runs/basketball-default", help="run folder or checkpoint file")
    ap.add_argument("--n-targets", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1_000_003, help="the evaluation seed of a seed-0 run")
    ap.add_argument("--json", default=os.path.join(ROOT, "benchmarks", "robustness_basketball.json"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "figures", "robustness_basketball.png"))
    ap.add_argument("--replot", action="store_true", help="only redraw the figure from --json")
    ap.add_argument("--compare", action="append", default=[], metavar="RUN",
                    help="another policy (e.g. trained with randomize=) to sweep beside --checkpoint")
    ap.add_argument("--compare-json", default=os.path.join(ROOT, "benchmarks", "robustness_basketball_dr.json"))
    ap.add_argument("--compare-figure", default=os.path.join(ROOT, "figures", "robustness_basketball_dr.png"))
    args = ap.parse_args()
    if args.compare:
        if args.replot:
            with open(args.compare_json) as fh:
                policies = json.load(fh)["policies"]
        else:
            policies = []
            for run in [args.checkpoint] + args.compare:
                res = sweep(run, args.n_targets, args.seed)
                policies.append(res)
                if res["observed"]:
                    policies.append(sweep(run, args.n_targets, args.seed, informed=True))
            os.makedirs(os.path.dirname(args.compare_json), exist_ok=True)
            with open(args.compare_json, "w") as fh:
                json.dump({"policies": policies}, fh, indent=2)
        plot_compare(policies, args.compare_figure)
        print_compare(policies)
        return
    if args.replot:
        with open(args.json) as fh:
            res = json.load(fh)
    else:
        res = sweep(args.checkpoint, args.n_targets, args.seed)
        os.makedirs(os.path.dirname(args.json), exist_ok=True)
        with open(args.json, "w") as fh:
            json.dump(res, fh, indent=2)
    plot(res, args.figure)
    print_tables(res)


if __name__ == "__main__":
    main()
