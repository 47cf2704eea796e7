"""Step-size limit of the explicit integrators, from the linearised dynamics.

Runs on concrete numbers only (numpy, inside ``jax.ensure_compile_time_eval``),
so ``simulate`` can check a ``dt`` before anything compiles, also while a
caller's ``jit`` or ``vmap`` is tracing.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax import dynamics, lie
from gvsjax.model import Robot


def linear_matrices(robot: Robot, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M_uu(q0), K_uu, D_uu of the free DoFs as numpy arrays."""
    n = robot.n_dofs
    with jax.ensure_compile_time_eval():  # eager even inside a caller's trace
        qs = [jnp.asarray(float(x)) for x in q0]
        M, _ = dynamics.mass_and_forces(robot, qs, [0] * n, [0] * len(robot.tendons))
        K, D = dynamics.stiffness_and_damping(robot)
        u = robot.free
        full = lambda A, sym: np.array(  # noqa: E731
            [[float(lie.as_array(A[i][j] if (i >= j or not sym) else A[j][i])) for j in u] for i in u]
        )
        return full(M, True), full(K, False), full(D, False)


def stable_step_estimate(robot: Robot, integrator: str, q0: np.ndarray) -> float:
    """Largest stable dt (s) of ``integrator`` on the dynamics linearised at q0.

    Gravity and centrifugal stiffening are left out (they move the estimate by
    a few %). The IMEX schemes treat K and D implicitly: no limit (inf).
    """
    if integrator in ("imex", "ars443") or not robot.free:
        return math.inf
    M, K, D = linear_matrices(robot, np.asarray(q0, dtype=float))
    Minv = np.linalg.inv(M)
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ D]])
    lam = np.linalg.eigvals(A)

    def stable(dt):
        if integrator == "rk4":
            z = lam * dt
            return np.all(np.abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24) <= 1 + 1e-12)
        if integrator == "midpoint":  # fixed-point iterations must contract
            return np.max(np.abs(lam)) * dt / 2 < 1
        # semi-implicit Euler on the linear system
        I = np.eye(n)
        G = np.block([[I - dt * dt * Minv @ K, dt * (I - dt * Minv @ D)], [-dt * Minv @ K, I - dt * Minv @ D]])
        return np.max(np.abs(np.linalg.eigvals(G))) <= 1 + 1e-9

    lo, hi = 0.0, 10.0
    if stable(hi):
        return math.inf
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo
