"""The pieces of the base-to-tip recursion that every pass shares: quadrature grids,
strain bases, sample points and the 4th-order Magnus (Zanna collocation) step, as
SoroSim has it (Mathew et al. 2023; docs/physics.md, Magnus steps).

The unrolled pass (``kinematics``), the scanned one (``scan``) and the contact
samples (``contact``) all step with ``magnus`` and ``advance``.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import jax.numpy as jnp
import numpy as np

from gvsjax.core import lie
from gvsjax.core.lie import const, mul, vadd, vscale, zeros
from gvsjax.core.model import Robot, SoftLink, StrainBasis

XI_STAR = (0, 0, 0, 1.0, 0, 0)  # straight, unstretched, unsheared reference strain
ZANNA = (0.5 - np.sqrt(3) / 6, 0.5 + np.sqrt(3) / 6)  # Gauss collocation points of a Magnus step


# ----------------------------------------------------------------------------
# static discretisation


@dataclass(frozen=True)
class LinkGrid:
    """Sample points of one soft link and the basis values the recursion needs.

    X: (nip,) points in [0, 1], Gauss-Legendre nodes bracketed by 0 and 1 (plus
    any load points); w: (nip,) quadrature weights as fractions of L (0 at the
    ends and at load points); phi: (nip, 6, n) raw basis at the points;
    phi1, phi2: (nip-1, 6, n) raw basis at the two Zanna collocation points of
    each interval; dX: (nip-1,) interval lengths.
    """

    X: np.ndarray
    w: np.ndarray
    phi: np.ndarray
    phi1: np.ndarray
    phi2: np.ndarray
    dX: np.ndarray


@functools.cache
def link_grid(basis: StrainBasis, n_gauss: int, extra: tuple[float, ...] = ()) -> LinkGrid:
    nodes, weights = np.polynomial.legendre.leggauss(n_gauss)
    pts = {0.0: 0.0, 1.0: 0.0}
    for x, wq in zip((nodes + 1) / 2, weights / 2):
        pts[float(x)] = float(wq)
    for x in extra:
        pts.setdefault(float(x), 0.0)
    X = np.array(sorted(pts))
    w = np.array([pts[x] for x in X])
    dX = np.diff(X)
    c1, c2 = ZANNA
    phi = np.stack([basis.raw(x) for x in X])
    phi1 = np.stack([basis.raw(a + c1 * d) for a, d in zip(X[:-1], dX)])
    phi2 = np.stack([basis.raw(a + c2 * d) for a, d in zip(X[:-1], dX)])
    return LinkGrid(X, w, phi, phi1, phi2, dX)


def extra_points(robot: Robot, link_index: int) -> tuple[float, ...]:
    """Material points of a link where a load or mass acts, or that are observed (sampled exactly)."""
    n = len(robot.links)
    return tuple(
        sorted({float(m.X) for m in (*robot.loads, *robot.masses, *robot.wrenches) if m.link % n == link_index}
               | {float(X) for link, X in robot.sample_points if link % n == link_index})
    )


def grid_of(robot: Robot, link_index: int) -> LinkGrid:
    link = robot.links[link_index]
    return link_grid(link.basis, link.n_gauss, extra_points(robot, link_index))


def scaled_columns(raw: np.ndarray, inv_length) -> list[tuple]:
    """Columns of Phi = diag(1/L, 1/L, 1/L, 1, 1, 1) Phi_raw as 6-tuples (SoRoSim scaling)."""
    return [
        tuple(mul(const(raw[r, k]), inv_length) if r < 3 else const(raw[r, k]) for r in range(6))
        for k in range(raw.shape[1])
    ]


def rest_strain(link: SoftLink, X: Any) -> tuple:
    """xi*(X) of a soft link (see ``SoftLink.rest_strain``); X a float or an array of points."""
    if link.rest_strain is None:
        return XI_STAR
    c = jnp.asarray(link.rest_strain)
    if c.ndim == 1:
        return tuple(c[r] for r in range(6))
    powers = jnp.asarray([X**j for j in range(c.shape[1])], c.dtype)
    return tuple(c[r] @ powers for r in range(6))


def strain(cols: Sequence[tuple], q: Sequence, rest: tuple = XI_STAR) -> tuple:
    """xi = Phi q + xi*."""
    out = rest
    for col, qk in zip(cols, q):
        out = vadd(out, vscale(qk, col))
    return out


def strain_rate(cols: Sequence[tuple], qd: Sequence) -> tuple:
    out = zeros(6)
    for col, qk in zip(cols, qd):
        out = vadd(out, vscale(qk, col))
    return out


# ----------------------------------------------------------------------------
# the recursion


@dataclass
class Point:
    """Kinematic state at one sample point (scalar-algebra values).

    kind: "soft" (a rod sample with quadrature weight ``weight``, physical
    metres), "rigid" (a rigid link's CoM) or "end" (a rigid link's far end).
    rows > 0 marks a *stacked* point: all of a soft link's samples at once, X an
    array of the ``rows`` material points and every non-zero scalar an array
    with a leading axis of that length; J is then one 6-vector of (rows, m)
    arrays, ``cols[k]`` the column of DoF k there (-1: J's column k is zero).
    See ``uses_scan``.
    """

    link: int
    X: Any
    kind: str
    weight: Any
    R: tuple
    p: tuple
    J: list
    eta: tuple
    psi: tuple
    rows: int = 0
    cols: tuple = ()


def advance(state, R_s, p_s, S_cols, cols_idx, S_qd, Sdot_qd, with_psi):
    """One step g <- g exp(O) = (R_s, p_s): add the step's Jacobian columns S_cols to J's
    columns idx, then update pose, J, eta and psi (docs/physics.md, Magnus steps)."""
    R, p, J, eta, psi = state
    J = list(J)
    for k, col in zip(cols_idx, S_cols):
        J[k] = vadd(J[k], col)
    if with_psi:
        psi = lie.ad_inv_apply(R_s, p_s, vadd(vadd(psi, Sdot_qd), lie.ad(eta, S_qd)))
    eta = lie.ad_inv_apply(R_s, p_s, vadd(eta, S_qd))
    J = [lie.ad_inv_apply(R_s, p_s, c) for c in J]
    R, p = lie.compose(R, p, R_s, p_s)
    return R, p, J, eta, psi


def magnus(xi1, xi2, xd1, xd2, P1, P2, h, with_psi: bool):
    """One 4th-order Magnus (Zanna) step over an interval of length h (m), from the
    strains xi1, xi2 and their rates xd1, xd2 at the two collocation points and the
    scaled basis columns P1, P2 there (6-tuples; any scalar may be an array, e.g.
    one per interval or per column).

    Returns (R_s, p_s) = exp(O), the columns S of the step's Jacobian, S qd and,
    with ``with_psi``, Sdot qd (else None).
    """
    c = mul(lie.SQRT3 / 12.0, mul(h, h))
    half_h = mul(0.5, h)
    # O = h/2 (xi1 + xi2) + sqrt(3) h^2/12 [xi1, xi2]
    O = vadd(vscale(half_h, vadd(xi1, xi2)), vscale(c, lie.ad(xi1, xi2)))
    Od = vadd(vscale(half_h, vadd(xd1, xd2)), vscale(c, vadd(lie.ad(xi1, xd2), lie.ad(xd1, xi2))))
    Z = [
        vadd(vscale(half_h, vadd(a, b)), vscale(c, lie.vsub(lie.ad(xi1, b), lie.ad(xi2, a))))
        for a, b in zip(P1, P2)
    ]
    Zd_qd = vscale(mul(2.0, c), lie.ad(xd1, xd2))
    T_out, T_rate = lie.dexp_and_rate(O, Od, Z + [Od, Zd_qd], rate_of=Od if with_psi else None)
    S_cols, S_qd, T_Zd_qd = T_out[:-2], T_out[-2], T_out[-1]
    Sdot_qd = vadd(T_rate, T_Zd_qd) if with_psi else None
    R_s, p_s = lie.exp_se3(O)
    return R_s, p_s, S_cols, S_qd, Sdot_qd


def zanna_points(grid: LinkGrid) -> tuple[np.ndarray, np.ndarray]:
    return grid.X[:-1] + ZANNA[0] * grid.dX, grid.X[:-1] + ZANNA[1] * grid.dX
