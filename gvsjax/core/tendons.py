"""Generalized forces of tendons (cables) from their tensions.

A cable at offset d(s) in the section frame runs, in the deformed rod, along
p_c(s) = p(s) + R(s) d(s), whose tangent in the section frame is
v + w x d + d' (v, w: the linear and angular strain, d' = dd/ds). Its length is
l(q) = integral of |v + w x d + d'| ds, and the work of a tension T pulling it
is -T dl. Varying the strain (d does not depend on q):

    dl/dq = integral of Phi(s)^T (d x t, t) ds,   t = unit(v + w x d + d').

Only the strain at the quadrature points enters: no frames, no Jacobians. The
same expression contains every effect a force-based cable model adds up
separately (the distributed load where the cable curves, the point forces where
it ends and where its direction jumps), because those are what dl/dq is made of
(Renda et al. 2018 derive the straight case in GVS; the routed case is the same
variation with d' kept). Routed paths are integrated piece by piece between
knots, so a kink is integrated exactly at its location.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core import lie
from gvsjax.core.lie import add, const, dot, mul, vadd, vscale
from gvsjax.core.magnus import grid_of, rest_strain, scaled_columns, strain
from gvsjax.core.model import Robot, RoutedTendon, SoftLink, Tendon, TendonPath


def generalized_force(robot: Robot, q: Sequence, tension: Sequence) -> list:
    """-T dl/dq summed over the robot's tendons (n scalars; zero where no tendon acts).

    q: n scalars; tension: one value per ``robot.tendons`` entry (N, >= 0)."""
    tau: list = [0] * robot.n_dofs
    slices = robot.dof_slices()
    for td, T in zip(robot.tendons, tension):
        if isinstance(td, Tendon):
            li = td.link % len(robot.links)
            _straight(robot, li, td, q, T, slices[li], tau)
        else:
            for path in td.paths:
                li = path.link % len(robot.links)
                _routed(robot.links[li], path, q, T, slices[li], tau)
    return tau


def _accumulate(tau, cols, s0, coef, d, dd, xi) -> None:
    """tau[s0 + k] += coef * Phi_k . (d x t, t), t = unit(v + w x d + d')."""
    t_raw = vadd(vadd(lie.cross(xi[:3], d), xi[3:]), dd)
    inv_norm = 1.0 / jnp.sqrt(lie.as_array(dot(t_raw, t_raw)))
    t = vscale(inv_norm, t_raw)
    screw = lie.cross(d, t) + t
    for k, col in enumerate(cols):
        tau[s0 + k] = add(tau[s0 + k], mul(coef, dot(col, screw)))


def _straight(robot: Robot, li: int, td: Tendon, q, T, slc, tau) -> None:
    """A straight tendon parallel to the midline over the whole link (d' = 0), on the
    link's own quadrature points."""
    link = robot.links[li]
    _, s0, end = slc
    grid = grid_of(robot, li)
    d = (0, mul(td.offset, const(td.direction[0])), mul(td.offset, const(td.direction[1])))
    inv_L = 1.0 / link.length
    for i in range(len(grid.X)):
        if grid.w[i] == 0.0:
            continue
        cols = scaled_columns(grid.phi[i], inv_L)
        xi = strain(cols, q[s0:end], rest_strain(link, float(grid.X[i])))
        coef = mul(mul(T, const(-grid.w[i])), link.length)
        _accumulate(tau, cols, s0, coef, d, (0, 0, 0), xi)


def _routed(link: SoftLink, path: TendonPath, q, T, slc, tau) -> None:
    _, s0, end = slc
    nodes, weights = np.polynomial.legendre.leggauss(path.n_quad)
    inv_L = 1.0 / link.length
    dtype = jnp.result_type(*(lie.as_array(x) for x in q[s0:end]))  # float32 stays float32
    for piece, (a, b) in enumerate(path.pieces):
        for x01, w01 in zip((nodes + 1) / 2, weights / 2):
            X = a + (b - a) * float(x01)
            d_yz, dd_yz = _offset(path, piece, X, dtype)
            d = (0, d_yz[0], d_yz[1])
            dd = (0, mul(dd_yz[0], inv_L), mul(dd_yz[1], inv_L))  # d/dX -> d/ds
            cols = scaled_columns(link.basis.raw(X), inv_L)
            xi = strain(cols, q[s0:end], rest_strain(link, X))
            coef = mul(mul(T, const(-(b - a) * float(w01))), link.length)
            _accumulate(tau, cols, s0, coef, d, dd, xi)


def _offset(path: TendonPath, piece: int, X: float, dtype) -> tuple[tuple, tuple]:
    """d(X) = (y, z) and dd/dX on ``piece`` (straight between knots, or the path function), in ``dtype``."""
    if path.path is not None:
        d, dd = jax.jvp(lambda x: jnp.reshape(jnp.asarray(path.path(x)), (2,)).astype(dtype),
                        (jnp.asarray(X, dtype),), (jnp.asarray(1.0, dtype),))
        return (d[0], d[1]), (dd[0], dd[1])
    off = jnp.asarray(path.offsets).astype(dtype)
    a, b = path.knots[piece], path.knots[piece + 1]
    lo, hi = off[piece], off[piece + 1]
    slope = (hi - lo) / (b - a)
    d = lo + slope * (X - a)
    return (d[0], d[1]), (slope[0], slope[1])


def cable_length(robot: Robot, tendon: RoutedTendon, q: jax.Array) -> jax.Array:
    """The routed cable's length in the configuration q (m): the quantity whose gradient,
    times -T, is the generalized force above (``jax.grad`` of it checks that force)."""
    total = jnp.zeros((), jnp.result_type(q))
    slices = robot.dof_slices()
    for path in tendon.paths:
        li = path.link % len(robot.links)
        link = robot.links[li]
        _, s0, end = slices[li]
        nodes, weights = np.polynomial.legendre.leggauss(path.n_quad)
        inv_L = 1.0 / link.length
        for piece, (a, b) in enumerate(path.pieces):
            for x01, w01 in zip((nodes + 1) / 2, weights / 2):
                X = a + (b - a) * float(x01)
                d_yz, dd_yz = _offset(path, piece, X, total.dtype)
                cols = scaled_columns(link.basis.raw(X), inv_L)
                xi = strain(cols, [q[i] for i in range(s0, end)], rest_strain(link, X))
                w = jnp.stack([lie.as_array(c) for c in xi[:3]])
                v = jnp.stack([lie.as_array(c) for c in xi[3:]])
                d = jnp.stack([0.0 * d_yz[0], d_yz[0], d_yz[1]])
                tangent = v + jnp.cross(w, d) + jnp.stack([0.0 * d_yz[0], dd_yz[0], dd_yz[1]]) * inv_L
                total = total + (b - a) * float(w01) * link.length * jnp.linalg.norm(tangent)
    return total
