"""How many runs of the closed-loop arm against a ball diverge, against the step.

``gv.soft_arm()`` with one ball (r 0.1 m at (0.35, 0, 0.75)) through ``Robot.contact`` and
the default ``gv.Contact``, driven for 0.5 s by random held tendon tensions up to 1500 N,
``ars443`` (the tasks' integrator), a batch of runs under ``jit(vmap)``, the stability check
off. Prints, per step: the runs that end non-finite, the deepest penetration among the
others, and ``stable_step_estimate`` with and without the contact.

    python experiments/studies/contact_divergence.py --steps 0.005 0.0025 0.00125
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax as gv  # noqa: F401  (XLA flags first)
from gvsjax.core.stability import stable_step_estimate


def robot() -> gv.Robot:
    arm = gv.soft_arm()
    return arm.replace(contact=gv.Contact(obstacles=(gv.Sphere(centre=(0.35, 0.0, 0.75), radius=0.1),)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--steps", type=float, nargs="+", default=[5e-3, 2.5e-3])
    ap.add_argument("--duration", type=float, default=0.5)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    r = robot()
    q0 = np.zeros(r.n_dofs)
    print(f"stable_step_estimate ars443: {stable_step_estimate(r, 'ars443', q0):.4g} s with the contact, "
          f"{stable_step_estimate(r, 'ars443', q0, with_contact=False):.4g} s without")
    tension = jax.random.uniform(jax.random.PRNGKey(args.seed), (args.batch, len(r.tendons)), maxval=1500.0)
    for dt in args.steps:
        n = int(round(args.duration / dt))

        @jax.jit
        def run(t, n=n):
            tr = gv.simulate(r, args.duration, n_steps=n, tendon_force=t, integrator="ars443", check_stability=False)
            ok = jnp.all(jnp.isfinite(tr.q[-1])) & jnp.all(jnp.isfinite(tr.qd[-1]))
            return ok, -jnp.min(tr.contact_gap), jnp.any(tr.in_contact)

        ok, depth, touched = (np.asarray(x) for x in jax.vmap(run)(tension))
        print(f"dt {dt * 1e3:g} ms: {int(np.sum(~ok))} of {args.batch} non-finite; {int(np.sum(touched))} touch; "
              f"deepest penetration of the finite runs {1e3 * np.max(depth[ok]):.2f} mm", flush=True)


if __name__ == "__main__":
    main()
