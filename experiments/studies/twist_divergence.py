"""Why the twisting benchmark arm diverges under ``ars443`` at 2 steps per 0.1 s: remove one term at a time.

The ``ik_4d`` arm (``gv.curvature_arm(twist=True)``) through 2 implicit steps per 0.1 s, float64, under
random actions held 2 s for 10 s: 8 episodes with twist actions, 8 bending only (the dynamics of the
``follow_target`` arm, torsion without rest twist). An episode diverges when |q| leaves 1e3 or a value
is not finite. Cases: ``ars443``; ``ars443`` without gravity; ``ars443`` with the Coriolis and
centrifugal forces removed (f(q, qd) replaced by f(q, 0) - D qd); ``ars443_frozen_mass`` (M0 in the
explicit part too).

    python experiments/studies/twist_divergence.py

Writes benchmarks/twist_divergence.json.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
import gvsjax as gv  # noqa: I001  (before JAX: the XLA flag)
import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core import integrators, lie
from gvsjax.core.system import FreeDynamics
from gvsjax.tasks.curvature import control
from gvsjax.tasks.curvature.control import ArmControl

OUT = Path(__file__).resolve().parents[2] / "benchmarks" / "twist_divergence.json"
EPISODES, STEPS, HOLD, N_SUB = 16, 100, 20, 2


class WithoutCoriolis(FreeDynamics):
    """f(q, qd) replaced by f(q, 0) - D qd: no Coriolis or centrifugal force."""

    def parts(self, t, q, qd):
        M, _, K, D = super().parts(t, q, qd)
        _, f0, _, _ = super().parts(t, q, tuple(jnp.zeros_like(x) for x in qd))
        n = len(q)
        f = [lie.sub(f0[i], lie.total([lie.mul(D[i][j], qd[j]) for j in range(n)])) for i in range(n)]
        return M, f, K, D


def largest_q(robot, integrator: str, dynamics, actions) -> np.ndarray:
    """(episodes, STEPS) max |q| after each control step."""
    arm, step = ArmControl(robot=robot), integrators.get(integrator).step
    n, T = robot.n_dofs, arm.control_dt
    dt = T / N_SUB

    def episode(acts):
        def one(carry, a):
            q, qd, kappa, twist = carry
            new_kappa, new_twist = control.apply(arm, kappa, twist, a)
            r0, r1 = control.rest_values(robot, kappa, twist), control.rest_values(robot, new_kappa, new_twist)
            system = dynamics(robot, lambda t: jnp.zeros(0), rest_strain=lambda t, q_, qd_: r0 + (t / T) * (r1 - r0))

            def sub(k, s):
                q1, qd1 = step(system, k * dt, tuple(s[0][i] for i in range(n)), tuple(s[1][i] for i in range(n)), dt)
                return jnp.stack(q1), jnp.stack(qd1)

            q, qd = jax.lax.fori_loop(0, N_SUB, sub, (q, qd))
            return (q, qd, new_kappa, new_twist), jnp.max(jnp.abs(q))

        zero = jnp.zeros(n)
        return jax.lax.scan(one, (zero, zero, jnp.zeros((5, 2)), jnp.zeros(5)), acts)[1]

    return np.asarray(jax.jit(jax.vmap(episode))(actions))


def main() -> dict:
    a = jax.random.uniform(jax.random.PRNGKey(0), (EPISODES, STEPS // HOLD, 15), minval=-1.0, maxval=1.0)
    actions = jnp.repeat(a, HOLD, axis=1).at[EPISODES // 2:, :, 10:].set(0.0)
    arm, flat = gv.curvature_arm(twist=True), gv.curvature_arm(twist=True, gravity=0.0)
    cases = {"ars443": (arm, "ars443", FreeDynamics), "ars443, no gravity": (flat, "ars443", FreeDynamics),
             "ars443, no Coriolis or centrifugal": (arm, "ars443", WithoutCoriolis),
             "ars443_frozen_mass": (arm, "ars443_frozen_mass", FreeDynamics)}
    rows = []
    for name, (robot, integrator, dynamics) in cases.items():
        t0 = time.perf_counter()
        qmax = largest_q(robot, integrator, dynamics, actions)
        bad = ~np.isfinite(qmax) | (qmax > 1e3)
        first = [int(np.argmax(b)) + 1 if b.any() else None for b in bad]
        half = EPISODES // 2
        rows.append({"case": name, "diverged_with_twist": int(bad[:half].any(1).sum()),
                     "diverged_bending_only": int(bad[half:].any(1).sum()), "first_bad_control_step": first})
        print(f"{name}: diverged {rows[-1]['diverged_with_twist']}/{half} with twist, "
              f"{rows[-1]['diverged_bending_only']}/{half} bending only; first bad step {first} "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    out = {"episodes": EPISODES, "control_steps": STEPS, "hold_steps": HOLD, "steps_per_0.1s": N_SUB,
           "dtype": "float64", "command": "python experiments/studies/twist_divergence.py", "rows": rows}
    OUT.write_text(json.dumps(out, indent=1) + "\n")
    return out


if __name__ == "__main__":
    main()
