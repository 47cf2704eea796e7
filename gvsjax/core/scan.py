"""The kinematic pass over one soft link as a ``lax.scan`` (``SoftLink.recursion``).

The unrolled pass (``kinematics.forward``) traces one Magnus step per interval and one
scalar chain per Jacobian column, so its compiled program grows with n_gauss
times the DoFs, and XLA's compile time faster still. Here the Magnus steps of all
intervals are traced once (inside the loop, or before it as arrays over the intervals),
and the Jacobian's columns travel as one 6-vector of arrays over the columns, so the
algebra is traced once whatever ``n_gauss`` and the DoFs; a ``lax.scan`` composes the
steps along the link.
The link's samples come back as one stacked ``Point``.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core import lie
from gvsjax.core.lie import mul, vadd, zeros
from gvsjax.core.magnus import XI_STAR, Point, grid_of, magnus, rest_strain, zanna_points
from gvsjax.core.model import SoftLink

# "auto" scans a soft link with at least SCAN_MIN_GAUSS Gauss points when its robot has at least
# SCAN_MIN_DOFS DoFs, or at most HOIST_MAX_DOFS and the link's unrolled pass would be large:
# (n_gauss + 1) intervals x the robot's DoFs x the link's active strains >= SCAN_MIN_SIZE (a 6-DoF
# spatial rod from 4 Gauss points, where its unrolled pass starts to compile for over 15 s; at 3 it
# compiles in ~10 s and steps ~1.8x faster than scanned at batch 1; docs/speed.md)
SCAN_MIN_DOFS, SCAN_MIN_GAUSS, SCAN_MIN_SIZE = 12, 2, 180
# up to this many DoFs the Magnus steps are computed before the loop, beyond it inside: before the
# loop a 6-DoF rod's step ran ~2.5x faster at batch 1; at 12 DoFs no gain was measured above the
# shared machine's noise, so larger robots keep the loop they had (docs/speed.md)
HOIST_MAX_DOFS = 6


def uses_scan(link: SoftLink, n_dofs: int | None = None) -> bool:
    """Whether a soft link's sample points are visited by ``lax.scan`` (one compiled
    composition step) rather than unrolled (one Magnus step per interval); see
    ``SoftLink.recursion``. ``n_dofs``: the DoFs of the robot the link belongs to
    (default: the link's own).

    The robot's size counts, not only the link's: every unrolled sample point feeds
    scalar chains into all n^2 entries of M, so in a large robot even a small
    link's unrolled pass costs more compile time than it saves run time. In a
    small robot the unrolled pass grows with the intervals times the Jacobian's
    columns times the active strains; a planar link (one active strain) stays unrolled."""
    if link.recursion != "auto":
        return link.recursion == "scan"
    n_dofs = link.basis.n_dofs if n_dofs is None else n_dofs
    active = sum(order >= 0 for order in link.basis.orders)
    size = (link.n_gauss + 1) * n_dofs * active
    small = n_dofs <= HOIST_MAX_DOFS and size >= SCAN_MIN_SIZE  # measured on 6 DoFs only
    return link.n_gauss >= SCAN_MIN_GAUSS and (n_dofs >= SCAN_MIN_DOFS or small)


def soft_link(robot, li, link, qs, qds, s0, state, points, with_psi, jacobian=True):
    """``_soft_link`` as a ``lax.scan`` over the intervals, recording one stacked point.

    One Magnus step's algebra is traced whatever ``n_gauss``, and the Jacobian's columns
    travel as one 6-vector of arrays over the columns, whatever the DoFs. The steps
    depend on q and qd only, not on the pose they start from: in a robot of up to
    ``HOIST_MAX_DOFS`` DoFs all intervals' steps are computed at once before the loop
    (arrays over the intervals), which then only composes them along the link; in
    larger robots each step is computed inside the loop. Basis rows that are zero
    everywhere (inactive strains) stay structural zeros and still prune the algebra.
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

    compose, pack, unpack = _carry(n_prev, len(cols), jacobian, with_psi, arr, psi0)

    first = pack(R0, p0, [tuple(J0[k][r] for k in cols) for r in range(6)], eta0, psi0)
    if n <= HOIST_MAX_DOFS:
        leaves, rebuild = _split(_magnus_steps(link, grid, active, scale, qv, qdv, dtype, with_psi, jacobian))

        def body(carry, xs):
            out = pack(*compose(unpack(carry), rebuild(xs)))
            return out, out

        last, ys = jax.lax.scan(body, first, leaves)
    else:
        def looped(carry, x):
            step = _interval_step(x, active, scale, link.length, link.rest_strain is not None, qv, qdv, with_psi,
                                  jacobian)
            out = pack(*compose(unpack(carry), step))
            return out, out

        last, ys = jax.lax.scan(looped, first, _interval_data(link, grid, dtype))
    stacked = jax.tree.map(lambda a, b: jnp.concatenate([a[None], b]), first, ys)
    R, p, J, eta, psi = unpack(stacked)
    points.append(Point(li, grid.X, "soft", mul(jnp.asarray(grid.w, dtype), L), R, p, J, eta, psi,
                        rows=len(grid.X), cols=tuple(cols.index(k) if k in cols else -1 for k in range(n))))
    R, p, J, eta, psi = unpack(last)
    J_list = [zeros(6)] * n
    for j, k in enumerate(cols):
        J_list[k] = tuple(Jr[j] for Jr in J)
    return R, p, J_list, eta, psi


def _carry(n_prev: int, m: int, jacobian: bool, with_psi: bool, arr, psi0) -> tuple:
    """(compose, pack, unpack) of the state (R, p, J, eta, psi) a scan carries along a link: one
    interval's step composed onto it, and the state to and from the loop's carry (24 scalars and J's
    six rows over its m columns, the first ``n_prev`` of them the links' before)."""
    def compose(state, step):
        R, p, J, eta, psi = state
        R_s, p_s, S, S_qd, Sdot_qd = step
        if jacobian:
            J = tuple(jnp.concatenate([Jr[:n_prev], Jr[n_prev:] + lie.as_array(Sr)]) for Jr, Sr in zip(J, S))
            J = lie.ad_inv_apply(R_s, p_s, J)
        if with_psi:
            psi = lie.ad_inv_apply(R_s, p_s, vadd(vadd(psi, Sdot_qd), lie.ad(eta, S_qd)))
        eta = lie.ad_inv_apply(R_s, p_s, vadd(eta, S_qd))
        R, p = lie.compose(R, p, R_s, p_s)
        return R, p, J, eta, psi

    def pack(R, p, J, eta, psi) -> tuple:
        scalars = [*(a for row in R for a in row), *p, *eta, *(psi if with_psi else ())]
        return tuple(arr(a) for a in scalars), tuple(jnp.broadcast_to(arr(c), (m,)) for c in J)

    def unpack(carry) -> tuple:
        f, J = carry
        R = (tuple(f[0:3]), tuple(f[3:6]), tuple(f[6:9]))
        return R, tuple(f[9:12]), tuple(J), tuple(f[12:18]), tuple(f[18:24]) if with_psi else psi0

    return compose, pack, unpack


def chain_groups(robot) -> list[list[int]]:
    """The robot's links in runs that one ``lax.scan`` visits (``soft_chain``); a run of one is a
    link on its own. A link continues its parent's run when both are scanned soft links of a robot
    with more than ``HOIST_MAX_DOFS`` DoFs, it sits on its parent's end by a joint with no DoFs and
    no offset, it is the parent's only child, and both have the same number of strain coordinates.
    A chain of n such links then traces one Magnus step, not n."""
    n = robot.n_dofs
    children = [sum(robot.parent(j) == i for j in range(len(robot.links))) for i in range(len(robot.links))]

    def scanned(li):
        link = robot.links[li]
        return isinstance(link, SoftLink) and uses_scan(link, n)

    groups: list[list[int]] = []
    for li, link in enumerate(robot.links):
        prev = robot.parent(li)
        joins = (n > HOIST_MAX_DOFS and groups and groups[-1][-1] == prev and scanned(li) and scanned(prev)
                 and link.joint.n_dofs == 0 and not link.joint.mounted and children[prev] == 1
                 and link.basis.n_dofs == robot.links[prev].basis.n_dofs)
        if joins:
            groups[-1].append(li)
        else:
            groups.append([li])
    return groups


def soft_chain(robot, lis, q, qd, state, points, with_psi, jacobian=True) -> list:
    """``soft_link`` over a run of links (``chain_groups``) in one ``lax.scan``: their intervals
    follow each other, each with its link's basis embedded in the run's columns, so one Magnus
    step is traced for the whole run. Records one stacked ``Point`` per link, as ``soft_link``
    does, and returns the state at each link's far end (None but for the last: only the run's
    next link starts from an inner link's end)."""
    slices = robot.dof_slices()
    links = [robot.links[li] for li in lis]
    grids = [grid_of(robot, li) for li in lis]
    s0, end = slices[lis[0]][1], slices[lis[-1]][2]
    offsets = [slices[li][1] - s0 for li in lis]
    qs, qds = q[s0:end], qd[s0:end]
    n_g = end - s0
    dtype = jnp.result_type(*(lie.as_array(x) for x in (*qs, *(link.length for link in links))))
    R0, p0, J0, eta0, psi0 = state
    n = len(J0)
    cols = [k for k in range(s0) if any(not lie.is_zero(a) for a in J0[k])] + list(range(s0, end))
    if not jacobian:
        cols = []
    n_prev = len(cols) - n_g
    arr = lambda a: jnp.asarray(lie.as_array(a), dtype)  # noqa: E731
    vec = lambda xs: 0 if all(lie.is_zero(x) for x in xs) else jnp.stack([arr(x) for x in xs])  # noqa: E731
    qv, qdv = vec(qs), vec(qds)
    active = [any(bool(np.any(g.phi1[:, r]) or np.any(g.phi2[:, r])) for g in grids) for r in range(6)]
    with_rest = any(link.rest_strain is not None for link in links)

    def embed(phi, k):  # (n_int, 6, n_s) -> (n_int, 6, n_g), scaled: SoRoSim's 1/L on the angular rows
        scale = jnp.stack([arr(1.0 / links[k].length)] * 3 + [arr(1.0)] * 3)
        out = jnp.zeros(phi.shape[:2] + (n_g,), dtype)
        return out.at[:, :, offsets[k]:offsets[k] + phi.shape[2]].set(jnp.asarray(phi, dtype) * scale[:, None])

    data: dict[str, Any] = dict(
        h=jnp.concatenate([jnp.asarray(g.dX, dtype) * arr(link.length) for g, link in zip(grids, links)]),
        phi1=jnp.concatenate([embed(g.phi1, k) for k, g in enumerate(grids)]),
        phi2=jnp.concatenate([embed(g.phi2, k) for k, g in enumerate(grids)]))
    if with_rest:
        for i, key in enumerate(("rest1", "rest2")):
            data[key] = jnp.concatenate([
                jnp.stack([jnp.broadcast_to(arr(c), x.shape) for c in rest_strain(link, x)], axis=1)
                for link, g in zip(links, grids) for x in (zanna_points(g)[i],)])

    compose, pack, unpack = _carry(n_prev, len(cols), jacobian, with_psi, arr, psi0)

    def looped(carry, x):
        step = _interval_step(x, active, [1.0] * 6, 1.0, with_rest, qv, qdv, with_psi, jacobian)
        out = pack(*compose(unpack(carry), step))
        return out, out

    first = pack(R0, p0, [tuple(J0[k][r] for k in cols) for r in range(6)], eta0, psi0)
    # rematerialised under reverse-mode AD: the transposed loop recomputes a step from its carry
    # rather than reading hundreds of per-step residuals, each its own in-place write in the loop
    last, ys = jax.lax.scan(jax.checkpoint(looped), first, data)
    stacked = jax.tree.map(lambda a, b: jnp.concatenate([a[None], b]), first, ys)
    start = 0
    for k, (li, link, g) in enumerate(zip(lis, links, grids)):
        rows = slice(start, start + len(g.X))
        start += len(g.dX)
        mine = cols[:n_prev + offsets[k] + link.basis.n_dofs] if jacobian else []
        f, J = stacked
        R, p, Jk, eta, psi = unpack((tuple(a[rows] for a in f), tuple(Jr[rows, :len(mine)] for Jr in J)))
        points.append(Point(li, g.X, "soft", mul(jnp.asarray(g.w, dtype), link.length), R, p, Jk, eta, psi,
                            rows=len(g.X), cols=tuple(mine.index(c) if c in mine else -1 for c in range(n))))
    R, p, J, eta, psi = unpack(last)
    J_list = [zeros(6)] * n
    for j, c in enumerate(cols):
        J_list[c] = tuple(Jr[j] for Jr in J)
    return [None] * (len(lis) - 1) + [(R, p, J_list, eta, psi)]


def _interval_data(link, grid, dtype) -> dict[str, Any]:
    """The scan's per-interval inputs: lengths h (n_int,), the raw basis at the two Zanna points
    phi1, phi2 (n_int, 6, n_s) and, with a rest strain, its values there rest1, rest2 (n_int, 6)."""
    xs: dict[str, Any] = dict(h=jnp.asarray(grid.dX, dtype), phi1=jnp.asarray(grid.phi1, dtype),
                              phi2=jnp.asarray(grid.phi2, dtype))
    if link.rest_strain is not None:
        for key, x in zip(("rest1", "rest2"), zanna_points(grid)):
            xs[key] = jnp.stack([jnp.broadcast_to(lie.as_array(c), x.shape) for c in rest_strain(link, x)], axis=1)
    return xs


def _interval_step(x, active, scale, length, with_rest, qv, qdv, with_psi, jacobian) -> tuple:
    """One interval's Magnus step inside the loop, from its slice ``x`` of ``_interval_data``
    (intervals of ``length`` times x["h"]; the basis scaled by ``scale`` per row; x["rest1"] and
    x["rest2"] read when ``with_rest``): (R_s, p_s, S (6 entries of shape (n_s,)), S_qd, Sdot_qd)."""
    def combine(P, v):  # sum_k P[:, k] v_k for a stacked basis P (6 entries of shape (n_s,))
        return tuple(0 if lie.is_zero(Pr) or lie.is_zero(v) else Pr @ v for Pr in P)

    P1, P2 = (tuple(mul(x[k][r], scale[r]) if active[r] else 0 for r in range(6)) for k in ("phi1", "phi2"))
    rest1, rest2 = (XI_STAR, XI_STAR) if not with_rest else (
        tuple(x["rest1"][r] for r in range(6)), tuple(x["rest2"][r] for r in range(6)))
    xi1, xi2 = vadd(rest1, combine(P1, qv)), vadd(rest2, combine(P2, qv))
    R_s, p_s, S_cols, S_qd, Sdot_qd = magnus(xi1, xi2, combine(P1, qdv), combine(P2, qdv),
                                             [P1] if jacobian else [], [P2] if jacobian else [],
                                             mul(x["h"], length), with_psi)
    return R_s, p_s, S_cols[0] if jacobian else (), S_qd, Sdot_qd


def _magnus_steps(link, grid, active, scale, qv, qdv, dtype, with_psi, jacobian) -> tuple:
    """Every interval's Magnus step (``magnus``'s outputs) at once: each scalar an array of
    shape (n_int,) (a structural zero, a constant or a shape-() array when the same for all),
    the Jacobian's columns S of shape (n_int, n_s)."""
    n_int = len(grid.dX)
    # a trailing axis of 1 on the strains, so that they broadcast against the columns (n_int, n_s)
    P1, P2 = (tuple(jnp.asarray(phi[:, r, :] * scale[r], dtype) if active[r] else 0 for r in range(6))
              for phi in (grid.phi1, grid.phi2))
    rest1: tuple
    rest2: tuple
    if link.rest_strain is None:
        rest1 = rest2 = XI_STAR
    else:
        rest1, rest2 = (tuple(jnp.broadcast_to(lie.as_array(c), x.shape)[:, None].astype(dtype)
                              for c in rest_strain(link, x)) for x in zanna_points(grid))

    def combine(P, x):  # sum_k P[:, k] x_k, (n_int, 1)
        return tuple(0 if lie.is_zero(Pr) or lie.is_zero(x) else (Pr @ x)[:, None] for Pr in P)

    xi1, xi2 = vadd(rest1, combine(P1, qv)), vadd(rest2, combine(P2, qv))
    h = mul(jnp.asarray(grid.dX, dtype)[:, None], link.length)
    R_s, p_s, S_cols, S_qd, Sdot_qd = magnus(xi1, xi2, combine(P1, qdv), combine(P2, qdv),
                                             [P1] if jacobian else [], [P2] if jacobian else [], h, with_psi)
    flat = lambda a: a if lie.is_zero(a) or np.ndim(a) == 0 else jnp.broadcast_to(a, (n_int, 1))[:, 0]  # noqa: E731
    S = tuple(0 if lie.is_zero(a) else jnp.broadcast_to(a, (n_int, grid.phi.shape[2])) for a in S_cols[0]) \
        if jacobian else ()
    return (tuple(tuple(map(flat, row)) for row in R_s), tuple(map(flat, p_s)), S, tuple(map(flat, S_qd)),
            tuple(map(flat, Sdot_qd)) if with_psi else None)


def _split(tree) -> tuple[list, Any]:
    """The arrays with a leading interval axis of a nest of tuples, and a function that rebuilds the
    nest from one slice of each (structural zeros, constants and shape-() arrays kept as they are)."""
    leaves: list = []

    def walk(x):
        if isinstance(x, tuple):
            parts = [walk(a) for a in x]
            return lambda vals: tuple(f(vals) for f in parts)
        if x is None or lie.is_zero(x) or np.ndim(x) == 0:
            return lambda vals: x
        leaves.append(x)
        k = len(leaves) - 1
        return lambda vals: vals[k]

    return leaves, walk(tree)
