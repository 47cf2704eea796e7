"""Contact between the robot and obstacles: a smooth penalty with regularised Coulomb friction.

The rod is a tube: every point within the section's radius (circumscribed
circle for ellipses and rectangles; ``taper`` scales it) of the centreline.
Each soft link carries ``n_points`` contact samples, uniform in X (ends
included, spacing h = L / (n_points - 1)). Sample k stands for the straight
piece of tube along its local tangent, u in [-h/2, h/2] (half of that at the
link's ends), so the pieces tile the rod without gaps: an obstacle of any
width is found, wherever it lies between samples. The piece departs from the
curved centreline by at most kappa h^2 / 8 (kappa: curvature, 1/m), the
sampling's only geometric error. The penalty per unit length is integrated
over each piece in closed form from the obstacle's overlap profile (parabolic
for spheres and capsules, linear for planes and box faces), so the force on a
straight rod does not depend on where an obstacle sits between samples.
Rigid links touch at ``ContactSite`` balls fixed in their frame.

Normal force, per metre of rod (per site for rigid links), at gap g (m):
``k delta(g) + c chi(g) (-v_n)``, clipped at 0 (no adhesion), with the smooth
penetration ``delta = l softplus(-g / l)`` and indicator ``chi = sigmoid(-g /
l)`` (l: smoothing length). Friction: ``-mu f_n v_t / sqrt(|v_t|^2 + v_s^2)``
on the slip velocity v_t of the rod's surface point against the obstacle's:
Coulomb's law for |v_t| >> v_s, a viscous creep below. See docs/contact.md.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax import lie
from gvsjax.kinematics import forward
from gvsjax.lie import zeros
from gvsjax.magnus import ZANNA, Point, advance, grid_of, magnus, rest_strain, strain, strain_rate
from gvsjax.model import RigidLink, Robot, SoftLink
from gvsjax.obstacles import OBSTACLES, Box, Capsule, Plane, Sphere
from gvsjax.stacked_contact import curved_area, smooth_depth, stacked_law
from gvsjax.validation import concrete, finite, integer, nonnegative, positive, require


@struct.dataclass
class Penalty:
    """Contact law parameters. For soft links stiffness is N/m per metre of rod (N/m^2) and
    damping N s/m per metre (N s/m^2); for rigid sites, N/m and N s/m.

    smoothing: length l of the softplus (m); friction: Coulomb's mu; slip_speed: the
    regularisation speed v_s (m/s) below which friction turns viscous (a creep)."""

    stiffness: Any = 1e7
    damping: Any = 5e3
    smoothing: Any = 1e-5
    friction: Any = 0.0
    slip_speed: Any = 1e-2


@struct.dataclass
class ContactSite:
    """A contact ball of ``radius`` (m) at ``offset`` (3,) (m, in the joint frame of rigid link
    ``link``, as ``RigidLink.com``)."""

    offset: Any = (0.0, 0.0, 0.0)
    radius: Any = 0.0
    link: int = struct.field(pytree_node=False, default=-1)


@struct.dataclass
class Contact:
    """Obstacles and how the robot touches them (``Robot.contact``).

    obstacles: a tuple of ``Plane``, ``Sphere``, ``Capsule``, ``Box``; rod: the penalty on
    soft links (per metre); site: the penalty at rigid ``sites``; n_points: contact samples
    per soft link (static), see ``points_for`` to choose it.
    """

    obstacles: tuple = ()
    rod: Penalty = Penalty()
    site: Penalty = Penalty(stiffness=1e5, damping=200.0, smoothing=1e-4)
    sites: tuple = ()
    n_points: int = struct.field(pytree_node=False, default=21)

    def validate(self, robot: Robot) -> None:
        """``check_robot``'s hook: ``check`` (a bad value raises, naming it)."""
        check(robot)

    def material_points(self, link: SoftLink) -> tuple[float, ...]:
        """The contact samples' X on a soft link."""
        return tuple(float(x) for x in np.linspace(0.0, 1.0, self.n_points))


def points_for(length: float, curvature: float, error: float = 1e-3) -> int:
    """Contact samples per link so that the straight pieces stay within ``error`` (m) of a
    centreline of curvature up to ``curvature`` (1/m): kappa h^2 / 8 <= error."""
    h = np.sqrt(8.0 * error / max(curvature, 1e-12))
    return int(max(2, np.ceil(length / h) + 1))


# ----------------------------------------------------------------------------
# the law at one sample (broadcasts over leading axes)


def _flat_area(gap, slope, u, lo, hi, l):
    """For a gap linear along the piece (gap at u, d gap/du = slope): the integral over [lo, hi]
    of the depth, smoothed at the deepest end and falling linearly from there while
    positive; the length where it is positive, and its middle (where the force acts)."""
    deep = jnp.where(slope > 0, lo, hi)
    s = jnp.maximum(jnp.abs(slope), 1e-12)
    peak = smooth_depth(gap + slope * (deep - u), l)
    length = jnp.minimum(peak / s, hi - lo)
    middle = jnp.where(slope > 0, lo + length / 2, hi - length / 2)
    return length * (peak - s * length / 2), length, middle


def _groups(obstacles) -> list[tuple[Any, bool]]:
    """The obstacles, the static spheres and the static capsules each stacked into one (leaves with
    a leading axis) when there are several: the law then runs once over all of a kind."""
    stackable = lambda o, kind: type(o) is kind and o.motion is None  # noqa: E731
    out: list[tuple[Any, bool]] = []
    rest = list(obstacles)
    for kind in (Sphere, Capsule):
        same = [o for o in obstacles if stackable(o, kind)]
        if len(same) > 1:
            # as arrays first: a leaf given as a tuple of floats is a pytree of floats
            same = [o.replace(**{f.name: jnp.asarray(getattr(o, f.name)) for f in dataclasses.fields(o)
                                 if f.name != "motion"}) for o in same]
            out.append((jax.tree.map(lambda *a: jnp.stack(a), *same), True))
            rest = [o for o in rest if not stackable(o, kind)]
    return out + [(o, False) for o in rest]


def _pair(obs, p, tangent, omega, vel, radius, lo, hi, pen: Penalty, t):
    """One obstacle's (or a stack's) world force and moment about the centre on a piece or site,
    and its gap (``law``'s arguments; lo None: a site)."""
    l = pen.smoothing
    point = lo is None
    pc = obs.piece(p, tangent, 0.0 if point else lo, 0.0 if point else hi, t)
    g = pc.gap - radius
    if point:
        area, length, u = smooth_depth(g, l), 1.0, pc.u
    elif isinstance(obs, (Plane, Box)):
        area, length, u = _flat_area(g, pc.slope, pc.u, lo, hi, l)
        g = g + pc.slope * (jnp.where(pc.slope > 0, lo, hi) - pc.u)  # at the deepest end
    else:
        area, length, u = curved_area(g, pc.curvature, pc.u, pc.centre, lo, hi, l)
    chi = jax.nn.sigmoid(-g / l)
    arm = u[..., None] * tangent - radius[..., None] * pc.normal  # centre -> surface point
    v_rel = vel + jnp.cross(omega, arm) - pc.velocity
    v_n = jnp.sum(v_rel * pc.normal, axis=-1)
    f_n = jnp.maximum(pen.stiffness * area - pen.damping * chi * v_n * length, 0.0)
    v_t = v_rel - v_n[..., None] * pc.normal
    slip = jnp.sqrt(jnp.sum(v_t * v_t, axis=-1) + pen.slip_speed**2)
    f = f_n[..., None] * (pc.normal - pen.friction * v_t / slip[..., None])
    return f, jnp.cross(arm, f), g


def law(p, R, eta, radius, lo, hi, obstacles, pen: Penalty, t):
    """The contact wrench on one rod piece or site from every obstacle.

    p (..., 3) world centre, R (..., 3, 3) world rotation (column 0: the tangent), eta
    (..., 6) body twist (angular, linear); radius (...) m; lo, hi: the piece's extent along
    the tangent (m; None for a site: a ball, forces per site). Returns (body wrench (..., 6):
    moment N m, force N, in the section's frame; world force (..., 3) N; the smallest gap
    over the obstacles (...), m, negative when penetrating).
    """
    tangent = R[..., :, 0]
    omega, vel = jnp.einsum("...ij,...j->...i", R, eta[..., :3]), jnp.einsum("...ij,...j->...i", R, eta[..., 3:])
    force = jnp.zeros_like(p)
    moment = jnp.zeros_like(p)
    gap_min = jnp.full(p.shape[:-1], jnp.inf, p.dtype)
    for obs, stacked in _groups(obstacles):
        if stacked and lo is not None:
            f3, m3, g = stacked_law(obs, p, tangent, omega, vel, radius, lo, hi, pen)
            force, moment = force + jnp.stack(f3, -1), moment + jnp.stack(m3, -1)
            gap_min = jnp.minimum(gap_min, g)
            continue
        # a stack of obstacles is one more axis before the vectors' (summed over below)
        x = (lambda a: a[..., None, :]) if stacked else (lambda a: a)  # noqa: E731
        y = (lambda a: a if a is None else jnp.asarray(a)[..., None]) if stacked else (lambda a: a)  # noqa: E731
        f, m, g = _pair(obs, x(p), x(tangent), x(omega), x(vel), y(radius), y(lo), y(hi), pen, t)
        if stacked:
            f, m, g = jnp.sum(f, axis=-2), jnp.sum(m, axis=-2), jnp.min(g, axis=-1)
        force = force + f
        moment = moment + m
        gap_min = jnp.minimum(gap_min, g)
    body = jnp.concatenate([jnp.einsum("...ji,...j->...i", R, moment),
                            jnp.einsum("...ji,...j->...i", R, force)], axis=-1)
    return body, force, gap_min


# ----------------------------------------------------------------------------
# the robot's contact samples


def _stack(xs: list, n_c: int):
    """One scalar per sample as a (n_c,) scalar; a structural zero when every one is."""
    if all(lie.is_zero(x) for x in xs):
        return 0
    return jnp.stack([jnp.broadcast_to(lie.as_array(x), ()) for x in xs])


def _columns(raw: np.ndarray, inv_length, dtype) -> list[tuple]:
    """``magnus.scaled_columns`` for per-sample raw bases (n_c, 6, n): (n_c,) scalars."""
    return [tuple(0 if not np.any(raw[:, r, k]) else
                  (jnp.asarray(raw[:, r, k], dtype) * inv_length if r < 3 else jnp.asarray(raw[:, r, k], dtype))
                  for r in range(6)) for k in range(raw.shape[2])]


def _rows(pt: Point, base: np.ndarray, n: int):
    """A stacked point's (R, p, J, eta) at grid rows ``base``, as (n_c,) scalars and n Jacobian columns."""
    sel = lambda x: 0 if lie.is_zero(x) else lie.as_array(x)[base]  # noqa: E731
    R = tuple(tuple(sel(a) for a in row) for row in pt.R)
    J = [zeros(6) if pt.cols[k] < 0 else
         tuple(0 if lie.is_zero(Jr) else lie.as_array(Jr)[base, pt.cols[k]] for Jr in pt.J) for k in range(n)]
    return R, tuple(sel(a) for a in pt.p), J, tuple(sel(a) for a in pt.eta)


def _soft_samples(robot: Robot, li: int, link: SoftLink, points: list[Point], q, qd):
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
        R, p, J, eta = _rows(grid_pts[0], base, robot.n_dofs)
    else:
        pick = [grid_pts[i] for i in base]
        R = tuple(tuple(_stack([pt.R[a][b] for pt in pick], n_c) for b in range(3)) for a in range(3))
        p = tuple(_stack([pt.p[a] for pt in pick], n_c) for a in range(3))
        eta = tuple(_stack([pt.eta[a] for pt in pick], n_c) for a in range(6))
        J = [tuple(_stack([pt.J[k][a] for pt in pick], n_c) for a in range(6)) for k in range(len(pick[0].J))]
    j0, s0, end = robot.dof_slices()[li]
    qs, qds = q[s0:end], qd[s0:end]
    dtype = jnp.result_type(*(lie.as_array(x) for x in (*qs, *qds, *p)))  # float32 runs stay float32
    L = link.length
    x1, x2 = grid.X[base] + ZANNA[0] * dX, grid.X[base] + ZANNA[1] * dX
    P1 = _columns(np.stack([link.basis.raw(x) for x in x1]), 1.0 / L, dtype)
    P2 = _columns(np.stack([link.basis.raw(x) for x in x2]), 1.0 / L, dtype)
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


def _arrays(R, p, eta, n_c: int):
    full = lambda x: jnp.broadcast_to(lie.as_array(x), (n_c,))  # noqa: E731
    return (jnp.stack([jnp.stack([full(a) for a in row], -1) for row in R], -2),
            jnp.stack([full(a) for a in p], -1), jnp.stack([full(a) for a in eta], -1))


def evaluate(robot: Robot, points: list[Point], q, qd, t) -> tuple[list, list, list]:
    """The contact at every sample: (generalized force, n scalars; world forces, one (n_c, 3)
    per soft link and one (3,) per site, N; gaps likewise, m). q, qd: n scalars each."""
    contact = robot.contact
    F: list = [0] * robot.n_dofs
    forces, gaps = [], []
    for li, link in enumerate(robot.links):
        if not isinstance(link, SoftLink):
            continue
        Xc = np.asarray(contact.material_points(link))
        n_c = len(Xc)
        Rs, ps, etas, pull = _soft_samples(robot, li, link, points, q, qd)
        R, p, eta = _arrays(Rs, ps, etas, n_c)
        half = 0.5 * float(Xc[1] - Xc[0]) * link.length  # the piece around each sample: half a spacing each way
        lo = -half * jnp.asarray(np.arange(n_c) > 0, dtype=p.dtype)
        hi = half * jnp.asarray(np.arange(n_c) < n_c - 1, dtype=p.dtype)
        w, f, g = law(p, R, eta, _radius(link, Xc, p.dtype), lo, hi, contact.obstacles, contact.rod, t)
        terms = pull(tuple(w[:, k] for k in range(6)))
        live = [j for j, x in enumerate(terms) if not lie.is_zero(x)]
        if live:  # one reduction for every column: XLA would repeat the columns' shared work in each
            Fs = jnp.sum(jnp.stack([jnp.broadcast_to(terms[j], (n_c,)) for j in live], -1), axis=0)
            for k, j in enumerate(live):
                F[j] = lie.add(F[j], Fs[k])
        forces.append(f)
        gaps.append(g)
    n = len(robot.links)
    for site in contact.sites:
        link = robot.links[site.link % n]
        pt = next(x for x in points if x.link == site.link % n and x.kind == "rigid")
        R, p, eta = (a[0] for a in _arrays(pt.R, pt.p, pt.eta, 1))
        d = jnp.asarray(site.offset, p.dtype) - jnp.asarray(link.com, p.dtype)  # from the CoM, body frame
        eta_s = jnp.concatenate([eta[:3], eta[3:] + jnp.cross(eta[:3], d)])
        w, f, g = law(p + R @ d, R, eta_s, jnp.asarray(site.radius, p.dtype), None, None, contact.obstacles,
                      contact.site, t)
        w = jnp.concatenate([w[:3] + jnp.cross(d, w[3:]), w[3:]])  # moved to the CoM
        for j, col in enumerate(pt.J):
            F[j] = lie.add(F[j], lie.dot(col, tuple(w[k] for k in range(6))))
        forces.append(f[None])
        gaps.append(g[None])
    return F, forces, gaps


def _sum(x):
    return 0 if lie.is_zero(x) else jnp.sum(x)


def _radius(link: SoftLink, X, dtype):
    half = link.radius if link.shape == "circle" else 0.5 * jnp.hypot(link.width, link.height)
    return half * (1.0 + (link.taper - 1.0) * jnp.asarray(X, dtype))


def report(robot: Robot, q, qd, t) -> tuple[jax.Array, jax.Array]:
    """World contact force on the robot at every contact sample (n_c, 3), N (a soft sample's is
    the total over its piece of rod), and each sample's smallest gap (n_c,), m (negative:
    penetrating); rows as ``sites``. q, qd: (n,) arrays."""
    if robot.contact is None:
        return jnp.zeros((0, 3), q.dtype), jnp.zeros((0,), q.dtype)
    n = robot.n_dofs
    qs, qds = [q[i] for i in range(n)], [qd[i] for i in range(n)]
    _, forces, gaps = evaluate(robot, forward(robot, qs, qds, with_psi=False, jacobian=False), qs, qds, t)
    return jnp.concatenate(forces), jnp.concatenate(gaps)


def sites(robot: Robot) -> list[tuple[int, Any]]:
    """(link, X or site index) of every row of the contact report, in order."""
    if robot.contact is None:
        return []
    rows: list[tuple[int, Any]] = []
    for li, link in enumerate(robot.links):
        if isinstance(link, SoftLink):
            rows += [(li, X) for X in robot.contact.material_points(link)]
    rows += [(s.link % len(robot.links), f"site {k}") for k, s in enumerate(robot.contact.sites)]
    return rows


def check(robot: Robot) -> None:
    """Validate ``robot.contact`` (concrete leaves only), naming the bad parameter."""
    c = robot.contact
    if c is None:
        return
    require(isinstance(c, Contact), "contact", type(c).__name__, "None or a gvsjax.Contact")
    integer("contact.n_points", c.n_points, low=2)
    for name, pen in (("contact.rod", c.rod), ("contact.site", c.site)):
        require(isinstance(pen, Penalty), name, type(pen).__name__, "a Penalty")
        positive(f"{name}.stiffness", pen.stiffness)
        nonnegative(f"{name}.damping", pen.damping)
        positive(f"{name}.smoothing", pen.smoothing)
        nonnegative(f"{name}.friction", pen.friction)
        positive(f"{name}.slip_speed", pen.slip_speed)
    require(isinstance(c.obstacles, tuple), "contact.obstacles", c.obstacles, "a tuple of obstacles")
    for k, obs in enumerate(c.obstacles):
        name = f"contact.obstacles[{k}]"
        require(isinstance(obs, OBSTACLES), name, type(obs).__name__, "a Plane, Sphere, Capsule or Box")
        require(obs.motion is None or callable(obs.motion), f"{name}.motion", obs.motion, "None or a law t -> (3,)")
        if isinstance(obs, Plane):
            finite(f"{name}.point", obs.point, (3,))
            finite(f"{name}.normal", obs.normal, (3,))
            if concrete(obs.normal):
                require(float(np.linalg.norm(np.asarray(obs.normal, float))) > 1e-9, f"{name}.normal",
                        obs.normal, "a nonzero 3-vector")
        elif isinstance(obs, Sphere):
            finite(f"{name}.centre", obs.centre, (3,))
            positive(f"{name}.radius", obs.radius, ())
        elif isinstance(obs, Capsule):
            finite(f"{name}.start", obs.start, (3,))
            finite(f"{name}.end", obs.end, (3,))
            positive(f"{name}.radius", obs.radius, ())
            if concrete((obs.start, obs.end)):
                require(float(np.linalg.norm(np.subtract(obs.end, obs.start, dtype=float))) > 1e-9,
                        f"{name}.end", obs.end, "a point apart from start (else use a Sphere)")
        else:
            finite(f"{name}.centre", obs.centre, (3,))
            positive(f"{name}.half_extents", obs.half_extents, (3,))
            finite(f"{name}.rotation", obs.rotation, (3, 3))
            if concrete(obs.rotation):
                rot = np.asarray(obs.rotation, float)
                require(bool(np.allclose(rot.T @ rot, np.eye(3), atol=1e-9)) and np.linalg.det(rot) > 0,
                        f"{name}.rotation", obs.rotation, "a rotation matrix (orthonormal, det +1)")
    n = len(robot.links)
    for k, site in enumerate(c.sites):
        name = f"contact.sites[{k}]"
        require(isinstance(site, ContactSite), name, type(site).__name__, "a ContactSite")
        require(-n <= site.link < n and isinstance(robot.links[site.link], RigidLink), f"{name}.link", site.link,
                "the index of a rigid link")
        finite(f"{name}.offset", site.offset, (3,))
        nonnegative(f"{name}.radius", site.radius, ())


__all__ = ["Contact", "ContactSite", "Penalty", "Plane", "Sphere", "Capsule", "Box", "law", "points_for", "sites"]
