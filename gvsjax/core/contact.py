"""Contact between the robot and obstacles: a conservative penalty with regularised friction.

The rod is a tube: every point within the section's radius (circumscribed
circle for ellipses and rectangles; ``taper`` scales it) of the centreline.
Each soft link carries ``n_points`` contact samples, uniform in X (ends
included, spacing h = L / (n_points - 1)). Sample k stands for the straight
piece of tube along its local tangent, u in [-h/2, h/2] (half of that at the
link's ends), so the pieces tile the rod without gaps: an obstacle of any
width is found, wherever it lies between samples. The piece departs from the
curved centreline by at most kappa h^2 / 8 (kappa: curvature, 1/m), the
sampling's only geometric error.

The penalty has an energy: k Phi(g) per metre of rod at gap g (per site for
rigid links), integrated over each piece in closed form along the obstacle's
gap profile (a parabola for spheres and capsules, linear for planes and box
faces; ``gvsjax.core.penetration``). The elastic force and moment on a piece are
that energy's exact derivatives (no work is gained round a closed path; the
contact stiffness is symmetric). Damping ``c chi(g) (-v_n)`` per metre is
added along the normal, the total clipped at 0 (no adhesion). Friction:
``-mu(|v_t|) f_n v_t / sqrt(|v_t|^2 + v_s^2)`` on the slip velocity v_t of the
rod's surface point against the obstacle's, mu falling from the static to the
kinetic coefficient as the slip grows: Coulomb's law for |v_t| >> v_s, a
viscous creep below. See docs/contact.md.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core import contact_samples as samples
from gvsjax.core import lie, penetration
from gvsjax.core.kinematics import forward
from gvsjax.core.magnus import Point
from gvsjax.core.model import RigidLink, Robot, SoftLink
from gvsjax.core.obstacles import OBSTACLES, Box, Capsule, Plane, Sphere
from gvsjax.core.stacked_contact import stacked_law
from gvsjax.core.validation import concrete, finite, integer, nonnegative, positive, require


@struct.dataclass
class Penalty:
    """Contact law parameters. For soft links stiffness is N/m per metre of rod (N/m^2) and
    damping N s/m per metre (N s/m^2); for rigid sites, N/m and N s/m.

    smoothing: length l (m) over which the penetration's corner is rounded; friction: the
    kinetic coefficient mu_k; static_friction: mu_s >= mu_k (None: mu_k, one coefficient);
    slip_speed: the regularisation speed v_s (m/s) below which friction turns viscous (a
    creep); mu falls from mu_s to mu_k around ``penetration.STRIBECK`` v_s."""

    stiffness: Any = 1e7
    damping: Any = 5e3
    smoothing: Any = 1e-5
    friction: Any = 0.0
    slip_speed: Any = 1e-2
    static_friction: Any = None


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
    per soft link (static), see ``points_for`` to choose it; nearest (static): None, or a
    broad phase: each rod piece runs the law against only its ``nearest`` nearest static spheres
    and capsules (by exact gap; the gaps reported are still over all). Exact while no piece is
    within the smoothing length of more than that many at once (a piece at a cage's corner
    touches three bars); cheaper when there are many more obstacles than that. pairs (static):
    None, or the other broad phase: the law runs on at most ``pairs`` (piece, obstacle) pairs of
    each soft link, those within the smoothing length of touching, the first along the link. Exact
    while no more pairs than that touch at once (beyond, those farthest along the link are
    dropped); cheaper than ``nearest`` when few pieces touch at a time. Set one of the two.
    """

    obstacles: tuple = ()
    rod: Penalty = Penalty()
    site: Penalty = Penalty(stiffness=1e5, damping=200.0, smoothing=1e-4)
    sites: tuple = ()
    n_points: int = struct.field(pytree_node=False, default=21)
    nearest: int | None = struct.field(pytree_node=False, default=None)
    pairs: int | None = struct.field(pytree_node=False, default=None)

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

SAFE_AREA = 1e-6  # times l^2: where I0 is this small the centroid I1 / I0 falls to the sample


def _groups(obstacles) -> list[tuple[Any, bool]]:
    """The obstacles, the static spheres and the static capsules each stacked into one (leaves with
    a leading axis, also a single one): the law then runs once over all of a kind, with the
    profile's derivatives by hand (``stacked_contact``); moving ones go one by one through autodiff."""
    stackable = lambda o, kind: type(o) is kind and o.motion is None  # noqa: E731
    out: list[tuple[Any, bool]] = []
    rest = list(obstacles)
    for kind in (Sphere, Capsule):
        same = [o for o in obstacles if stackable(o, kind)]
        if same:
            # as arrays first: a leaf given as a tuple of floats is a pytree of floats
            same = [o.replace(**{f.name: jnp.asarray(getattr(o, f.name)) for f in dataclasses.fields(o)
                                 if f.name != "motion"}) for o in same]
            out.append((jax.tree.map(lambda *a: jnp.stack(a), *same), True))
            rest = [o for o in rest if not stackable(o, kind)]
    return out + [(o, False) for o in rest]


def static_friction(pen: Penalty):
    """mu_s: ``pen.static_friction``, or ``pen.friction`` when that is None."""
    return pen.friction if pen.static_friction is None else pen.static_friction


def _curved(obs, p, tangent, radius, lo, hi, t, pen: Penalty):
    """A sphere's or capsule's piece: (Piece, energy, k I0, I_chi, elastic force, its moment),
    the force and moment the derivatives of the energy through the profile's parameters."""
    shape = jax.eval_shape(lambda: obs.piece(p, tangent, lo, hi, t, radius).gap).shape
    p, tangent = (jnp.broadcast_to(x, shape + (3,)) for x in (p, tangent))  # one cotangent per obstacle

    def profile(p, tangent):
        pc = obs.piece(p, tangent, lo, hi, t, radius)
        return (pc.floor - radius, pc.curvature, pc.centre), pc

    (floor, curv, centre), pull, pc = jax.vjp(profile, p, tangent, has_aux=True)
    energy, I0, I2, I_chi, phi_lo, phi_hi = penetration.curved(floor, curv, lo - centre, hi - centre, pen.smoothing)
    k = pen.stiffness
    d_p, d_t = pull((-k * I0, -k * I2, k * (phi_lo - phi_hi)))
    return pc, k * energy, k * I0, I_chi, -d_p, -jnp.cross(tangent, d_t)


def _pair(obs, p, tangent, omega, vel, radius, lo, hi, pen: Penalty, t):
    """One obstacle's (or a stack's) world force and moment about the centre on a piece or site,
    its gap and its penalty energy (``law``'s arguments; lo None: a site)."""
    l, k = pen.smoothing, pen.stiffness
    if lo is None:  # a ball: k Phi(g), pushing along the normal through the centre
        pc = obs.piece(p, tangent, 0.0, 0.0, t)
        g = pc.gap - radius
        push, I_chi = k * penetration.depth(g, l), penetration.indicator(g, l)
        energy = k * penetration.energy_density(g, l)
        f_el, m_el, u = push[..., None] * pc.normal, 0.0, pc.u
    elif isinstance(obs, (Plane, Box)):
        pc = obs.piece(p, tangent, lo, hi, t)
        g = pc.gap - radius
        g0 = g - pc.slope * pc.u  # the gap at the sample
        energy, I0, I1, I_chi = penetration.flat(g0, pc.slope, lo, hi, l)
        energy, push = k * energy, k * I0
        f_el, m_el = push[..., None] * pc.normal, (k * I1)[..., None] * jnp.cross(tangent, pc.normal)
        u = I1 / (I0 + SAFE_AREA * l * l)  # damping and friction act at the penetration's centroid
        g = jnp.minimum(g0 + pc.slope * lo, g0 + pc.slope * hi)
    else:
        pc, energy, push, I_chi, f_el, m_el = _curved(obs, p, tangent, radius, lo, hi, t, pen)
        g, u = pc.gap - radius, pc.u
    arm = u[..., None] * tangent - radius[..., None] * pc.normal  # centre -> surface point
    v_rel = vel + jnp.cross(omega, arm) - pc.velocity
    v_n = jnp.sum(v_rel * pc.normal, axis=-1)
    f_n = jnp.maximum(push - pen.damping * I_chi * v_n, 0.0)  # the damping never pulls
    v_t = v_rel - v_n[..., None] * pc.normal
    mu = penetration.friction_coefficient(jnp.sum(v_t * v_t, axis=-1), static_friction(pen), pen.friction,
                                          pen.slip_speed)
    f = (f_n - push)[..., None] * pc.normal - (f_n * mu)[..., None] * v_t  # besides the elastic force
    return f_el + f, m_el + jnp.cross(arm, f), g, energy


def law(p, R, eta, radius, lo, hi, obstacles, pen: Penalty, t, nearest: int | None = None,
        pairs: int | None = None):
    """The contact wrench on one rod piece or site from every obstacle.

    p (..., 3) world centre, R (..., 3, 3) world rotation (column 0: the tangent), eta
    (..., 6) body twist (angular, linear); radius (...) m; lo, hi: the piece's extent along
    the tangent (m; None for a site: a ball, forces per site). Returns (body wrench (..., 6):
    moment N m, force N, in the section's frame; world force (..., 3) N; the smallest gap
    over the obstacles (...), m, negative when penetrating; the penalty's energy (...), J).
    nearest, pairs: ``Contact.nearest``, ``Contact.pairs`` (pieces only; pairs over the leading axis of p).
    """
    tangent = R[..., :, 0]
    omega, vel = jnp.einsum("...ij,...j->...i", R, eta[..., :3]), jnp.einsum("...ij,...j->...i", R, eta[..., 3:])
    force = jnp.zeros_like(p)
    moment = jnp.zeros_like(p)
    gap_min = jnp.full(p.shape[:-1], jnp.inf, p.dtype)
    energy = jnp.zeros(p.shape[:-1], p.dtype)
    for obs, stacked in _groups(obstacles):
        if stacked and lo is not None:
            f3, m3, g, e = stacked_law(obs, p, tangent, omega, vel, radius, lo, hi, pen, nearest, pairs)
            force, moment = force + jnp.stack(f3, -1), moment + jnp.stack(m3, -1)
            gap_min, energy = jnp.minimum(gap_min, g), energy + e
            continue
        # a stack of obstacles is one more axis before the vectors' (summed over below)
        x = (lambda a: a[..., None, :]) if stacked else (lambda a: a)  # noqa: E731
        y = (lambda a: a if a is None else jnp.asarray(a)[..., None]) if stacked else (lambda a: a)  # noqa: E731
        f, m, g, e = _pair(obs, x(p), x(tangent), x(omega), x(vel), y(radius), y(lo), y(hi), pen, t)
        if stacked:
            f, m, g, e = jnp.sum(f, axis=-2), jnp.sum(m, axis=-2), jnp.min(g, axis=-1), jnp.sum(e, axis=-1)
        force = force + f
        moment = moment + m
        gap_min = jnp.minimum(gap_min, g)
        energy = energy + e
    body = jnp.concatenate([jnp.einsum("...ji,...j->...i", R, moment),
                            jnp.einsum("...ji,...j->...i", R, force)], axis=-1)
    return body, force, gap_min, energy


def evaluate(robot: Robot, points: list[Point], q, qd, t) -> tuple[list, list, list, Any]:
    """The contact at every sample: (generalized force, n scalars; world forces, one (n_c, 3)
    per soft link and one (3,) per site, N; gaps likewise, m; the penalty's energy, J).
    q, qd: n scalars each."""
    contact = robot.contact
    F: list = [0] * robot.n_dofs
    forces, gaps = [], []
    energy: Any = 0.0
    for li, link in enumerate(robot.links):
        if not isinstance(link, SoftLink):
            continue
        Xc = np.asarray(contact.material_points(link))
        n_c = len(Xc)
        Rs, ps, etas, pull = samples.soft_samples(robot, li, link, points, q, qd)
        R, p, eta = samples.arrays(Rs, ps, etas, n_c)
        half = 0.5 * float(Xc[1] - Xc[0]) * link.length  # the piece around each sample: half a spacing each way
        lo = -half * jnp.asarray(np.arange(n_c) > 0, dtype=p.dtype)
        hi = half * jnp.asarray(np.arange(n_c) < n_c - 1, dtype=p.dtype)
        w, f, g, e = law(p, R, eta, samples.radius(link, Xc, p.dtype), lo, hi, contact.obstacles, contact.rod, t,
                         contact.nearest, contact.pairs)
        terms = pull(tuple(w[:, k] for k in range(6)))
        live = [j for j, x in enumerate(terms) if not lie.is_zero(x)]
        if live:  # one reduction for every column: XLA would repeat the columns' shared work in each
            Fs = jnp.sum(jnp.stack([jnp.broadcast_to(terms[j], (n_c,)) for j in live], -1), axis=0)
            for k, j in enumerate(live):
                F[j] = lie.add(F[j], Fs[k])
        forces.append(f)
        gaps.append(g)
        energy = energy + jnp.sum(e)
    n = len(robot.links)
    for site in contact.sites:
        link = robot.links[site.link % n]
        pt = next(x for x in points if x.link == site.link % n and x.kind == "rigid")
        R, p, eta = (a[0] for a in samples.arrays(pt.R, pt.p, pt.eta, 1))
        d = jnp.asarray(site.offset, p.dtype) - jnp.asarray(link.com, p.dtype)  # from the CoM, body frame
        eta_s = jnp.concatenate([eta[:3], eta[3:] + jnp.cross(eta[:3], d)])
        w, f, g, e = law(p + R @ d, R, eta_s, jnp.asarray(site.radius, p.dtype), None, None, contact.obstacles,
                      contact.site, t)
        w = jnp.concatenate([w[:3] + jnp.cross(d, w[3:]), w[3:]])  # moved to the CoM
        for j, col in enumerate(pt.J):
            F[j] = lie.add(F[j], lie.dot(col, tuple(w[k] for k in range(6))))
        forces.append(f[None])
        gaps.append(g[None])
        energy = energy + e
    return F, forces, gaps, energy


def report(robot: Robot, q, qd, t) -> tuple[jax.Array, jax.Array]:
    """World contact force on the robot at every contact sample (n_c, 3), N (a soft sample's is
    the total over its piece of rod), and each sample's smallest gap (n_c,), m (negative:
    penetrating); rows as ``sites``. q, qd: (n,) arrays."""
    if robot.contact is None:
        return jnp.zeros((0, 3), q.dtype), jnp.zeros((0,), q.dtype)
    n = robot.n_dofs
    qs, qds = [q[i] for i in range(n)], [qd[i] for i in range(n)]
    _, forces, gaps, _ = evaluate(robot, forward(robot, qs, qds, with_psi=False, jacobian=False), qs, qds, t)
    return jnp.concatenate(forces), jnp.concatenate(gaps)


def energy(robot: Robot, q, t=0.0) -> jax.Array:
    """The penalty's elastic energy (J) at coordinates q (n,): k Phi integrated over every
    piece of rod, plus k Phi(g) per site. Its gradient is minus the contact force without
    damping and friction. Zero without ``Robot.contact``."""
    if robot.contact is None:
        return jnp.zeros((), q.dtype)
    n = robot.n_dofs
    qs, qds = [q[i] for i in range(n)], [jnp.zeros_like(q[i]) for i in range(n)]
    return jnp.asarray(evaluate(robot, forward(robot, qs, qds, with_psi=False, jacobian=False), qs, qds, t)[3])


def site_positions(robot: Robot, q) -> jax.Array:
    """World position (n_sites, 3) of every ``ContactSite`` at q (n,)."""
    n, n_links = robot.n_dofs, len(robot.links)
    qs = [q[i] for i in range(n)]
    points = forward(robot, qs, [jnp.zeros_like(x) for x in qs], with_psi=False, jacobian=False)
    out = []
    for site in robot.contact.sites:
        link = robot.links[site.link % n_links]
        pt = next(x for x in points if x.link == site.link % n_links and x.kind == "rigid")
        R, p, _ = (a[0] for a in samples.arrays(pt.R, pt.p, pt.eta, 1))
        out.append(p + R @ (jnp.asarray(site.offset, q.dtype) - jnp.asarray(link.com, q.dtype)))
    return jnp.stack(out)


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
    if c.nearest is not None:
        integer("contact.nearest", c.nearest, low=1)
    if c.pairs is not None:
        integer("contact.pairs", c.pairs, low=1)
        require(c.nearest is None, "contact.pairs", c.pairs, "None while contact.nearest is set (one broad phase)")
    for name, pen in (("contact.rod", c.rod), ("contact.site", c.site)):
        require(isinstance(pen, Penalty), name, type(pen).__name__, "a Penalty")
        positive(f"{name}.stiffness", pen.stiffness)
        nonnegative(f"{name}.damping", pen.damping)
        positive(f"{name}.smoothing", pen.smoothing)
        nonnegative(f"{name}.friction", pen.friction)
        if pen.static_friction is not None:
            nonnegative(f"{name}.static_friction", pen.static_friction)
            if concrete((pen.friction, pen.static_friction)):
                require(bool(np.all(np.asarray(pen.static_friction) >= np.asarray(pen.friction))),
                        f"{name}.static_friction", pen.static_friction,
                        f"None or a number >= {name}.friction (mu_s >= mu_k)")
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


__all__ = ["Contact", "ContactSite", "Penalty", "Plane", "Sphere", "Capsule", "Box", "energy", "law", "points_for",
           "sites"]
