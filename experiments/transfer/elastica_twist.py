"""The 3D benchmark arm against its PyElastica twin under random actions: does it twist as theirs does?

The twin is ``elastica_twins.py``'s rod (20 elements, as the benchmark builds it; damping, gravity and
clamp as there), driven open loop by the same 10 bending actions as gvsjax's ``follow_target`` arm.
Actions are smooth random walks: uniform knots in [-1, 1] every second, linear in between, 20 s per
episode; then 3 s with no action, to settle. Compared per control step (0.1 s), the tips' distance:

* dynamic: gvsjax's arm (torsion, the task's default control step) and the arm rigid in torsion
  (``torsion=False`` with ``ars443``, the arm before it twisted) against the 20-element twin;
* settled: the shapes after the 3 s hold against the twin refined to 40 and 60 elements (dt scaled
  with the element), each ramped to the walk's final turning angles over 1 s and held 3 s. The
  refined rods spread each angle over the same segments as gvsjax, node by node (at 20 elements
  exactly the benchmark's node weights).

    python experiments/transfer/elastica_twist.py [--episodes 48] [--seconds 20]
    python experiments/transfer/elastica_twist.py --figure   # figures/elastica_twist.png from the JSON

Writes benchmarks/elastica_twist.json (``python docs/gen_results.py elastica_twist`` prints its table).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.metadata
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path[:0] = [HERE, ROOT]

import elastica_twins as et  # noqa: I001  (imports gvsjax, which configures JAX, first)
import jax
import jax.numpy as jnp

import gvsjax as gv
from gvsjax.core.curvature_arm import SEGMENT_SHARE, SEGMENTS
from gvsjax.tasks.curvature import control
from gvsjax.tasks.curvature.control import ArmControl

OUT = os.path.join(ROOT, "benchmarks", "elastica_twist.json")
FIGURE = os.path.join(ROOT, "figures", "elastica_twist.png")
HOLD_S, RAMP_S, SEED, KNOT_S = 3.0, 1.0, 0, 1.0
REFINED = (40, 60)


def walks(n: int, seconds: float, seed: int = SEED) -> np.ndarray:
    """(n, steps, 10) actions: uniform knots in [-1, 1] every KNOT_S, linear in between, per 0.1 s."""
    steps, per = int(round(seconds / 0.1)), int(round(KNOT_S / 0.1))
    knots = np.asarray(jax.random.uniform(jax.random.PRNGKey(seed), (n, steps // per + 1, 10), minval=-1, maxval=1))
    t = np.arange(steps) / per
    k = np.floor(t).astype(int)
    w = (t - k)[None, :, None]
    return (1 - w) * knots[:, k] + w * knots[:, k + 1]


def angles(actions: np.ndarray, arm: ArmControl) -> np.ndarray:
    """(steps + 1, 5, 2) turning angles after each step (the first: zero), as ``control.apply``."""
    out = [np.zeros((5, 2))]
    for a in actions:
        out.append(np.clip(out[-1] + arm.step_scale * np.clip(a, -1, 1).reshape(5, 2), -arm.kappa_max, arm.kappa_max))
    return np.stack(out)


def gvsjax_tips(arm: ArmControl, actions: np.ndarray) -> np.ndarray:
    """(n, steps, 3) tips after each control step of ``actions`` (n, steps, 10)."""
    return np.asarray(jax.jit(jax.vmap(lambda a: control.open_loop_tips(arm, a)))(jnp.asarray(actions)))


def node_weights(n_el: int) -> np.ndarray:
    """(n_el - 1, 5): the share of control point k's angle at interior node j + 1: the segment's
    curvature integrated over the node's Voronoi cell (``SEGMENT_SHARE`` included)."""
    h, knots = et.LENGTH / n_el, np.asarray(SEGMENTS) * et.LENGTH
    s = np.arange(1, n_el) * h
    lo, hi = s - h / 2, s + h / 2
    W = np.zeros((n_el - 1, 5))
    for k in range(5):
        overlap = np.clip(np.minimum(hi, knots[k + 1]) - np.maximum(lo, knots[k]), 0.0, None)
        W[:, k] = SEGMENT_SHARE[k] * overlap / (knots[k + 1] - knots[k])
    return W


class Rod:
    """The twin's rod with ``n_el`` elements (dt scaled with the element), clamped upright under gravity."""

    def __init__(self, n_el: int):
        import elastica as ea

        self.n_el, self.dt = n_el, et.DT * et.N_EL / n_el
        sim = type("Sim", (ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping), {})()
        rod = ea.CosseratRod.straight_rod(n_elements=n_el, start=np.zeros(3), direction=np.array([0.0, 0.0, 1.0]),
                                          normal=np.array([1.0, 0.0, 0.0]), base_length=et.LENGTH,
                                          base_radius=et.RADIUS, density=et.RHO, youngs_modulus=et.E,
                                          shear_modulus=et.E / 3.0)
        sim.append(rod)
        sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
        sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -et.GRAVITY]))
        dl, nu, inertia = et.LENGTH / n_el, 10.0, np.pi * et.RADIUS**4 / 4
        J = et.RHO * np.array([inertia, inertia, 2 * inertia])[:, None] * dl * np.ones(n_el)
        sim.dampen(rod).using(ea.AnalyticalLinearDamper, time_step=self.dt,
                              translational_damping_constant=nu * dl * np.r_[0.5, np.ones(n_el - 1), 0.5],
                              rotational_damping_constant=np.log1p(nu * dl * self.dt / J) * J / self.dt)
        sim.finalize()
        self.sim, self.rod, self.stepper, self.time = sim, rod, ea.PositionVerlet(), np.float64(0.0)
        self.W = node_weights(n_el)

    def rest(self, kappa: np.ndarray) -> np.ndarray:
        out = np.zeros((3, self.n_el - 1))
        out[0], out[1] = self.W @ kappa[:, 0], -(self.W @ kappa[:, 1])
        return out / self.rod.rest_voronoi_lengths

    def advance(self, old: np.ndarray, new: np.ndarray, seconds: float = 0.1) -> np.ndarray:
        """Rest angles linear from ``old`` to ``new`` over ``seconds``: the tip after (their world)."""
        n = int(round(seconds / self.dt))
        a, b = self.rest(old), self.rest(new)
        for i in range(n):
            self.rod.rest_kappa[:] = a + ((i + 1) / n) * (b - a)
            self.time = self.stepper.step(self.sim, self.time, self.dt)
        return self.rod.position_collection[et.SWAP, -1].copy()


def twin_walk(kappas: np.ndarray) -> np.ndarray:
    """(steps, 3) tips of the 20-element twin along turning angles (steps + 1, 5, 2)."""
    rod = Rod(et.N_EL)
    return np.stack([rod.advance(kappas[t], kappas[t + 1]) for t in range(len(kappas) - 1)])


def twin_settled(kappa: np.ndarray, n_el: int) -> np.ndarray:
    """The tip of an ``n_el`` twin ramped from straight to ``kappa`` over RAMP_S and held HOLD_S."""
    rod = Rod(n_el)
    rod.advance(np.zeros_like(kappa), kappa, RAMP_S)
    return rod.advance(kappa, kappa, HOLD_S)


def run(episodes: int, seconds: float) -> dict:
    arm = ArmControl()  # follow_target's arm and control step
    rigid = dataclasses.replace(arm, robot=gv.curvature_arm(torsion=False), integrator="ars443")
    hold = int(round(HOLD_S / 0.1))
    acts = walks(episodes, seconds)
    acts = np.concatenate([acts, np.zeros((episodes, hold, 10))], axis=1)
    t0 = time.perf_counter()
    tips = {"torsion": gvsjax_tips(arm, acts), "rigid_torsion": gvsjax_tips(rigid, acts)}
    print(f"gvsjax {time.perf_counter() - t0:.0f} s", flush=True)
    walk, settled = [], {n: [] for n in (et.N_EL, *REFINED)}
    for i in range(episodes):
        t0 = time.perf_counter()
        kappas = angles(acts[i], arm)
        walk.append(twin_walk(kappas))
        settled[et.N_EL].append(walk[-1][-1])
        for n in REFINED:
            settled[n].append(twin_settled(kappas[-1], n))
        print(f"episode {i}: {time.perf_counter() - t0:.0f} s", flush=True)
    walk = np.stack(walk)
    steps = acts.shape[1] - hold
    cm = lambda x: (100 * x).tolist()  # noqa: E731
    out = {"episodes": episodes, "seconds": seconds, "hold_s": HOLD_S, "refined": list(REFINED),
           "command": f"python experiments/transfer/elastica_twist.py --episodes {episodes} --seconds {seconds:g}",
           "twin": "elastica_twist.Rod: 20 elements, dt 2e-4 s (refined: dt x 20 / n), PyElastica "
                   f"{importlib.metadata.version('pyelastica')}",
           "dynamic_gap_cm": {}, "settled_gap_cm": {}}
    for name, t in tips.items():
        out["dynamic_gap_cm"][name] = cm(np.linalg.norm(t[:, :steps] - walk[:, :steps], axis=-1).reshape(-1))
        for n, ref in settled.items():
            out["settled_gap_cm"][f"{name}_vs_{n}"] = cm(np.linalg.norm(t[:, -1] - np.stack(ref), axis=-1))
    for n in REFINED:
        out["settled_gap_cm"][f"twin20_vs_{n}"] = cm(np.linalg.norm(np.stack(settled[et.N_EL]) - np.stack(settled[n]),
                                                                   axis=-1))
    out["settled_gap_cm"]["twin40_vs_60"] = cm(np.linalg.norm(np.stack(settled[40]) - np.stack(settled[60]), axis=-1))
    return out


def summary(d: dict) -> dict:
    """name -> (median, p95, max) of each gap distribution."""
    rows = {}
    for kind in ("dynamic_gap_cm", "settled_gap_cm"):
        for name, x in d[kind].items():
            rows[f"{kind[:-7]} {name}"] = (float(np.median(x)), float(np.percentile(x, 95)), float(np.max(x)))
    return rows


def figure(d: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    labels = {"torsion": "twisting arm (default)", "rigid_torsion": "rigid in torsion (before)"}
    for name, label in labels.items():
        x = np.sort(d["dynamic_gap_cm"][name])
        axes[0].plot(x, np.linspace(0, 1, len(x)), label=label)
        x = np.sort(d["settled_gap_cm"][f"{name}_vs_60"])
        axes[1].plot(x, np.linspace(0, 1, len(x)), label=label)
    x = np.sort(d["settled_gap_cm"]["twin20_vs_60"])
    axes[1].plot(x, np.linspace(0, 1, len(x)), "k:", label="PyElastica 20 elements")
    axes[0].set(title=f"during the walks: against the 20-element twin\n({d['episodes']} walks of {d['seconds']:g} s, "
                      "every 0.1 s)", xlabel="tip distance (cm)", ylabel="fraction")
    axes[1].set(title="settled: against the twin refined to 60 elements", xlabel="tip distance (cm)")
    axes[0].axvline(1.5, color="grey", lw=0.8, ls="--", label="target: median below")
    axes[1].axvline(0.6, color="grey", lw=0.8, ls="--", label="target: median below")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
        ax.set_xlim(left=0)
    fig.tight_layout()
    fig.savefig(FIGURE, dpi=110)
    print(FIGURE)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=48)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--figure", action="store_true")
    args = ap.parse_args()
    if not args.figure:
        d = run(args.episodes, args.seconds)
        with open(OUT, "w") as f:
            json.dump(d, f)
            f.write("\n")
    with open(OUT) as f:
        d = json.load(f)
    for name, (med, p95, mx) in summary(d).items():
        print(f"{name:40s} median {med:.2f} cm, p95 {p95:.2f}, max {mx:.2f}")
    figure(d)


if __name__ == "__main__":
    main()
