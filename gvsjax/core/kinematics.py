"""The forward recursion along the chain.

One pass from the base to the tip gives, at every sample point, the world pose
(R, p), the body-frame geometric Jacobian J (6 x n), the body twist eta = J qd
and psi = Jdot qd. Soft links advance between sample points with a 4th-order
Magnus (Zanna collocation) step, as SoRoSim does (Mathew et al. 2023; docs/physics.md,
Magnus steps).

Public helpers return ordinary arrays: ``backbone`` (positions along the
robot), ``tip_state`` (tip position and velocity), ``jacobians`` (J and Jdot at
every sample point).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import chex
import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core import lie, scan
from gvsjax.core.lie import const, mul, vscale, zeros
from gvsjax.core.magnus import (
    Point,
    advance,
    grid_of,
    magnus,
    rest_strain,
    scaled_columns,
    strain,
    strain_rate,
    zanna_points,
)
from gvsjax.core.model import RigidLink, Robot, SoftLink
from gvsjax.core.validation import require


def forward(robot: Robot, q: Sequence, qd: Sequence, with_psi: bool = True,
            jacobian: bool = True) -> list[Point]:
    """Run the base-to-tip recursion and return every sample point.

    q, qd: sequences of n scalars (arrays of shape () or scalar-algebra values).
    ``jacobian=False``: the points' J are left zero (poses and twists are unchanged); the
    pass is then n times smaller, which is what poses and velocities alone need.
    """
    n = robot.n_dofs
    R = lie.const_mat(robot.base_rotation)
    p = zeros(3)
    base = (R, p, [zeros(6)] * n, zeros(6), zeros(6))
    ends: list = []  # the state at each link's far end, where its children start
    points: list[Point] = []
    runs = {g[0]: g for g in scan.chain_groups(robot) if len(g) > 1}
    for li, (link, (j0, s0, end)) in enumerate(zip(robot.links, robot.dof_slices())):
        if len(ends) > li:  # visited by its run's scan
            continue
        parent = robot.parent(li)
        state = base if parent < 0 else ends[parent]
        if link.joint.mounted:
            state = advance(state, lie.const_mat(link.joint.rotation), tuple(const(a) for a in link.joint.offset),
                             [], [], zeros(6), zeros(6), with_psi)
        for k, twist in enumerate(link.joint.twists()):
            phi_j = tuple(const(a) for a in twist)
            O = vscale(q[j0 + k], phi_j)
            Od = vscale(qd[j0 + k], phi_j)
            R_s, p_s = lie.exp_se3(O)
            # one-DoF motion: T(O) Phi_j = Phi_j, so S = Phi_j and Sdot = 0
            state = advance(state, R_s, p_s, [phi_j] if jacobian else [], [j0 + k] if jacobian else [], Od, zeros(6),
                            with_psi)
        if li in runs:  # the links after the first have joints with no DoFs and no offset
            ends += scan.soft_chain(robot, runs[li], q, qd, state, points, with_psi, jacobian)
            continue
        if isinstance(link, SoftLink):
            state = _soft_link(robot, li, link, q[s0:end], qd[s0:end], s0, state, points, with_psi, jacobian)
        else:
            state = _rigid_link(li, link, state, points)
        ends.append(state)
    return points


def _record(points, li, X, kind, weight, state):
    R, p, J, eta, psi = state
    points.append(Point(li, X, kind, weight, R, p, J, eta, psi))


def _magnus_step(state, P1, P2, rest1, rest2, h, qs, qds, idx, with_psi, jacobian=True):
    """Advance the state over one interval of length h (m): P1, P2 are the scaled basis
    columns at the two Zanna points, rest1, rest2 the reference strains there."""
    xi1, xi2 = strain(P1, qs, rest1), strain(P2, qs, rest2)
    xd1, xd2 = strain_rate(P1, qds), strain_rate(P2, qds)
    R_s, p_s, S_cols, S_qd, Sdot_qd = magnus(xi1, xi2, xd1, xd2, P1 if jacobian else [], P2 if jacobian else [],
                                             h, with_psi)
    return advance(state, R_s, p_s, S_cols, idx if jacobian else [], S_qd, Sdot_qd, with_psi)


def _soft_link(robot, li, link, qs, qds, s0, state, points, with_psi, jacobian=True):
    if scan.uses_scan(link, robot.n_dofs):
        return scan.soft_link(robot, li, link, qs, qds, s0, state, points, with_psi, jacobian)
    grid = grid_of(robot, li)
    L = link.length
    inv_L = 1.0 / L
    idx = list(range(s0, s0 + len(qs)))
    x1, x2 = zanna_points(grid)
    _record(points, li, float(grid.X[0]), "soft", mul(const(grid.w[0]), L), state)
    for i in range(len(grid.dX)):
        P1 = scaled_columns(grid.phi1[i], inv_L)
        P2 = scaled_columns(grid.phi2[i], inv_L)
        h = mul(const(grid.dX[i]), L)
        state = _magnus_step(state, P1, P2, rest_strain(link, float(x1[i])), rest_strain(link, float(x2[i])),
                             h, qs, qds, idx, with_psi, jacobian)
        _record(points, li, float(grid.X[i + 1]), "soft", mul(const(grid.w[i + 1]), L), state)
    return state


def _row(pt: Point, i: int) -> Point:
    take = lambda a: a if lie.is_zero(a) else a[i]  # noqa: E731
    J = [zeros(6) if j < 0 else tuple(Jr[i, j] for Jr in pt.J) for j in pt.cols]
    return Point(pt.link, float(pt.X[i]), pt.kind, take(pt.weight), tuple(tuple(map(take, r)) for r in pt.R),
                 tuple(map(take, pt.p)), J, tuple(map(take, pt.eta)), tuple(map(take, pt.psi)))


def rows(points: Sequence[Point]) -> list[Point]:
    """The points with every stacked point split into its rows (one Point per sample)."""
    out: list[Point] = []
    for pt in points:
        out += [_row(pt, i) for i in range(pt.rows)] if pt.rows else [pt]
    return out


def point_at(points: Sequence[Point], link: int, X: float, n_links: int) -> Point:
    """The sample point at material point X of ``link`` (a rigid link's CoM for X < 1)."""
    link %= n_links
    mine = [p for p in points if p.link == link]
    for p in mine:
        if p.rows:
            hit = np.flatnonzero(np.abs(p.X - X) < 1e-12)
            if hit.size:
                return _row(p, int(hit[0]))
        elif p.kind != "rigid" and abs(p.X - X) < 1e-12:
            return p
    rigid = [p for p in mine if p.kind == "rigid"]
    if rigid:  # rigid link: anything but X = 1 acts at the CoM
        return rigid[0]
    raise ValueError(f"no sample point at X={X} of link {link}")


def _translate(state, offset):
    return advance(state, lie.IDENTITY3, offset, [], [], zeros(6), zeros(6), True)


def _rigid_link(li, link: RigidLink, state, points):
    com = tuple(link.com)
    state = _translate(state, com)
    _record(points, li, 0.5, "rigid", 1.0, state)
    tip = (link.length - com[0], -com[1], -com[2])
    state = _translate(state, tip)
    _record(points, li, 1.0, "end", 0, state)
    return state


# ----------------------------------------------------------------------------
# array-level helpers


def sample_sites(robot: Robot) -> list[tuple[int, float]]:
    """(link index, material point X) of every row of ``backbone``/``frames``/``jacobians``,
    in order: a soft link's grid points, a rigid link's centre of mass (X = 0.5) and end (X = 1)."""
    sites: list[tuple[int, float]] = []
    for li, link in enumerate(robot.links):
        if isinstance(link, SoftLink):
            sites += [(li, float(x)) for x in grid_of(robot, li).X]
        else:
            sites += [(li, 0.5), (li, 1.0)]
    return sites


def end_row(robot: Robot, link: int) -> int:
    """The row of ``backbone``/``frames`` at link ``link``'s far end (X = 1)."""
    return sample_sites(robot).index((link % len(robot.links), 1.0))


def coords(robot: Robot, x: Any, name: str) -> jax.Array:
    """``x`` as an array of the robot's n coordinates. A wrong length would otherwise
    be silently cut or padded by the recursion; the check runs at trace time only."""
    x = jnp.asarray(x)
    chex.assert_shape(x, (robot.n_dofs,), custom_message=f"{name} must have shape (n_dofs,) = ({robot.n_dofs},)")
    return x


def _scalars(robot: Robot, x: Any, name: str) -> list:
    x = coords(robot, x, name)
    return [x[i] for i in range(x.shape[0])]


def backbone(robot: Robot, q: jax.Array) -> jax.Array:
    """World positions of every sample point along the robot, shape (n_points, 3)."""
    q_s = _scalars(robot, q, "q")
    pts = rows(forward(robot, q_s, [0] * len(q_s), with_psi=False, jacobian=False))
    return jnp.stack([jnp.stack([lie.as_array(a) for a in pt.p]) for pt in pts])


def frames(robot: Robot, q: jax.Array) -> tuple[jax.Array, jax.Array]:
    """World rotations (n_points, 3, 3) and positions (n_points, 3) of every sample point."""
    q_s = _scalars(robot, q, "q")
    pts = rows(forward(robot, q_s, [0] * len(q_s), with_psi=False, jacobian=False))
    R = jnp.stack([jnp.stack([jnp.stack([lie.as_array(a) for a in row]) for row in pt.R]) for pt in pts])
    p = jnp.stack([jnp.stack([lie.as_array(a) for a in pt.p]) for pt in pts])
    return R, p


def tip_state(robot: Robot, q: jax.Array, qd: jax.Array) -> tuple[jax.Array, jax.Array]:
    """World position (3,) and linear velocity (3,) of the robot's last point (the far end of
    its last link)."""
    pt = rows(forward(robot, _scalars(robot, q, "q"), _scalars(robot, qd, "qd"), with_psi=False,
                       jacobian=False)[-1:])[-1]
    vel = lie.matvec(pt.R, pt.eta[3:])
    return (
        jnp.stack([lie.as_array(a) for a in pt.p]),
        jnp.stack([lie.as_array(a) for a in vel]),
    )


def point_states(robot: Robot, q: jax.Array, qd: jax.Array, points: Sequence[tuple[int, float]]) -> tuple:
    """World positions (k, 3), linear velocities (k, 3) and rotations (k, 3, 3) at the material
    points ``points`` ((link, X) pairs; X in [0, 1]), in their order. One pass of the recursion
    with the points added to its grid (``Robot.sample_points``), without Jacobians."""
    n = len(robot.links)
    for link, X in points:
        require(isinstance(link, (int, np.integer)) and -n <= link < n and 0.0 <= float(X) <= 1.0, "points",
                points, f"(link in [-{n}, {n}), X in [0, 1]) pairs")
    wanted = [(int(link) % n, float(X)) for link, X in points]
    sampled = dataclasses.replace(robot, sample_points=tuple(robot.sample_points) + tuple(wanted))
    pts = rows(forward(sampled, _scalars(robot, q, "q"), _scalars(robot, qd, "qd"), with_psi=False, jacobian=False))
    sites = [(pt.link, float(pt.X)) for pt in pts]
    picked = [pts[_site_index(sites, w)] for w in wanted]
    stack = lambda xs: jnp.stack([lie.as_array(a) for a in xs])  # noqa: E731
    p = jnp.stack([stack(pt.p) for pt in picked])
    v = jnp.stack([stack(lie.matvec(pt.R, pt.eta[3:])) for pt in picked])
    R = jnp.stack([jnp.stack([stack(row) for row in pt.R]) for pt in picked])
    return p, v, R


def _site_index(sites: list, wanted: tuple[int, float]) -> int:
    """The row of a sampled point (a rigid link has rows at its CoM, X = 0.5, and its end, X = 1)."""
    hits = [i for i, (li, x) in enumerate(sites) if li == wanted[0] and abs(x - wanted[1]) < 1e-12]
    require(bool(hits), "points", wanted, "a soft link's material point, or X in (0.5, 1) on a rigid link")
    return hits[0]


def tip_frame(robot: Robot, q: jax.Array) -> tuple[jax.Array, jax.Array]:
    """World rotation (3, 3) and position (3,) of the robot's last point; the rotation's first
    column is the rod's tangent there (its axis, for a soft link)."""
    pt = rows(forward(robot, _scalars(robot, q, "q"), [0] * robot.n_dofs, with_psi=False, jacobian=False)[-1:])[-1]
    R = jnp.stack([jnp.stack([lie.as_array(a) for a in row]) for row in pt.R])
    return R, jnp.stack([lie.as_array(a) for a in pt.p])


def jacobians(robot: Robot, q: jax.Array) -> jax.Array:
    """Body-frame geometric Jacobians at every sample point, shape (n_points, 6, n)."""
    q_s = _scalars(robot, q, "q")
    pts = rows(forward(robot, q_s, [0] * len(q_s), with_psi=False))
    return jnp.stack(
        [jnp.stack([jnp.stack([lie.as_array(a) for a in col]) for col in pt.J], axis=1) for pt in pts]
    )


def jacobian_rates(robot: Robot, q: jax.Array, qd: jax.Array) -> jax.Array:
    """Jdot at every sample point (n_points, 6, n): the derivative of J(q) along qd."""
    return jax.jvp(lambda x: jacobians(robot, x), (q,), (qd,))[1]
