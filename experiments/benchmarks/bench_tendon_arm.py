"""Speed of the 3D tendon-driven arm (``gv.tendon_arm``) next to the paper's planar arm.

Both are integrated with ``ars443`` at dt = 2 ms for 1 s (500 steps), float64:

- paper arm: the basketball swing, its base prescribed as theta_F (t / T)^2 (3 DoFs, 1 free
  angle held by the law, 2 bending modes);
- tendon arm, open loop: step tensions on its four routed tendons and a sinusoidal hub torque
  (6 DoFs: hub angle, torsion, two linear bending curvatures; 20 cable quadrature points);
- tendon arm, closed loop: a zero-order-hold controller every 10 steps (20 ms) that reads the
  state, computes the tip by forward kinematics and sets the hub torque (PD) and the tensions
  (feedforward plus tip-error feedback through a fixed gain matrix).

A batch varies the inputs per arm (T for the swing, the tension level for the tendon arm).
Reported: compile time (first call minus a median call) and arm-steps per second (batch x
steps / median wall time) at batch 1 (one arm, no vmap) and 1024 (``vmap``); then the tendon
arm's statics (``equilibrium`` and ``inverse_statics``): compile and solve time.

    python experiments/benchmarks/bench_tendon_arm.py [--repeats 5] [--json benchmarks/tendon_arm.json]
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import jax.numpy as jnp
import numpy as np
from bench_sim import load_average, timed  # this folder is on sys.path when run as a script

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation

DT, DURATION = 2e-3, 1.0
GAINS = np.array([[0.0, 0.0, 0.0], [0.0, 60.0, 0.0], [0.0, 0.0, 60.0], [0.0, 30.0, 30.0]])  # N per m of tip error


def paper_swing():
    arm = gv.paper_arm(tip_force=5.886)
    theta_f = float(np.deg2rad(210.0))

    def run(T):
        return gv.simulate(arm, DURATION, DT, integrator="ars443", save_every=500,
                           base_angle=lambda t: theta_f * (t / T) ** 2).tip[-1]

    return run, lambda batch: jnp.linspace(1.0, 3.0, batch)


def tendon_open_loop():
    arm = gv.tendon_arm()

    def run(level):
        tension = level * jnp.array([1.0, 0.5, 0.0, 0.8])
        return gv.simulate(arm, DURATION, DT, integrator="ars443", save_every=500, tendon_force=tension,
                           joint_force=lambda t: jnp.array([0.05 * jnp.sin(2 * jnp.pi * t)])).tip[-1]

    return run, lambda batch: jnp.linspace(1.0, 8.0, batch)


def tendon_closed_loop():
    arm = gv.tendon_arm()
    gains = jnp.asarray(GAINS)

    def run(level):
        target = jnp.array([0.05, -0.54, 0.02]) * jnp.array([level / 8.0, 1.0, level / 8.0])

        def controller(t, q, qd):
            tip = gv.backbone(arm, q)[-1]
            tension = jnp.clip(2.0 + gains @ (target - tip), 0.0, 40.0)
            return {"joint_force": jnp.array([-0.2 * (q[0] - 0.5) - 0.06 * qd[0]]), "tendon_force": tension}

        return gv.simulate(arm, DURATION, DT, integrator="ars443", save_every=500, controller=controller,
                           control_every=10).tip[-1]

    return run, lambda batch: jnp.linspace(1.0, 8.0, batch)


def statics() -> dict:
    held = gv.tendon_arm().replace(prescribed=(0,))
    out = {}
    t0 = time.perf_counter()
    eq = gv.equilibrium(held, tendon_force=jnp.array([6.0, 0.0, 0.0, 3.0]))
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    eq = jax.block_until_ready(gv.equilibrium(held, tendon_force=jnp.array([5.0, 1.0, 0.0, 3.0])))
    out["equilibrium"] = dict(compile_s=first, solve_s=time.perf_counter() - t0, newton_steps=int(eq.iterations))
    target = gv.backbone(held, gv.equilibrium(held, tendon_force=jnp.array([0.0, 5.0, 1.0, 3.0]),
                                              prescribed=jnp.array([0.8])).q)[-1]
    for name in ("compile", "solve"):
        t0 = time.perf_counter()
        inv = jax.block_until_ready(gv.inverse_statics(held, target, controls=("tension", "prescribed"),
                                                       tension0=jnp.full(4, 1.0 if name == "compile" else 2.0)))
        out.setdefault("inverse_statics", {})[f"{name}_s"] = time.perf_counter() - t0
    out["inverse_statics"].update(equilibria=int(inv.iterations), error_m=float(inv.error),
                                  converged=bool(inv.converged))
    out["inverse_statics"]["compile_s"] -= out["inverse_statics"]["solve_s"]
    out["equilibrium"]["compile_s"] -= out["equilibrium"]["solve_s"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--batches", type=str, default="1,1024")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", type=str, default=None)
    args = ap.parse_args()
    print(load_average())
    n_steps = int(round(DURATION / DT))
    rows = []
    for name, make, n_dofs in (("paper arm, swing", paper_swing, gv.paper_arm().n_dofs),
                               ("tendon arm, open loop", tendon_open_loop, gv.tendon_arm().n_dofs),
                               ("tendon arm, ZOH feedback", tendon_closed_loop, gv.tendon_arm().n_dofs)):
        run, inputs = make()
        for batch in [int(b) for b in args.batches.split(",")]:
            # batch 1 is one arm without vmap (a vmap of one arm can cost more: a law of t, broadcast
            # against the batched state, doubles the open-loop step)
            fn = jax.jit(jax.vmap(run)) if batch > 1 else jax.jit(lambda x, run=run: run(x[0])[None])
            compile_s, run_s = timed(fn, inputs(batch), repeats=args.repeats)
            tips = np.asarray(fn(inputs(batch)))
            assert np.all(np.isfinite(tips)), f"{name}: non-finite tips at batch {batch}"
            rows.append(dict(case=name, dofs=n_dofs, batch=batch, compile_s=compile_s, median_run_s=run_s,
                             steps_per_s=batch * n_steps / run_s))
            print(f"{name:<26} {n_dofs} DoFs  batch {batch:>5}: compile {compile_s:5.1f} s, "
                  f"{batch * n_steps / run_s:10.3g} arm-steps/s ({run_s * 1e3:.2f} ms per call)", flush=True)
    solved = statics()
    print(f"tendon arm statics: equilibrium compile {solved['equilibrium']['compile_s']:.1f} s, solve "
          f"{solved['equilibrium']['solve_s'] * 1e3:.1f} ms; inverse statics compile "
          f"{solved['inverse_statics']['compile_s']:.1f} s, solve {solved['inverse_statics']['solve_s'] * 1e3:.0f} ms "
          f"({solved['inverse_statics']['equilibria']} equilibria)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(dict(dt=DT, duration=DURATION, integrator="ars443", rows=rows, statics=solved,
                           load_average=load_average(), jax=jax.__version__), fh, indent=2)


if __name__ == "__main__":
    main()
