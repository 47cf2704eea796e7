"""Accuracy per cost of each integrator on the fast throw (T = 0.5 s, release at T).

Prints the release tip-position error against RK4 at 0.1 ms and the RHS evaluations
used, for a range of steps: the comparison behind ``simulate``'s default (RK4) and
the table in ``gvsjax.core.integrators``.

    python experiments/studies/integrator_accuracy.py
"""

import argparse

import numpy as np

import gvsjax as gv  # configures JAX (XLA flag, x64) before any computation
from gvsjax.core import integrators

THETA_F, T = np.deg2rad(210.0), 0.5
ARM = gv.paper_arm(tip_force=5.886)
NAMES = ("rk4", "midpoint", "euler", "imex", "ars443")


def release(integrator, n):
    traj = gv.simulate(ARM, T, n_steps=n, base_angle=lambda t: THETA_F * (t / T) ** 2,
                       integrator=integrator, save_every=n, check_stability=False)
    return np.asarray(traj.tip[-1])


def main():
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    ref = release("rk4", 5000)
    print(f"{'integrator':>10} {'dt ms':>7} {'RHS evals':>9} {'error m':>10}")
    for name in NAMES:
        for dt in (10e-3, 5e-3, 2e-3, 1e-3, 0.5e-3):
            n = int(round(T / dt))
            err = np.linalg.norm(release(name, n) - ref)
            print(f"{name:>10} {dt * 1e3:>7.1f} {n * integrators.get(name).evals:>9d} {err:>10.2e}")


if __name__ == "__main__":
    main()
