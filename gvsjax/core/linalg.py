"""Symmetric positive-definite solves for the dynamics, in two layouts.

``solve_spd`` takes and returns the scalar algebra of ``gvsjax.core.lie`` (lists of
scalars with structural zeros). Below ``STACKED_MIN_DOFS`` unknowns it runs an
LDL^T factorisation entry by entry, which XLA fuses into a few elementwise
loops over the batch: the fastest step for small robots. That program grows
as n^3 scalar operations, and XLA's compile time faster still, so from
``STACKED_MIN_DOFS`` on the same LDL^T runs on a stacked (n, n) array
(``ldl_solve``): O(n) traced operations, each on a shrinking block.

Not LAPACK (``jax.scipy.linalg.cho_solve``): inside the integrator's loop,
vmapped over a batch of 64 or more, its CPU kernel has been seen to stop
the program indefinitely (jax 0.10.2: every XLA worker idle, the executable waiting).
Plain array operations have no such dependency and differentiate as any other.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence

import jax
import jax.numpy as jnp

from gvsjax.core.lie import Scalar, as_array, is_zero, mul, sub

# From this many unknowns the stacked LDL^T is used. Measured on clamped spatial rods at
# batch 1024 (docs/speed.md): at 12 DoFs a wash (one rod equal, a two-link chain 23% slower);
# at 18 and 24 DoFs the stacked form steps 1.2x and 2x faster and compiles 2-4x faster.
STACKED_MIN_DOFS = 16


@contextlib.contextmanager
def stacked_solves(min_dofs: int = 1) -> Iterator[None]:
    """Within the block, trace every solve of ``min_dofs`` or more unknowns (and the ``ars443``
    step of that many DoFs) on stacked arrays.

    For a program that will be differentiated in reverse mode: the entry-by-entry LDL^T is the
    fastest forward step for a few DoFs, but its transpose is n^3 scalar operations more, which XLA
    compiles slowly and runs slowly. The layout is chosen while tracing, so the block must hold the
    tracing (``jax.jit(f).lower(...)``, the first call of a jitted function, or the traced body
    itself). ``simulate`` keys its cached program on the layout; a function of yours traced
    before the block keeps the layout it was traced with (JAX caches traces per function).
    """
    global STACKED_MIN_DOFS
    if not (isinstance(min_dofs, int) and min_dofs >= 1):
        raise ValueError(f"min_dofs={min_dofs!r} is invalid: expected an int >= 1")
    previous, STACKED_MIN_DOFS = STACKED_MIN_DOFS, min_dofs
    try:
        yield
    finally:
        STACKED_MIN_DOFS = previous


def solve_spd(A: Sequence[Sequence[Scalar]], b: Sequence[Scalar]) -> list[Scalar]:
    """Solve A x = b for a symmetric positive definite A given as scalar algebra.

    Only the lower triangle of A is read. Returns n scalars (structural zeros
    where the scalar form proves them).
    """
    n = len(b)
    if n >= STACKED_MIN_DOFS and not all(is_zero(x) for x in b):
        dtype = jnp.result_type(*(as_array(x) for row in A for x in row), *(as_array(x) for x in b))
        x = ldl_solve(symmetric(A, dtype), jnp.stack([_entry(v, dtype) for v in b]))
        return [x[i] for i in range(n)]
    return _solve_scalar(A, b)


def ldl_solve(A: jnp.ndarray, b: jnp.ndarray) -> jnp.ndarray:
    """x with A x = b for one symmetric positive definite (n, n) array A (no pivoting).

    Right-looking LDL^T: each column of L comes from the trailing block, which is
    then updated by one outer product, so every operation is elementwise over a
    block and nothing is scattered. Only the lower triangle of A is read.
    Works under ``jit``, ``vmap`` (batch of systems) and ``grad``.
    """
    n = A.shape[-1]
    if A.shape != (n, n) or b.shape != (n,):
        raise ValueError(f"ldl_solve: A must be (n, n) and b (n,), got {A.shape} and {b.shape}")
    return _ldl_solve(A, b)


def _factor(A: jnp.ndarray) -> tuple[list, list]:
    """L's columns below the diagonal and D of A = L D L^T, from A's lower triangle."""
    n = A.shape[-1]
    S = A  # the trailing block; only its first column and corner are ever read
    cols, d = [], []
    for j in range(n):
        dj = S[0, 0]
        d.append(dj)
        if j + 1 < n:
            col = S[1:, 0] / dj
            S = S[1:, 1:] - (dj * col)[:, None] * col[None, :]
            cols.append(col)
    return cols, d


def _substitute(cols: list, d: list, b: jnp.ndarray) -> jnp.ndarray:
    """x with L D L^T x = b."""
    n = len(d)
    z, y = b, []
    for j in range(n):
        y.append(z[0])
        if j + 1 < n:
            z = z[1:] - cols[j] * z[0]
    x = (y[n - 1] / d[n - 1])[None]
    for i in reversed(range(n - 1)):
        xi = y[i] / d[i] - jnp.sum(cols[i] * x)
        x = jnp.concatenate([xi[None], x])
    return x


# The solve's tangent from the factors, dx = A^-1 (db - dA x): differentiated through the
# factorisation instead, a reverse pass traces one full-size pad per slice of the shrinking block,
# which dominates the compile and the run time of a gradient through the dynamics.
@jax.custom_jvp
def _ldl_solve(A, b):
    cols, d = _factor(A)
    return _substitute(cols, d, b)


@_ldl_solve.defjvp
def _ldl_jvp(primals, tangents):
    A, b = primals
    dA, db = tangents
    cols, d = _factor(A)
    x = _substitute(cols, d, b)
    dS = jnp.tril(dA) + jnp.tril(dA, -1).T  # the symmetric matrix the lower triangle stands for
    return x, _substitute(cols, d, db - jnp.sum(dS * x[None, :], axis=-1))


def entries(x: jnp.ndarray, index: Sequence[int]) -> tuple:
    """The entries x[i] of a 1-D array for i in ``index``, as a tuple of scalars (the scalar
    algebra's layout).

    Taken by one split rather than by indexing each: a split transposes into one concatenation,
    where n indexings transpose into n full-size pads and their sum, which in a reverse pass over
    the dynamics cost more than the rest of it.
    """
    pieces = jnp.split(x, x.shape[0])
    return tuple(pieces[i].reshape(()) for i in index)


def symmetric(A: Sequence[Sequence[Scalar]], dtype) -> jnp.ndarray:
    """The symmetric (n, n) array of a scalar-algebra matrix; only its lower triangle is read."""
    n = len(A)
    return jnp.stack([jnp.stack([_entry(A[i][j] if j <= i else A[j][i], dtype) for j in range(n)]) for i in range(n)])


def _entry(x: Scalar, dtype) -> jnp.ndarray:
    """A scalar-algebra value (a structural zero included) as a JAX scalar of ``dtype``."""
    return jnp.zeros((), dtype) if is_zero(x) else jnp.asarray(as_array(x), dtype)


def _solve_scalar(A, b) -> list[Scalar]:
    """LDL^T entry by entry, skipping structural zeros."""
    n = len(b)
    L: list[list[Scalar]] = [[0] * n for _ in range(n)]
    d: list[Scalar] = [0] * n
    for j in range(n):
        dj = A[j][j]
        for k in range(j):
            dj = sub(dj, mul(mul(L[j][k], L[j][k]), d[k]))
        d[j] = dj
        inv_dj = 1.0 / dj
        for i in range(j + 1, n):
            lij = A[i][j]
            for k in range(j):
                lij = sub(lij, mul(mul(L[i][k], L[j][k]), d[k]))
            L[i][j] = mul(lij, inv_dj)
    y = list(b)
    for i in range(n):
        for k in range(i):
            y[i] = sub(y[i], mul(L[i][k], y[k]))
    x = [mul(y[i], 1.0 / d[i]) if not is_zero(y[i]) else 0 for i in range(n)]
    for i in reversed(range(n)):
        for k in range(i + 1, n):
            x[i] = sub(x[i], mul(L[k][i], x[k]))
    return x
