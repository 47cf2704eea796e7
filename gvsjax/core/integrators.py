"""Fixed-step integrators for M(q) qdd = f(q, qd, t), behind one interface.

Each integrator is ``step(system, t, q, qd, dt) -> (q, qd)`` (q, qd: tuples of
scalars) where ``system``
offers ``accel(t, q, qd)`` and, for IMEX, ``parts(t, q, qd) -> (M, f, K, D)``
(scalar-algebra M, f including -K q - D qd, constant K and D).

| name     | order | RHS evals | stability (paper arm, 2 modes)                     |
|----------|-------|-----------|----------------------------------------------------|
| rk4      | 4     | 4         | |lambda| dt < 2.78: dt < ~13.9 ms (damping decay)   |
| midpoint | 2     | 3         | implicit midpoint by 2 fixed-point iterations;     |
|          |       |           | iterations converge for dt |lambda| / 2 < 1 (~9 ms) |
| euler    | 1     | 1         | semi-implicit (symplectic) Euler: ~8.5 ms           |
| imex     | 1     | 1 + solve | K and D implicit: no limit from stiffness/damping;  |
|          |       |           | for many strain modes, where the others collapse    |
| ars443   | 3     | 4 + solve | IMEX RK, K and D implicit (L-stable part): no limit |
|          |       |           | from stiffness/damping, step set by accuracy alone  |
| ars443_  | 1 (3  | 4 + solve | ars443 with M frozen in both parts: stable where a  |
| frozen_  | for   |           | fast strain's inertia changes with the shape (a     |
| mass     | M(q)  |           | twisting rod), where ars443 diverges               |
|          | fixed)|           |                                                     |

``simulate``'s default is RK4: at 2 ms it puts the fast throw's release within
1e-9 m of a converged run, where semi-implicit Euler at 1 ms is 1.6 mm off
(``experiments/studies/integrator_accuracy.py``; docs/physics.md, integrators). Where
the step is bounded by stability rather than accuracy, as in the basketball
task (300 RK4 steps for a 3 s throw, while 40 ARS(4,4,3) steps keep every
release within 0.5 mm), ``ars443`` does the same work with about a seventh of
the evaluations.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core import lie, linalg


class Integrator(NamedTuple):
    name: str
    order: int
    evals: int
    step: Callable


# States are tuples of scalars (one array per DoF), not stacked vectors: XLA
# then fuses a whole step into elementwise loops over the batch instead of
# re-deriving shared subexpressions for every lane of a stacked output.
#
# XLA's CPU backend forms no multi-output loop fusions, so n accelerations
# leaving one evaluation of the dynamics become n fusions that each recompute
# the whole recursion (or one (batch, n) fusion that does, per lane). Packed in
# pairs as complex numbers, two come out of one fusion that computes the
# recursion once. The pack must cross a loop boundary (a stage scan's carry)
# before it is unpacked: in the same computation XLA folds real(complex(a, b))
# back to a. Same arithmetic, same results; only the fusion changes
# (``experiments/benchmarks/bench_ceiling.py`` prints the FLOPs per evaluation both ways).


def _pack(xs) -> tuple:
    """n real scalars as ceil(n/2) complex ones (the last imaginary part 0 for odd n)."""
    xs = [lie.as_array(x) for x in xs]
    if len(xs) % 2:
        xs.append(jnp.zeros_like(xs[0]))
    return tuple(jax.lax.complex(xs[k], xs[k + 1]) for k in range(0, len(xs), 2))


def _unpack(packed, n: int) -> tuple:
    """The n real scalars of ``_pack``."""
    out = []
    for c in packed:
        out += [jnp.real(c), jnp.imag(c)]
    return tuple(out[:n])


def _axpy(x, a, y):
    """x + a * y over tuples."""
    return tuple(xi + a * yi for xi, yi in zip(x, y))


def _rk4(system, t, q, qd, dt):
    """Classical RK4. The four stages run as a 4-long ``lax.scan`` so the
    dynamics appear once in the compiled program (a quarter of the compile
    time of an unrolled step, at the same run time). Each stage's acceleration
    leaves packed (``_pack``) and is unpacked, and added to the weighted sum,
    by the next stage."""
    dtype = jnp.result_type(*q)
    c = jnp.array([0.0, 0.5, 0.5, 1.0], dtype)
    b = jnp.array([1.0, 2.0, 2.0, 1.0], dtype) / 6
    b_prev = jnp.array([0.0, 1.0, 2.0, 2.0], dtype) / 6  # weight of the previous stage's acceleration
    n = len(q)

    def stage(carry, coef):
        (kq, kqd_packed), (aq, aqd) = carry
        ci, bi, bp = coef
        kqd = _unpack(kqd_packed, n)
        aqd = _axpy(aqd, bp, kqd)
        qi, qdi = _axpy(q, ci * dt, kq), _axpy(qd, ci * dt, kqd)
        acc = _pack(system.accel(t + ci * dt, qi, qdi))
        return ((qdi, acc), (_axpy(aq, bi, qdi), aqd)), None

    zero = tuple(jnp.zeros_like(x) for x in qd)
    ((_, acc), (aq, aqd)), _ = jax.lax.scan(stage, ((zero, _pack(zero)), (zero, zero)), (c, b, b_prev))
    aqd = _axpy(aqd, b[3], _unpack(acc, n))
    return _axpy(q, dt, aq), _axpy(qd, dt, aqd)


def _semi_implicit_euler(system, t, q, qd, dt):
    qd1 = _axpy(qd, dt, system.accel(t, q, qd))
    return _axpy(q, dt, qd1), qd1


def _midpoint(system, t, q, qd, dt, iterations: int = 2):
    """Implicit midpoint by fixed-point iterations from an Euler predictor.

    Starting the iterate at (q, qd) makes the predictor the first pass of the
    same update evaluated at t, so predictor and iterations run as one
    ``lax.scan`` and the dynamics appear once in the compiled program."""
    fractions = jnp.array([0.0] + [0.5] * iterations, jnp.result_type(*q))
    n = len(q)

    def one(carry, c):
        q1, acc = carry  # the iterate's qd1 = qd + dt * acc, acc packed (``_pack``)
        qd1 = _axpy(qd, dt, _unpack(acc, n))
        qm = tuple((a + b) / 2 for a, b in zip(q, q1))
        qdm = tuple((a + b) / 2 for a, b in zip(qd, qd1))
        return (_axpy(q, dt, qdm), _pack(system.accel(t + c * dt, qm, qdm))), None

    zero = tuple(jnp.zeros_like(x) for x in qd)
    (q1, acc), _ = jax.lax.scan(one, (q, _pack(zero)), fractions)
    return q1, _axpy(qd, dt, _unpack(acc, n))


def _imex_euler(system, t, q, qd, dt):
    """(M + dt D + dt^2 K) dv = dt f - dt^2 K qd; qd += dv; q += dt qd."""
    M, f, K, D = system.parts(t, q, qd)
    n = len(q)
    qd_s = list(qd)
    A = [[lie.add(lie.add(M[i][j], lie.mul(dt, D[i][j])), lie.mul(dt * dt, K[i][j])) for j in range(n)]
         for i in range(n)]
    rhs = [
        lie.sub(lie.mul(dt, f[i]), lie.mul(dt * dt, lie.total([lie.mul(K[i][j], qd_s[j]) for j in range(n)])))
        for i in range(n)
    ]
    dv = tuple(lie.as_array(x) for x in linalg.solve_spd(A, rhs))
    qd1 = _axpy(qd, 1.0, dv)
    return _axpy(q, dt, qd1), qd1


# ARS(4,4,3) (Ascher, Ruuth & Spiteri, Appl. Numer. Math. 1997): a third-order
# IMEX Runge-Kutta pair, L-stable SDIRK part with a_ii = 1/2, stiffly accurate
# (the step's result is its last stage). Row i holds stage i's coefficients.
# Only the off-diagonal implicit entries are stored: the diagonal 1/2 is the solve.
# NumPy tables: a JAX array at import would start JAX's backend, after which
# jax.distributed.initialize can no longer run.
_ARS443_E = np.array([[0.5, 0, 0, 0], [11 / 18, 1 / 18, 0, 0], [5 / 6, -5 / 6, 0.5, 0], [0.25, 1.75, 0.75, -1.75]])
_ARS443_I = np.array([[0.0, 0, 0, 0], [0.0, 1 / 6, 0, 0], [0.0, -0.5, 0.5, 0], [0.0, 1.5, -1.5, 0.5]])
_ARS443_C = np.array([0.5, 2 / 3, 0.5, 1.0])
FOLD_MIN_DOFS = 4  # measured: 3D robots (6+ DoFs) gain, the paper's arm (2) loses (docs/speed.md)


def _ars443(system, t, q, qd, dt):
    """IMEX RK: the linear stiff part g(y) = (qd, -M0^-1 (K q + D qd)), with M0 the
    mass matrix at the step's start, implicit; the rest F(y) - g(y) explicit.

    Freezing M0 keeps the split additive within a step, so the pair's order 3
    holds, and every implicit stage is one SPD solve with the same matrix
    M0 + (dt/2) D + (dt/2)^2 K. The damping and bending modes, which bound
    RK4's step, then bound nothing: the step is set by accuracy alone.

    Two layouts of the same arithmetic: from ``FOLD_MIN_DOFS`` free DoFs on, all
    four evaluations of the dynamics run in one loop (``_ars443_folded``: the
    dynamics traced once, half the compile time of a 3D robot and a faster
    step); below, the step's start is evaluated before a 3-long loop
    (``_ars443_split``: the fastest step for small planar robots). From
    ``linalg.STACKED_MIN_DOFS`` DoFs the folded loop's matrices are arrays
    (``_ars443_stacked``).
    """
    return _ars443_layout(system, t, q, qd, dt, False)


def _ars443_frozen_mass(system, t, q, qd, dt):
    """``_ars443`` with the explicit part's accelerations also solved with M0:
    within a step it integrates M0 qdd = f(q, qd, t), every term but the inertia
    evaluated at the stage.

    Why: in ``_ars443`` the explicit part holds (M0^-1 - M(q_i)^-1)(K q + D qd),
    whose sensitivity to the stage's state is (M0^-1 - M(q_i)^-1)(K, D): the
    stiff terms times the change of M over the step. The benchmark arm's short
    links have M^-1 D up to 1e7 1/s; where the inertia such a strain drags changes
    with the shape (a bent rod's twist) that product diverges at 0.05 s steps
    (without gravity or Coriolis terms too; frozen M, not). With M0 in both parts the
    stiff K and D terms are implicit only, and the split is additive in the
    stages. Order 3 where M is constant (linear analyses give the same map as
    ``_ars443``); where M(q) changes the step is first order in that change,
    an error dt^2 (M(q) - M0) qdd per step, small where the motion is slow
    against the step (docs/physics.md, integrators).
    """
    return _ars443_layout(system, t, q, qd, dt, True)


def _ars443_layout(system, t, q, qd, dt, frozen_mass):
    if len(q) >= linalg.STACKED_MIN_DOFS:
        return _ars443_stacked(system, t, q, qd, dt, frozen_mass)
    fn = _ars443_folded if len(q) >= FOLD_MIN_DOFS else _ars443_split
    return fn(system, t, q, qd, dt, frozen_mass)


def _ars443_folded(system, t, q, qd, dt, frozen_mass: bool = False):
    """``_ars443`` with the step's start as the first of four loop iterations, which
    also keeps M0."""
    n = len(q)
    a = 0.5 * dt
    dtype = jnp.result_type(*q)
    tab_e, tab_i, tab_c = (jnp.asarray(x, dtype) for x in (_ARS443_E, _ARS443_I, _ARS443_C))
    t_eval = t + jnp.concatenate([jnp.zeros(1, dtype), tab_c[:3]]) * dt  # where iteration i evaluates
    arr = lambda xs: jnp.stack([lie.as_array(x) for x in xs])  # noqa: E731
    q0, qd0 = jnp.stack(q), jnp.stack(qd)
    lower = [(i, j) for i in range(n) for j in range(i + 1)]

    def body(carry, i):
        # slots (5 x n): implicit q' and qd', explicit qd' per stage (slot 0 of the implicit
        # parts has weight 0 in every stage, so it stays empty; slot 4 is never read)
        g_q, g_v, e_v, e_prev, M0_prev, qi, vi = carry
        # the previous iteration's explicit part enters its slot here, after crossing the
        # loop boundary packed: written where it is computed, XLA would fuse the whole
        # dynamics into that strided in-place update
        e_v = e_v.at[jnp.maximum(i - 1, 0)].set(arr(_unpack(e_prev, n)))
        M, f, K, D = system.parts(t_eval[i], tuple(qi[k] for k in range(n)), tuple(vi[k] for k in range(n)))
        first = i == 0
        M0: list[list[Any]] = [[0] * n for _ in range(n)]
        for (r, c), old in zip(lower, M0_prev):
            M0[r][c] = M0[c][r] = 0 if lie.is_zero(M[r][c]) else jnp.where(first, lie.as_array(M[r][c]), old)
        # at the step's start the explicit part is M0^-1 (f + K q + D qd); later f's own
        elastic = [lie.mul(jnp.where(first, 1.0, 0.0).astype(dtype), lie.add(x, y))
                   for x, y in zip(lie.matvec(K, q), lie.matvec(D, qd))]
        M_e = tuple(map(tuple, M0)) if frozen_mass else M
        e = arr(linalg.solve_spd(M_e, [lie.add(fi, el) for fi, el in zip(f, elastic)])) - g_v[i]
        A = [[lie.add(lie.add(M0[r][c], lie.mul(a, D[r][c])), lie.mul(a * a, K[r][c])) for c in range(n)]
             for r in range(n)]
        Yq = q0 + dt * (tab_i[i] @ g_q[:4])
        Yv = qd0 + dt * (tab_e[i] @ e_v[:4] + tab_e[i, i] * e + tab_i[i] @ g_v[:4])
        M0_rows = tuple(map(tuple, M0))
        m = [lie.sub(mv, lie.mul(a, kq)) for mv, kq in zip(lie.matvec(M0_rows, tuple(Yv)), lie.matvec(K, tuple(Yq)))]
        v = arr(linalg.solve_spd(A, m))
        M0_out = [jnp.asarray(lie.as_array(M0[r][c]), dtype) for r, c in lower]
        return (g_q.at[i + 1].set(v), g_v.at[i + 1].set((v - Yv) / a), e_v, _pack(e), M0_out, Yq + a * v, v), None

    zeros = jnp.zeros((5, n), dtype)
    M0_init = [jnp.zeros((), dtype)] * len(lower)
    carry0 = (zeros, zeros, zeros, _pack(jnp.zeros(n, dtype)), M0_init, q0, qd0)
    (*_, q1, qd1), _ = jax.lax.scan(body, carry0, jnp.arange(4))
    return tuple(q1[k] for k in range(n)), tuple(qd1[k] for k in range(n))  # stiffly accurate: the last stage


def _ars443_stacked(system, t, q, qd, dt, frozen_mass: bool = False):
    """``_ars443_folded`` with M0, K and D as (n, n) arrays and the solves stacked
    (``linalg.ldl_solve``): for many DoFs the scalar algebra's n^2 traced products
    (n^3 in the solves) cost more compile time than the arithmetic they save."""
    n = len(q)
    a = 0.5 * dt
    dtype = jnp.result_type(*q)
    tab_e, tab_i, tab_c = (jnp.asarray(x, dtype) for x in (_ARS443_E, _ARS443_I, _ARS443_C))
    t_eval = t + jnp.concatenate([jnp.zeros(1, dtype), tab_c[:3]]) * dt
    arr = lambda xs: jnp.stack([jnp.asarray(lie.as_array(x), dtype) for x in xs])  # noqa: E731
    mv = lambda A, x: jnp.sum(A * x, axis=-1)  # elementwise: fuses, where a batched dot would not  # noqa: E731
    q0, qd0 = jnp.stack(q), jnp.stack(qd)

    def body(carry, i):
        g_q, g_v, e_v, e_prev, M0_prev, qi, vi = carry  # as in _ars443_folded
        e_v = e_v.at[jnp.maximum(i - 1, 0)].set(arr(_unpack(e_prev, n)))
        M, f, K, D = system.parts(t_eval[i], tuple(qi[k] for k in range(n)), tuple(vi[k] for k in range(n)))
        M, K, D = (linalg.symmetric(X, dtype) for X in (M, K, D))
        first = i == 0
        M0 = jnp.where(first, M, M0_prev)
        elastic = jnp.where(first, mv(K, q0) + mv(D, qd0), jnp.zeros(n, dtype))
        e = linalg.ldl_solve(M0 if frozen_mass else M, arr(f) + elastic) - g_v[i]
        Yq = q0 + dt * (tab_i[i] @ g_q[:4])
        Yv = qd0 + dt * (tab_e[i] @ e_v[:4] + tab_e[i, i] * e + tab_i[i] @ g_v[:4])
        v = linalg.ldl_solve(M0 + a * D + (a * a) * K, mv(M0, Yv) - a * mv(K, Yq))
        return (g_q.at[i + 1].set(v), g_v.at[i + 1].set((v - Yv) / a), e_v, _pack(e), M0, Yq + a * v, v), None

    zeros = jnp.zeros((5, n), dtype)
    carry0 = (zeros, zeros, zeros, _pack(jnp.zeros(n, dtype)), jnp.zeros((n, n), dtype), q0, qd0)
    (*_, q1, qd1), _ = jax.lax.scan(body, carry0, jnp.arange(4))
    return tuple(q1[k] for k in range(n)), tuple(qd1[k] for k in range(n))


def _ars443_split(system, t, q, qd, dt, frozen_mass: bool = False):
    """``_ars443`` with the step's start evaluated before the loop over stages 1-3."""
    M, f, K, D = system.parts(t, q, qd)
    n = len(q)
    a = 0.5 * dt
    dtype = jnp.result_type(*q)
    tab_e, tab_i, tab_c = (jnp.asarray(x, dtype) for x in (_ARS443_E, _ARS443_I, _ARS443_C))
    A = [[lie.add(lie.add(M[i][j], lie.mul(a, D[i][j])), lie.mul(a * a, K[i][j])) for j in range(n)]
         for i in range(n)]
    arr = lambda xs: jnp.stack([lie.as_array(x) for x in xs])  # noqa: E731
    elastic = [lie.add(x, y) for x, y in zip(lie.matvec(K, q), lie.matvec(D, qd))]
    zeros = jnp.zeros((4, n), dtype)
    # stage slots (4 x n): implicit q' and qd', explicit qd' (q' has no explicit part).
    # Slot 0 of the implicit parts has weight 0 in every stage, so it stays empty.
    e_v0 = _pack(linalg.solve_spd(M, [lie.add(fi, e) for fi, e in zip(f, elastic)]))
    q0, qd0 = jnp.stack(q), jnp.stack(qd)

    def solve_stage(i, g_q, g_v, e_v):
        Yq = q0 + dt * (tab_i[i] @ g_q)
        Yv = qd0 + dt * (tab_e[i] @ e_v + tab_i[i] @ g_v)
        m = [lie.sub(mv, lie.mul(a, kq)) for mv, kq in zip(lie.matvec(M, tuple(Yv)), lie.matvec(K, tuple(Yq)))]
        v = arr(linalg.solve_spd(A, m))
        return Yq + a * v, v, Yv

    # Each stage's acceleration leaves the stage packed (``_pack``) and enters its
    # slot at the next stage. Written into the (4, n) slot array in the stage that
    # computes it, XLA would fuse the whole dynamics into that in-place update, whose
    # lanes lie 4n elements apart: no SIMD across the batch.
    def stage(carry, i):
        g_q, g_v, e_v, acc_prev = carry
        e_v = e_v.at[i].set(arr(_unpack(acc_prev, n)) - g_v[i])
        qi, v, Yv = solve_stage(i, g_q, g_v, e_v)
        if frozen_mass:
            _, f_i, _, _ = system.parts(t + tab_c[i] * dt, tuple(qi), tuple(v))
            acc = _pack(linalg.solve_spd(M, f_i))
        else:
            acc = _pack(system.accel(t + tab_c[i] * dt, tuple(qi), tuple(v)))
        return (g_q.at[i + 1].set(v), g_v.at[i + 1].set((v - Yv) / a), e_v, acc), None

    (g_q, g_v, e_v, acc_last), _ = jax.lax.scan(stage, (zeros, zeros, zeros, e_v0), jnp.arange(3))
    e_v = e_v.at[3].set(arr(_unpack(acc_last, n)) - g_v[3])
    q1, qd1, _ = solve_stage(3, g_q, g_v, e_v)  # stiffly accurate: the last stage is the step
    return tuple(q1), tuple(qd1)


INTEGRATORS = {
    "rk4": Integrator("rk4", 4, 4, _rk4),
    "midpoint": Integrator("midpoint", 2, 3, _midpoint),
    "euler": Integrator("euler", 1, 1, _semi_implicit_euler),
    "imex": Integrator("imex", 1, 1, _imex_euler),
    "ars443": Integrator("ars443", 3, 4, _ars443),
    "ars443_frozen_mass": Integrator("ars443_frozen_mass", 1, 4, _ars443_frozen_mass),
}


def get(name: str) -> Integrator:
    if name not in INTEGRATORS:
        raise ValueError(f"integrator={name!r} is unknown; choose one of {sorted(INTEGRATORS)}")
    return INTEGRATORS[name]
