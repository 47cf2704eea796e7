"""The kinematic pass over one soft link as a ``lax.scan`` (``SoftLink.recursion``).

The unrolled pass (``kinematics.forward``) traces one Magnus step per interval and one
scalar chain per Jacobian column, so its compiled program grows with n_gauss
times the DoFs, and XLA's compile time faster still. Here one step is traced
whatever ``n_gauss``, and the Jacobian's columns travel as one 6-vector of
arrays over the columns, so the step's algebra is traced once whatever the
DoFs. The link's samples come back as one stacked ``Point``.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax import lie
from gvsjax.lie import mul, vadd, zeros
from gvsjax.magnus import XI_STAR, Point, grid_of, magnus, rest_strain, zanna_points
from gvsjax.model import SoftLink

# "auto" scans a soft link of a robot with at least this many DoFs when the link has at least
# this many Gauss points (docs/speed.md)
SCAN_MIN_DOFS, SCAN_MIN_GAUSS = 12, 2


def uses_scan(link: SoftLink, n_dofs: int | None = None) -> bool:
    """Whether a soft link's sample points are visited by ``lax.scan`` (one compiled
    Magnus step) rather than unrolled (one per interval); see ``SoftLink.recursion``.
    ``n_dofs``: the DoFs of the robot the link belongs to (default: the link's own).

    The robot's size decides, not the link's: every unrolled sample point feeds
    scalar chains into all n^2 entries of M, so in a large robot even a small
    link's unrolled pass costs more compile time than it saves run time."""
    if link.recursion != "auto":
        return link.recursion == "scan"
    n_dofs = link.basis.n_dofs if n_dofs is None else n_dofs
    return n_dofs >= SCAN_MIN_DOFS and link.n_gauss >= SCAN_MIN_GAUSS


def soft_link(robot, li, link, qs, qds, s0, state, points, with_psi, jacobian=True):
    """``_soft_link`` as a ``lax.scan`` over the intervals, recording one stacked point.

    Two things keep the compiled program small: one Magnus step is traced
    whatever ``n_gauss``, and the Jacobian's columns travel as one 6-vector of
    arrays over the columns, so the step's algebra is traced once whatever the
    number of DoFs. Basis rows that are zero everywhere (inactive strains) stay
    structural zeros and still prune the algebra.
    """
    grid = grid_of(robot, li)
    L = link.length
    scale = [1.0 / L] * 3 + [1.0] * 3
    n_s = len(qs)
    dtype = jnp.result_type(*(lie.as_array(x) for x in (*qs, L)))
    R0, p0, J0, eta0, psi0 = state
    n = len(J0)
    cols = [k for k in range(s0) if any(not lie.is_zero(a) for a in J0[k])] + list(range(s0, s0 + n_s))
    if not jacobian:  # J stays zero: no columns travel
        cols = []
    n_prev = len(cols) - n_s
    arr = lambda a: jnp.asarray(lie.as_array(a), dtype)  # noqa: E731
    vec = lambda xs: 0 if all(lie.is_zero(x) for x in xs) else jnp.stack([arr(x) for x in xs])  # noqa: E731
    qv, qdv = vec(qs), vec(qds)
    active = [bool(np.any(grid.phi1[:, r]) or np.any(grid.phi2[:, r])) for r in range(6)]

    def pack(R, p, J, eta, psi) -> tuple:
        scalars = [*(a for row in R for a in row), *p, *eta, *(psi if with_psi else ())]
        return tuple(arr(a) for a in scalars), tuple(jnp.broadcast_to(arr(c), (len(cols),)) for c in J)

    def unpack(carry) -> tuple:
        f, J = carry
        R = (tuple(f[0:3]), tuple(f[3:6]), tuple(f[6:9]))
        return R, tuple(f[9:12]), tuple(J), tuple(f[12:18]), tuple(f[18:24]) if with_psi else psi0

    x1, x2 = zanna_points(grid)
    xs: dict[str, Any] = dict(h=jnp.asarray(grid.dX, dtype), phi1=jnp.asarray(grid.phi1, dtype),
                              phi2=jnp.asarray(grid.phi2, dtype))
    if link.rest_strain is not None:
        for key, x in (("rest1", x1), ("rest2", x2)):
            xs[key] = jnp.stack([jnp.broadcast_to(lie.as_array(c), x.shape) for c in rest_strain(link, x)], axis=1)

    def combine(P, x):  # sum_k P[:, k] x_k for a stacked basis P (6 entries of shape (n_s,))
        return tuple(0 if lie.is_zero(Pr) or lie.is_zero(x) else Pr @ x for Pr in P)

    def step(carry, x):
        R, p, J, eta, psi = unpack(carry)
        P1, P2 = (tuple(mul(x[k][r], scale[r]) if active[r] else 0 for r in range(6)) for k in ("phi1", "phi2"))
        rest1, rest2 = (XI_STAR, XI_STAR) if link.rest_strain is None else (
            tuple(x["rest1"][r] for r in range(6)), tuple(x["rest2"][r] for r in range(6)))
        xi1, xi2 = vadd(rest1, combine(P1, qv)), vadd(rest2, combine(P2, qv))
        R_s, p_s, S_cols, S_qd, Sdot_qd = magnus(xi1, xi2, combine(P1, qdv), combine(P2, qdv),
                                                 [P1] if jacobian else [], [P2] if jacobian else [],
                                                 mul(x["h"], L), with_psi)
        if jacobian:
            J = tuple(jnp.concatenate([Jr[:n_prev], Jr[n_prev:] + lie.as_array(Sr)]) for Jr, Sr in zip(J, S_cols[0]))
            J = lie.ad_inv_apply(R_s, p_s, J)
        if with_psi:
            psi = lie.ad_inv_apply(R_s, p_s, vadd(vadd(psi, Sdot_qd), lie.ad(eta, S_qd)))
        eta = lie.ad_inv_apply(R_s, p_s, vadd(eta, S_qd))
        R, p = lie.compose(R, p, R_s, p_s)
        out = pack(R, p, J, eta, psi)
        return out, out

    first = pack(R0, p0, [tuple(J0[k][r] for k in cols) for r in range(6)], eta0, psi0)
    last, ys = jax.lax.scan(step, first, xs)
    stacked = jax.tree.map(lambda a, b: jnp.concatenate([a[None], b]), first, ys)
    R, p, J, eta, psi = unpack(stacked)
    points.append(Point(li, grid.X, "soft", mul(jnp.asarray(grid.w, dtype), L), R, p, J, eta, psi,
                        rows=len(grid.X), cols=tuple(cols.index(k) if k in cols else -1 for k in range(n))))
    R, p, J, eta, psi = unpack(last)
    J_list = [zeros(6)] * n
    for j, k in enumerate(cols):
        J_list[k] = tuple(Jr[j] for Jr in J)
    return R, p, J_list, eta, psi
