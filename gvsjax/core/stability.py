"""Step-size limit of the explicit integrators, from the linearised dynamics.

Runs on concrete numbers only (numpy, inside ``jax.ensure_compile_time_eval``),
so ``simulate`` can check a ``dt`` before anything compiles, also while a
caller's ``jit`` or ``vmap`` is tracing.

Every integrator treats the contact penalty explicitly (the IMEX schemes too:
only K and D are implicit). With obstacles the estimate adds the penalty at its
stiffest, pressed deep, as decoupled oscillators: a soft link lying pressed
along its length moves on the penalty at omega^2 = k / (rho A) (per-metre
stiffness over mass per metre, the lightest section), damped at c / (rho A);
a rigid link's site at omega^2 = k lambda_max(J M^-1 J^T) (J: the site's
translational Jacobian). Each must be stable under the scheme's own update
(for ``imex`` and ``ars443``, their explicit part with the implicit one,
``amplification``). This is the limit of a rod pressed along a plane; a short
contact (a ball) tolerates up to about twice the step. Friction's viscous
slope (mu f_n / v_s) depends on the load and is left out.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core import contact, dynamics, integrators, lie
from gvsjax.core.model import Robot, SoftLink


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


def contact_modes(robot: Robot, q0: np.ndarray, M: np.ndarray | None) -> list[tuple[float, float]]:
    """(omega^2, damping rate) of the penalty's stiffest motions (1/s^2, 1/s): one per soft link,
    one per site (``M``: M_uu at q0, needed only with sites); none without obstacles."""
    c = robot.contact
    if c is None or not c.obstacles:
        return []
    modes = []
    for link in robot.links:
        if isinstance(link, SoftLink):
            X = np.asarray(c.material_points(link))
            with jax.ensure_compile_time_eval():  # numpy X: nothing compiles (but a rectangle's torsion)
                rho_a = float(np.min(np.asarray(dynamics.section(link, X).inertia[3])))
            modes.append((float(c.rod.stiffness) / rho_a, float(c.rod.damping) / rho_a))
    if c.sites:
        assert M is not None, "M_uu is needed for sites"
        u = list(robot.free)
        with jax.ensure_compile_time_eval():
            J = np.asarray(jax.jacfwd(lambda x: contact.site_positions(robot, x))(jnp.asarray(q0, float)))
        for Js in J[:, :, u]:
            lam = float(np.max(np.linalg.eigvalsh(Js @ np.linalg.solve(M, Js.T))))
            modes.append((float(c.site.stiffness) * lam, float(c.site.damping) * lam))
    return modes


def amplification(integrator: str, M, K, D, Kc, Dc, dt: float) -> np.ndarray:
    """One step of ``imex`` or ``ars443`` on M qdd = -(K + Kc) q - (D + Dc) qd, K and D
    implicit, Kc and Dc explicit (as the integrators split it): the (2n, 2n) map of (q, qd)."""
    n = M.shape[0]
    I, Z = np.eye(n), np.zeros((n, n))
    explicit = np.linalg.solve(M, -np.hstack([Kc, Dc]))  # qdd's explicit part, per unit (q, qd)
    if integrator == "imex":
        f = -np.hstack([K, D]) + M @ explicit
        dv = np.linalg.solve(M + dt * D + dt * dt * K, dt * f - dt * dt * np.hstack([Z, K]))
        v1 = np.hstack([Z, I]) + dv
        return np.vstack([np.hstack([I, Z]) + dt * v1, v1])
    tab_e, tab_i = integrators._ARS443_E, integrators._ARS443_I
    a = 0.5 * dt
    A = M + a * D + a * a * K
    y0 = np.eye(2 * n)
    stages, e_v = [y0], []
    g_q: list = [None]
    g_v: list = [None]
    for i in range(4):
        e_v.append(explicit @ stages[i])
        Yq = y0[:n] + dt * sum((tab_i[i, j] * g_q[j] for j in range(1, i + 1)), np.zeros((n, 2 * n)))
        Yv = y0[n:] + dt * (sum(tab_e[i, j] * e_v[j] for j in range(i + 1))
                            + sum((tab_i[i, j] * g_v[j] for j in range(1, i + 1)), np.zeros((n, 2 * n))))
        v = np.linalg.solve(A, M @ Yv - a * K @ Yq)
        g_q.append(v)
        g_v.append((v - Yv) / a)
        stages.append(np.vstack([Yq + a * v, v]))
    return stages[4]


def stable_step_estimate(robot: Robot, integrator: str, q0: np.ndarray, with_contact: bool = True) -> float:
    """Largest stable dt (s) of ``integrator`` on the dynamics linearised at q0, with the contact
    penalty at its stiffest (if any, and ``with_contact``; see the module's notes).

    Gravity and centrifugal stiffening are left out (they move the estimate by
    a few %). The IMEX schemes treat K and D implicitly: without contact, no
    limit (inf).
    """
    if not robot.free:
        return math.inf
    q0 = np.asarray(q0, dtype=float)
    has_contact = with_contact and robot.contact is not None and bool(robot.contact.obstacles)
    implicit = integrator in ("imex", "ars443", "ars443_frozen_mass")
    if implicit and not has_contact:
        return math.inf
    sites = has_contact and bool(robot.contact.sites)
    M, K, D = linear_matrices(robot, q0) if (sites or not implicit) else (None, None, None)
    modes = contact_modes(robot, q0, M) if has_contact else []
    systems = [] if implicit else [(M, K, D)]
    systems += [(np.eye(1), np.array([[w2]]), np.array([[rate]])) for w2, rate in modes]

    def stable_one(dt, Ms, Ks, Ds):
        if implicit:  # the contact explicit, the rod's K and D (not coupled in here) implicit
            zero = np.zeros_like(Ks)
            return np.max(np.abs(np.linalg.eigvals(amplification(integrator, Ms, zero, zero, Ks, Ds, dt)))) <= 1 + 1e-9
        m = Ms.shape[0]
        Minv = np.linalg.inv(Ms)
        lam = np.linalg.eigvals(np.block([[np.zeros((m, m)), np.eye(m)], [-Minv @ Ks, -Minv @ Ds]]))
        if integrator == "rk4":
            z = lam * dt
            return np.all(np.abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24) <= 1 + 1e-12)
        if integrator == "midpoint":  # fixed-point iterations must contract
            return np.max(np.abs(lam)) * dt / 2 < 1
        # semi-implicit Euler on the linear system
        I = np.eye(m)
        G = np.block([[I - dt * dt * Minv @ Ks, dt * (I - dt * Minv @ Ds)], [-dt * Minv @ Ks, I - dt * Minv @ Ds]])
        return np.max(np.abs(np.linalg.eigvals(G))) <= 1 + 1e-9

    def stable(dt):
        return all(stable_one(dt, *s) for s in systems)

    lo, hi = 0.0, 10.0
    if stable(hi):
        return math.inf
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo
