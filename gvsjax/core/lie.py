"""se(3)/SE(3) maths on small vectors and matrices written entry by entry.

Why entry by entry: the rod recursion is a long chain of 3x3 and 6x6 products
on tiny matrices. Written with dense ``jnp`` matrices and ``vmap``-ed, XLA on
the CPU turns each product into a small batched kernel and spends its time
moving data between them. Written here as scalar expressions, every product
becomes a few multiply-adds and XLA fuses the whole step into a handful of
elementwise loops over the batch.

Representation
--------------
* A *scalar* is the Python int ``0`` (a **structural zero**, known at trace
  time), a Python float (a trace-time constant) or a JAX array (usually of
  shape ``()``; ``vmap`` adds the batch axis).
* A vector is a tuple of scalars; a matrix is a tuple of rows.
* Twists and wrenches are 6-tuples ordered ``(angular(3), linear(3))`` as in
  SoRoSim.

Structural zeros are skipped by ``add``/``mul``, so a planar robot written
with the general 3D code only computes its in-plane entries: the sparsity of
the robot description flows through the algebra at trace time.

Small-angle safety: every coefficient is a function of ``u = |w|^2`` with a
"double where" so that neither values nor gradients are NaN at zero twist.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

Scalar = Any
Vec = tuple
Mat = tuple

# ----------------------------------------------------------------------------
# scalar algebra with structural zeros


def is_zero(a: Scalar) -> bool:
    """True for the structural zero (the Python int 0), never for a traced value."""
    return type(a) is int and a == 0


def _is_one(a: Scalar) -> bool:
    return (type(a) is int or type(a) is float) and a == 1


def _operands(a: Scalar, b: Scalar) -> tuple[Any, Any] | None:
    """``a`` and ``b`` as operands ``lax`` takes as they are, or None.

    Why: ``a * b`` on traced arrays goes through ``jnp.multiply``, a jitted function
    that is traced and inlined on every call; the recursion makes tens of thousands
    of such calls per step (a fifth of its tracing time). ``lax`` binds the
    primitive directly. It is the same operation with the same result type, so this
    path is taken only where ``jnp`` would not promote: two arrays of one floating
    dtype (a shape-() one broadcast to the other's shape), or a strongly typed one
    with a Python number (cast to its dtype, as ``jnp`` casts a weakly typed number)."""
    aval_a, aval_b = getattr(a, "aval", None), getattr(b, "aval", None)
    if aval_a is not None and aval_b is not None:
        if aval_a.dtype != aval_b.dtype or aval_a.dtype.kind != "f":
            return None
        if aval_a.shape == aval_b.shape:
            return a, b
        if aval_a.shape == ():
            return lax.broadcast_in_dim(a, aval_b.shape, ()), b
        if aval_b.shape == ():
            return a, lax.broadcast_in_dim(b, aval_a.shape, ())
        return None
    if aval_a is not None and type(b) in (float, int) and not aval_a.weak_type and aval_a.dtype.kind == "f":
        return a, np.asarray(b, aval_a.dtype)
    if aval_b is not None and type(a) in (float, int) and not aval_b.weak_type and aval_b.dtype.kind == "f":
        return np.asarray(a, aval_b.dtype), b
    return None


def add(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(a):
        return b
    if is_zero(b):
        return a
    ops = _operands(a, b)
    return a + b if ops is None else lax.add(*ops)


def sub(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(b):
        return a
    if is_zero(a):
        return neg(b)
    ops = _operands(a, b)
    return a - b if ops is None else lax.sub(*ops)


def mul(a: Scalar, b: Scalar) -> Scalar:
    if is_zero(a) or is_zero(b):
        return 0
    if _is_one(a):
        return b
    if _is_one(b):
        return a
    ops = _operands(a, b)
    return a * b if ops is None else lax.mul(*ops)


def neg(a: Scalar) -> Scalar:
    if is_zero(a):
        return 0
    aval = getattr(a, "aval", None)
    return lax.neg(a) if aval is not None and not aval.weak_type and aval.dtype.kind == "f" else -a


def total(terms: Sequence[Scalar]) -> Scalar:
    out: Scalar = 0
    for t in terms:
        out = add(out, t)
    return out


def const(x: float) -> Scalar:
    """A trace-time constant; exact zeros become structural zeros."""
    x = float(x)
    return 0 if x == 0.0 else x


def as_array(a: Scalar) -> jax.Array:
    """A scalar as a JAX array (structural zeros become 0.0)."""
    if is_zero(a) or isinstance(a, (int, float)):
        return jnp.asarray(float(a))  # weakly typed: takes the dtype of what it meets
    return a


# ----------------------------------------------------------------------------
# vectors and matrices


def vadd(x: Vec, y: Vec) -> Vec:
    return tuple(add(a, b) for a, b in zip(x, y))


def vsub(x: Vec, y: Vec) -> Vec:
    return tuple(sub(a, b) for a, b in zip(x, y))


def vscale(s: Scalar, x: Vec) -> Vec:
    return tuple(mul(s, a) for a in x)


def dot(x: Vec, y: Vec) -> Scalar:
    return total([mul(a, b) for a, b in zip(x, y)])


def cross(a: Vec, b: Vec) -> Vec:
    return (
        sub(mul(a[1], b[2]), mul(a[2], b[1])),
        sub(mul(a[2], b[0]), mul(a[0], b[2])),
        sub(mul(a[0], b[1]), mul(a[1], b[0])),
    )


def matvec(A: Mat, x: Vec) -> Vec:
    return tuple(dot(row, x) for row in A)


def matTvec(A: Mat, x: Vec) -> Vec:
    """A^T x."""
    n = len(A[0])
    return tuple(total([mul(A[i][j], x[i]) for i in range(len(A))]) for j in range(n))


def matmul(A: Mat, B: Mat) -> Mat:
    cols = list(zip(*B))
    return tuple(tuple(dot(row, col) for col in cols) for row in A)


def zeros(n: int) -> Vec:
    return (0,) * n


def unit(n: int, k: int) -> Vec:
    return tuple(1.0 if i == k else 0 for i in range(n))


IDENTITY3: Mat = (unit(3, 0), unit(3, 1), unit(3, 2))


def const_mat(M: Any) -> Mat:
    """A numpy/list matrix as trace-time constants (exact zeros structural)."""
    return tuple(tuple(const(x) for x in row) for row in M)


# ----------------------------------------------------------------------------
# se(3) operators applied to vectors (never formed as 6x6 matrices)


def ad(x: Vec, y: Vec) -> Vec:
    """ad_x y = [x, y] for twists x = (w, v): (w x y_w, v x y_w + w x y_v)."""
    w, v = x[:3], x[3:]
    return cross(w, y[:3]) + vadd(cross(v, y[:3]), cross(w, y[3:]))


def ad_transpose(x: Vec, y: Vec) -> Vec:
    """ad_x^T y, used for the centrifugal/Coriolis wrench ad_eta^T M eta."""
    w, v = x[:3], x[3:]
    # ad_x^T = [[-w~, -v~], [0, -w~]]
    return vsub(vsub(zeros(3), cross(w, y[:3])), cross(v, y[3:])) + vsub(
        zeros(3), cross(w, y[3:])
    )


# ----------------------------------------------------------------------------
# coefficient functions of u = |w|^2, safe (value and gradient) at u = 0

# Series in u (through u^4; docs/physics.md, precision) and the threshold below which they are
# used. fp64: theta < 0.1 and terms through u^3 (truncation < 1e-13; the closed
# forms lose ~1e-10 to cancellation at theta = 0.1). fp32: theta < 1 and terms
# through u^4 (truncation ~3e-8, at fp32 rounding), where the closed forms would
# lose whole digits at theta = 0.1.
_U_SMALL = {jnp.dtype(jnp.float64): 1e-2, jnp.dtype(jnp.float32): 1.0}
_N_TERMS = {jnp.dtype(jnp.float64): 4, jnp.dtype(jnp.float32): 5}


def _safe(u, series, closed):
    """series(u) below the threshold, closed(sqrt(u)) above; gradient-safe at u = 0."""
    dtype = jnp.result_type(u)
    if dtype not in _U_SMALL:
        raise TypeError(f"a {dtype} angle: gvsjax computes in float64 or float32")
    small = u < _U_SMALL[dtype]
    u_safe = jnp.where(small, 1.0, u)
    terms = series[: _N_TERMS[dtype]]
    poly = terms[-1]
    for c in reversed(terms[:-1]):  # Horner
        poly = c + u * poly
    return jnp.where(small, poly, closed(jnp.sqrt(u_safe)))


def _sinc(u):
    return _safe(u, (1, -1 / 6, 1 / 120, -1 / 5040, 1 / 362880), lambda t: jnp.sin(t) / t)


def _a(u):  # (1 - cos t) / t^2
    return _safe(u, (0.5, -1 / 24, 1 / 720, -1 / 40320, 1 / 3628800), lambda t: (1 - jnp.cos(t)) / t**2)


def _b(u):  # (t - sin t) / t^3
    return _safe(u, (1 / 6, -1 / 120, 1 / 5040, -1 / 362880, 1 / 39916800), lambda t: (t - jnp.sin(t)) / t**3)


def _f3(u):  # (2 - 2c - t s) / (2 t^4)
    return _safe(
        u,
        (1 / 24, -1 / 360, 1 / 13440, -1 / 907200, 1 / 95800320),
        lambda t: (2 - 2 * jnp.cos(t) - t * jnp.sin(t)) / (2 * t**4),
    )


def _f4(u):  # (2 t - 3 s + t c) / (2 t^5)
    return _safe(
        u,
        (1 / 120, -1 / 2520, 1 / 120960, -1 / 9979200, 1 / 1245404160),
        lambda t: (2 * t - 3 * jnp.sin(t) + t * jnp.cos(t)) / (2 * t**5),
    )


_SERIES_AT_ZERO = {_sinc: 1.0, _a: 0.5, _b: 1 / 6, _f3: 1 / 24, _f4: 1 / 120}


def _coef(fn, u):
    """fn(u), folded to a constant when u is a structural zero."""
    return _SERIES_AT_ZERO[fn] if is_zero(u) else fn(u)


def _coef_and_rate(fn, u, udot):
    """(fn(u), fn'(u) * udot), with structural zeros handled at trace time."""
    if is_zero(u):
        # u is identically 0 along this path; its rate is 0 too
        return _SERIES_AT_ZERO[fn], 0
    if is_zero(udot):
        return fn(u), 0
    val, rate = jax.jvp(fn, (u,), (udot,))
    return val, rate


# ----------------------------------------------------------------------------
# exponential and its tangent operator


def exp_se3(x: Vec) -> tuple[Mat, Vec]:
    """exp of the twist x = (w, v) as (R, p)."""
    w, v = x[:3], x[3:]
    u = dot(w, w)
    if is_zero(u):
        return IDENTITY3, tuple(v)
    s, a, b = _coef(_sinc, u), _coef(_a, u), _coef(_b, u)
    wx = (
        (0, neg(w[2]), w[1]),
        (w[2], 0, neg(w[0])),
        (neg(w[1]), w[0], 0),
    )
    wx2 = matmul(wx, wx)
    R = tuple(
        tuple(add(add(IDENTITY3[i][j], mul(s, wx[i][j])), mul(a, wx2[i][j])) for j in range(3))
        for i in range(3)
    )
    wv = cross(w, v)
    p = vadd(vadd(v, vscale(a, wv)), vscale(b, cross(w, wv)))
    return R, p


def _is_planar(x: Vec, xd: Vec) -> bool:
    """True when w.v = 0 holds structurally along x + s xd (then ad^3 = -|w|^2 ad)."""
    w, v, wd, vd = x[:3], x[3:], xd[:3], xd[3:]
    return all(is_zero(dot(a, b)) for a, b in ((w, v), (w, vd), (wd, v), (wd, vd)))


def dexp(x: Vec, ys: Sequence[Vec]) -> list[Vec]:
    """T(x) y for each y: the tangent operator sum_k ad_x^k / (k+1)!."""
    return dexp_and_rate(x, zeros(6), ys, rate_of=None)[0]


def _dexp_coefs(x: Vec, xd: Vec) -> list:
    """The coefficients (c_k, their rates along xd) of T(x) = I + sum_k c_k ad_x^k."""
    w, wd = x[:3], xd[:3]
    u = dot(w, w)
    udot = mul(2.0, dot(w, wd))
    planar = _is_planar(x, xd)
    if planar:  # T = I + A ad + B ad^2, exact when w.v = 0
        fns: tuple[Any, ...] = (_a, _b)
    else:  # T = I + f1 ad + f2 ad^2 + f3 ad^3 + f4 ad^4
        fns = ("f1", "f2", _f3, _f4)
    coefs = []
    for fn in fns:
        if isinstance(fn, str):
            # f1 = A + u f3 and f2 = B + u f4 (cheaper than their own closed forms)
            base, hi = (_a, _f3) if fn == "f1" else (_b, _f4)
            cb, rb = _coef_and_rate(base, u, udot)
            ch, rh = _coef_and_rate(hi, u, udot)
            coefs.append((add(cb, mul(u, ch)), add(rb, add(mul(udot, ch), mul(u, rh)))))
        else:
            coefs.append(_coef_and_rate(fn, u, udot))
    return coefs


def dexp_transpose(x: Vec, y: Vec) -> Vec:
    """T(x)^T y: a wrench carried back through the tangent operator (its columns never formed)."""
    acc, a_k = y, y
    for c, _ in _dexp_coefs(x, zeros(6)):
        a_k = ad_transpose(x, a_k)
        acc = vadd(acc, vscale(c, a_k))
    return acc


def dexp_and_rate(x: Vec, xd: Vec, ys: Sequence[Vec], rate_of: Vec | None):
    """T(x) y for each y in ys, and (d/ds T(x + s xd)) rate_of at s = 0.

    The second result is what the recursion needs for psi = Jdot qd:
    Tdot applied to Odot (``rate_of = xd``). It is None when ``rate_of`` is None.
    """
    coefs = _dexp_coefs(x, xd)
    outs = []
    for y in ys:
        acc, a_k = y, y
        for c, _ in coefs:
            a_k = ad(x, a_k)
            acc = vadd(acc, vscale(c, a_k))
        outs.append(acc)

    rate = None
    if rate_of is not None:
        y = rate_of
        rate = zeros(6)
        a_k, ad_k = y, zeros(6)  # ad_x^k y and its rate along xd
        for c, c_rate in coefs:
            ad_k = vadd(ad(xd, a_k), ad(x, ad_k))
            a_k = ad(x, a_k)
            rate = vadd(rate, vadd(vscale(c_rate, a_k), vscale(c, ad_k)))
    return outs, rate


def ad_inv_apply(R: Mat, p: Vec, y: Vec) -> Vec:
    """Ad_g^-1 y for g = (R, p): (R^T y_w, R^T (y_v - p x y_w))."""
    yw, yv = y[:3], y[3:]
    return matTvec(R, yw) + matTvec(R, vsub(yv, cross(p, yw)))


def ad_inv_transpose(R: Mat, p: Vec, w: Vec) -> Vec:
    """(Ad_g^-1)^T w for g = (R, p): a wrench (moment, force) in g's frame carried to the frame g
    is relative to: (R m + p x R f, R f)."""
    m, f = matvec(R, w[:3]), matvec(R, w[3:])
    return vadd(m, cross(p, f)) + f


def compose(R: Mat, p: Vec, R2: Mat, p2: Vec) -> tuple[Mat, Vec]:
    """(R, p) * (R2, p2)."""
    return matmul(R, R2), vadd(p, matvec(R, p2))


SQRT3 = math.sqrt(3.0)
