"""Pose, twist and J^T at a soft link's contact samples, from the grid points of the recursion.

Each sample is one Magnus step (as ``kinematics._soft_link``'s) from the grid point
before it, all samples of a link at once: the scalars are (n_c,) arrays.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from gvsjax.core import lie
from gvsjax.core.lie import zeros
from gvsjax.core.magnus import ZANNA, Point, advance, grid_of, magnus, rest_strain, strain, strain_rate
from gvsjax.core.model import Robot, SoftLink


def stack(xs: list, n_c: int):
    """One scalar per sample as a (n_c,) scalar; a structural zero when every one is."""
    if all(lie.is_zero(x) for x in xs):
        return 0
    return jnp.stack([jnp.broadcast_to(lie.as_array(x), ()) for x in xs])


def columns(raw: np.ndarray, inv_length, dtype) -> list[tuple]:
    """``magnus.scaled_columns`` for per-sample raw bases (n_c, 6, n): (n_c,) scalars."""
    return [tuple(0 if not np.any(raw[:, r, k]) else
                  (jnp.asarray(raw[:, r, k], dtype) * inv_length if r < 3 else jnp.asarray(raw[:, r, k], dtype))
                  for r in range(6)) for k in range(raw.shape[2])]


def grid_rows(pt: Point, base: np.ndarray, n: int):
    """A stacked point's (R, p, J, eta) at grid rows ``base``, as (n_c,) scalars and n Jacobian columns."""
    sel = lambda x: 0 if lie.is_zero(x) else lie.as_array(x)[base]  # noqa: E731
    R = tuple(tuple(sel(a) for a in row) for row in pt.R)
    J = [zeros(6) if pt.cols[k] < 0 else
         tuple(0 if lie.is_zero(Jr) else lie.as_array(Jr)[base, pt.cols[k]] for Jr in pt.J) for k in range(n)]
    return R, tuple(sel(a) for a in pt.p), J, tuple(sel(a) for a in pt.eta)


def soft_samples(robot: Robot, li: int, link: SoftLink, points: list[Point], q, qd):
    """Pose and twist at every contact sample of soft link ``li``, each sample one Magnus step
    (as ``kinematics._soft_link``'s) from the grid point before it, all samples at once: the
    scalars are (n_c,) arrays. Returns (R, p, eta) in scalar algebra and ``pull``: body wrenches
    at the samples (6 scalars) -> J^T w per sample (n scalars), J's columns never formed (the
    step's transpose carries the wrench back instead, one vector instead of n columns)."""
    grid = grid_of(robot, li)
    Xc = np.asarray(robot.contact.material_points(link))
    n_c = len(Xc)
    base = np.clip(np.searchsorted(grid.X, Xc, side="right") - 1, 0, len(grid.X) - 1)
    dX = Xc - grid.X[base]
    grid_pts = [pt for pt in points if pt.link == li and pt.kind == "soft"]
    if grid_pts[0].rows:  # a scanned link: one stacked point, its rows the grid points
        R, p, J, eta = grid_rows(grid_pts[0], base, robot.n_dofs)
    else:
        pick = [grid_pts[i] for i in base]
        R = tuple(tuple(stack([pt.R[a][b] for pt in pick], n_c) for b in range(3)) for a in range(3))
        p = tuple(stack([pt.p[a] for pt in pick], n_c) for a in range(3))
        eta = tuple(stack([pt.eta[a] for pt in pick], n_c) for a in range(6))
        J = [tuple(stack([pt.J[k][a] for pt in pick], n_c) for a in range(6)) for k in range(len(pick[0].J))]
    if not np.any(dX):  # every sample on a grid point (a one-Gauss-point link's ends and middle): no step
        return R, p, eta, lambda w: [lie.dot(col, w) for col in J]
    j0, s0, end = robot.dof_slices()[li]
    qs, qds = q[s0:end], qd[s0:end]
    dtype = jnp.result_type(*(lie.as_array(x) for x in (*qs, *qds, *p)))  # float32 runs stay float32
    L = link.length
    x1, x2 = grid.X[base] + ZANNA[0] * dX, grid.X[base] + ZANNA[1] * dX
    P1 = columns(np.stack([link.basis.raw(x) for x in x1]), 1.0 / L, dtype)
    P2 = columns(np.stack([link.basis.raw(x) for x in x2]), 1.0 / L, dtype)
    xi1, xi2 = strain(P1, qs, rest_strain(link, x1)), strain(P2, qs, rest_strain(link, x2))
    h = jnp.asarray(dX, dtype) * L
    R_s, p_s, _, S_qd, _ = magnus(xi1, xi2, strain_rate(P1, qds), strain_rate(P2, qds), [], [], h,
                                  with_psi=False)
    R, p, _, eta, _ = advance((R, p, [], eta, zeros(6)), R_s, p_s, [], [], S_qd, None, False)
    c, half_h = lie.mul(lie.SQRT3 / 12.0, lie.mul(h, h)), lie.mul(0.5, h)
    O = lie.vadd(lie.vscale(half_h, lie.vadd(xi1, xi2)), lie.vscale(c, lie.ad(xi1, xi2)))  # as magnus'

    def pull(w):
        # J = Ad_step^-1 (J_before + T(O) Z) with magnus' Z = h/2 (P1 + P2) + c (ad_xi1 P2 - ad_xi2 P1)
        wb = lie.ad_inv_transpose(R_s, p_s, w)
        z = lie.dexp_transpose(O, wb)
        z1, z2 = lie.ad_transpose(xi1, z), lie.ad_transpose(xi2, z)
        terms = [lie.dot(col, wb) for col in J]
        for k, (a, b) in enumerate(zip(P1, P2)):
            own = lie.add(lie.mul(half_h, lie.dot(lie.vadd(a, b), z)),
                          lie.mul(c, lie.sub(lie.dot(b, z1), lie.dot(a, z2))))
            terms[s0 + k] = lie.add(terms[s0 + k], own)
        return terms

    return R, p, eta, pull


def arrays(R, p, eta, n_c: int):
    full = lambda x: jnp.broadcast_to(lie.as_array(x), (n_c,))  # noqa: E731
    return (jnp.stack([jnp.stack([full(a) for a in row], -1) for row in R], -2),
            jnp.stack([full(a) for a in p], -1), jnp.stack([full(a) for a in eta], -1))


def radius(link: SoftLink, X, dtype):
    half = link.radius if link.shape == "circle" else 0.5 * jnp.hypot(link.width, link.height)
    return half * (1.0 + (link.taper - 1.0) * jnp.asarray(X, dtype))
