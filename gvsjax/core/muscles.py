"""Distributed internal moments ("muscle torques") as generalized forces on the strain coordinates.

An actuation moment field m(X) along a soft link, in the section's frame (torsion about
the local x axis, bending about y and z), is an active stress acting like the elastic
one: with no other load the rod settles where the elastic moment carries it,
Sigma_w (xi_w - xi*_w) = m, e.g. a uniform bending moment m gives the curvature m / EI.
Its virtual work is int m . delta(xi_w) ds, so the generalized force is

    tau = int_0^L Phi_w(s)^T m(s) ds,

with Phi_w the angular rows of the strain basis. It does not depend on q, and it is
linear in the values the moment is interpolated from, so tau = B u with a constant
matrix B; ``moment_map`` builds B once and ``simulate(..., strain_force=B @ u)``
(or ``gv.equilibrium(..., strain_force=B @ u)``) applies it.

The profile along the link is a clamped uniform cubic B-spline (as the Elastica soft-arm
benchmarks' muscle torques) with ``n_points`` coefficients per component:

    m_c(X) = sum_i N_i(X) u_{c, i},   X in [0, 1].

A clamped spline's ends take the first and last coefficients, the basis sums to one
(equal coefficients give a uniform moment, exactly) and it reproduces any linear
profile when coefficient i is the profile's value at the Greville point X_i (the mean
of the spline's knots i+1 ... i+3; ``control_points``): X_i are where the controls sit
along the link, 0, 1/9, 1/3, 2/3, 8/9, 1 for the default six.
B is integrated exactly: Gauss-Legendre on each knot span, with enough nodes for the
spline's cubics times the basis polynomials.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gvsjax.core.model import STRAIN_NAMES, Robot, SoftLink
from gvsjax.core.validation import require

MOMENT_COMPONENTS = ("torsion", "bend_y", "bend_z")  # the angular strains, in the order of STRAIN_NAMES
DEGREE = 3


def _knots(n_points: int) -> np.ndarray:
    """The clamped, uniform knot vector of a cubic spline with ``n_points`` coefficients on [0, 1]."""
    inner = np.linspace(0.0, 1.0, n_points - DEGREE + 1)
    return np.concatenate([np.zeros(DEGREE), inner, np.ones(DEGREE)])


def _check_points(n_points) -> None:
    require(isinstance(n_points, (int, np.integer)) and not isinstance(n_points, bool) and n_points >= DEGREE + 1,
            "n_points", n_points, f"an int >= {DEGREE + 1} (a cubic spline's coefficients)")


def control_points(n_points: int = 6) -> np.ndarray:
    """The material points X in [0, 1] the spline's coefficients belong to (Greville abscissae)."""
    _check_points(n_points)
    t = _knots(int(n_points))
    return np.array([t[i + 1: i + DEGREE + 1].mean() for i in range(int(n_points))])


def profile(X, n_points: int = 6) -> np.ndarray:
    """The spline's basis at the points X: (len(X), n_points), N_i(X); the moment at X is N(X) @ u_c."""
    _check_points(n_points)
    X = np.clip(np.atleast_1d(np.asarray(X, dtype=float)), 0.0, 1.0)
    t = _knots(int(n_points))
    # Cox-de Boor from degree 0; X = 1 belongs to the last non-empty span (the clamped end)
    last = len(t) - DEGREE - 2
    N = np.stack([((t[i] <= X) & (X < t[i + 1])) | ((i == last) & (X == 1.0)) for i in range(len(t) - 1)],
                 axis=1).astype(float)
    for k in range(1, DEGREE + 1):
        ratio = lambda num, den: np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)  # noqa: E731
        N = np.stack([ratio(X - t[i], t[i + k] - t[i]) * N[:, i] + ratio(t[i + k + 1] - X, t[i + k + 1] - t[i + 1])
                      * N[:, i + 1] for i in range(len(t) - k - 1)], axis=1)
    return N


def moment_map(robot: Robot, link: int = -1, n_points: int = 6,
               components: Sequence[str] = ("bend_y", "bend_z")) -> np.ndarray:
    """B, (robot.n_dofs, len(components) * n_points): the generalized force of spline moments.

    ``strain_force = B @ u`` with u = (u_{c0, 0..n_points-1}, u_{c1, ...}, ...): the moment
    coefficients (N m) of each component in turn, from the link's base to its tip, at
    ``control_points(n_points)``. components: any of "torsion", "bend_y", "bend_z" (moments
    about the section's x, y, z axes; positive along them); a component the link's basis
    leaves inactive gets zero columns (the rod cannot respond to it). Rows of other links'
    and of joint coordinates are zero.
    """
    require(isinstance(link, (int, np.integer)) and not isinstance(link, bool)
            and -len(robot.links) <= link < len(robot.links), "link", link,
            f"an index into robot.links (-{len(robot.links)} ... {len(robot.links) - 1})")
    li = int(link) % len(robot.links)
    soft = robot.links[li]
    require(isinstance(soft, SoftLink), "link", link, "the index of a soft link")
    _check_points(n_points)
    comps = (components,) if isinstance(components, str) else tuple(components)
    require(len(comps) >= 1 and all(c in MOMENT_COMPONENTS for c in comps) and len(set(comps)) == len(comps),
            "components", components, f"distinct names among {list(MOMENT_COMPONENTS)}")
    n_points = int(n_points)
    t = _knots(n_points)
    top = max(soft.basis.orders[:3])
    nodes, weights = np.polynomial.legendre.leggauss((DEGREE + max(top, 0)) // 2 + 1)
    B = np.zeros((robot.n_dofs, len(comps) * n_points))
    _, s0, end = robot.dof_slices()[li]
    spans = np.unique(t)
    for a, b in zip(spans[:-1], spans[1:]):
        for x01, w01 in zip((nodes + 1) / 2, weights / 2):
            X = a + (b - a) * float(x01)
            N = profile(X, n_points)[0]
            # ds = L dX and the angular rows of Phi are Phi_raw / L: the lengths cancel
            raw = soft.basis.raw(X)
            for k, c in enumerate(comps):
                row = STRAIN_NAMES.index(c)
                B[s0:end, k * n_points:(k + 1) * n_points] += (b - a) * float(w01) * np.outer(raw[row], N)
    return B


__all__ = ["moment_map", "control_points", "profile", "MOMENT_COMPONENTS"]
