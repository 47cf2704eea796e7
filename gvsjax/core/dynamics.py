"""Generalized dynamics of a GVS robot: M(q) qdd = F(q, qd, t).

F gathers gravity, Coriolis/centrifugal forces (-C qd), point loads, contact
(``gvsjax.core.contact``), the elastic and Kelvin-Voigt forces (-K q - D qd) and
tendon actuation. K and D
are constant (the reference strain is kept out of Phi q) and are assembled
once per call from the material; everything is differentiable in the robot's
leaves (E, eta, loads, sizes ...).

Prescribed (position-controlled) DoFs ``a`` follow a given law; the free DoFs
``u`` obey M_uu qdd_u = F_u - M_ua qdd_a, and the actuator effort of the
prescribed DoFs follows by inverse dynamics: tau_a = M_a. qdd - F_a.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import jax.numpy as jnp
import numpy as np

from gvsjax.core import contact, lie, linalg, tendons
from gvsjax.core.kinematics import coords, forward, point_at, rows
from gvsjax.core.lie import add, const, dot, mul, sub, total, vadd
from gvsjax.core.magnus import Point, grid_of
from gvsjax.core.model import RigidLink, Robot, SoftLink

# ----------------------------------------------------------------------------
# section properties and constant matrices


@dataclass
class Section:
    """Per-unit-length diagonals (6 entries each, twist order)."""

    inertia: tuple  # rho * (Ip, Iy, Iz, A, A, A)
    stiffness: tuple  # (G Jt, E Iy, E Iz, E A, G A, G A)
    damping: tuple  # eta * factors * (Jt, Iy, Iz, A, A, A)


def _geometry(link: SoftLink, scale) -> tuple[tuple, tuple]:
    """(Ip, Iy, Iz, A, A, A) for inertia and (Jt, Iy, Iz, A, A, A) for stiffness, dimensions
    multiplied by ``scale``. Jt is Saint-Venant's torsion constant: the polar moment for a
    circle, pi a^3 b^3 / (a^2 + b^2) for an ellipse, Roark's series for a rectangle; or, with
    ``torsion_constant="polar"``, Iy + Iz for every shape."""
    if link.shape == "circle":
        r = link.radius * scale
        area, second = math.pi * r * r, math.pi * r**4 / 4.0
        geo = (2.0 * second, second, second, area, area, area)
        return geo, geo
    w, h = link.width * scale, link.height * scale
    if link.shape == "ellipse":
        a, b = w / 2.0, h / 2.0
        area, iy, iz = math.pi * a * b, math.pi * a * b**3 / 4.0, math.pi * a**3 * b / 4.0
        jt = math.pi * a**3 * b**3 / (a * a + b * b)
    else:
        area, iy, iz = w * h, w * h**3 / 12.0, h * w**3 / 12.0
        long, short = jnp.maximum(w, h), jnp.minimum(w, h)
        r = short / long
        jt = long * short**3 * (1.0 / 3.0 - 0.21 * r * (1.0 - r**4 / 12.0))
    if link.torsion_constant == "polar":
        jt = iy + iz
    return (iy + iz, iy, iz, area, area, area), (jt, iy, iz, area, area, area)


def section(link: SoftLink, X: Any = 0.0) -> Section:
    """The section's diagonals at material coordinate X (the base's when untapered)."""
    scale = 1.0 if _uniform(link) else 1.0 + (link.taper - 1.0) * X
    geo_m, geo_k = _geometry(link, scale)
    mat = link.material
    shear = mat.youngs_modulus / (2.0 * (1.0 + mat.poisson))
    stiff = (shear, mat.youngs_modulus, mat.youngs_modulus) + (mat.youngs_modulus, shear, shear)
    return Section(
        inertia=tuple(mat.density * g for g in geo_m),
        stiffness=tuple(s * g for s, g in zip(stiff, geo_k)),
        damping=tuple(mat.damping * f * g for f, g in zip(link.damping_factors, geo_k)),
    )


def _uniform(link: SoftLink) -> bool:
    """True when the section is the same all along (a taper of exactly 1, known at trace time)."""
    return isinstance(link.taper, (int, float)) and link.taper == 1


def _weighted_gram(robot: Robot, li: int, per_component) -> list[list]:
    """sum_i W_i Phi_i^T diag(c(X_i)) Phi_i for a soft link (n_s x n_s, scalar algebra).

    ``per_component(X)`` gives the six diagonal entries at X; a uniform link takes them once.
    """
    link = robot.links[li]
    grid = grid_of(robot, li)
    L = link.length
    n = grid.phi.shape[2]
    scale = [1.0 / (L * L) if c < 3 else 1.0 for c in range(6)]  # SoRoSim 1/L on angular rows
    out = [[0] * n for _ in range(n)]
    points = [0.0] if _uniform(link) else [float(x) for x, w in zip(grid.X, grid.w) if w > 0]
    weights = [grid.w] if _uniform(link) else [np.where(grid.X == x, grid.w, 0.0) for x in points]
    for x, w in zip(points, weights):
        diag = per_component(x)
        for c in range(6):
            gram = np.einsum("i,ij,ik->jk", w, grid.phi[:, c, :], grid.phi[:, c, :])
            if not np.any(gram):
                continue
            coef = mul(mul(diag[c], L), scale[c])
            for j in range(n):
                for k in range(n):
                    out[j][k] = add(out[j][k], mul(coef, const(gram[j, k])))
    return out


def _per_dof(value, k: int):
    """Entry k of a per-joint-DoF parameter given as a scalar (the same for each) or a sequence;
    a Python 0 stays a structural zero (no term is traced for a joint without spring or damper)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return 0 if value == 0 else value
    v = jnp.asarray(value)
    return v if v.ndim == 0 else v[k]


def stiffness_and_damping(robot: Robot) -> tuple[list[list], list[list]]:
    """K and D (n x n, scalar algebra): sum_i W_i Phi_i^T Sigma Phi_i for the soft DoFs, likewise
    for D; the links' ``joint_stiffness``/``joint_damping`` on the joint DoFs' diagonal."""
    n = robot.n_dofs
    K = [[0] * n for _ in range(n)]
    D = [[0] * n for _ in range(n)]
    for li, (link, (j0, s0, end)) in enumerate(zip(robot.links, robot.dof_slices())):
        for big, value in ((K, link.joint_stiffness), (D, link.joint_damping)):
            for k in range(s0 - j0):
                big[j0 + k][j0 + k] = _per_dof(value, k)
        if not isinstance(link, SoftLink) or end == s0:
            continue
        for big, part in ((K, "stiffness"), (D, "damping")):
            block = _weighted_gram(robot, li, lambda x, link=link, part=part: getattr(section(link, x), part))
            for j in range(end - s0):
                for k in range(end - s0):
                    big[s0 + j][s0 + k] = block[j][k]
    return K, D


# ----------------------------------------------------------------------------
# point-wise contributions


def _rigid_inertia(link: RigidLink) -> tuple:
    I = link.inertia
    return (I[0], I[1], I[2], link.mass, link.mass, link.mass)


def _add_body(M, F, pt: Point, inertia_diag: tuple, weight, gravity_world: tuple):
    """Accumulate W J^T Ms J into M and W J^T (Ms (g_body - psi) + ad_eta^T Ms eta) into F."""
    Ms = tuple(mul(weight, m) for m in inertia_diag)
    wrench = _body_wrench(pt, Ms, gravity_world)
    MJ = [tuple(mul(m, a) for m, a in zip(Ms, col)) for col in pt.J]
    n = len(pt.J)
    for j in range(n):
        F[j] = add(F[j], dot(pt.J[j], wrench))
        for k in range(j + 1):
            M[j][k] = add(M[j][k], dot(pt.J[j], MJ[k]))


def _distributed(robot: Robot, pt: Point, t) -> tuple:
    """The distributed load at a soft sample point, per metre, in the section's frame."""
    R = jnp.stack([jnp.stack([lie.as_array(a) for a in row]) for row in pt.R])
    p = jnp.stack([lie.as_array(a) for a in pt.p])
    eta = jnp.stack([lie.as_array(a) for a in pt.eta])
    w = jnp.reshape(robot.distributed(pt.X, R, p, eta, t), (6,))
    return tuple(w[k] for k in range(6))


def _body_wrench(pt: Point, Ms: tuple, gravity_world: tuple) -> tuple:
    """Ms (g_body - psi) + ad_eta^T Ms eta: the inertial and gravity wrench at a point."""
    grav_body = (0, 0, 0) + lie.matTvec(pt.R, gravity_world)
    Ms_eta = tuple(mul(m, e) for m, e in zip(Ms, pt.eta))
    return vadd(
        tuple(mul(m, lie.sub(g, s)) for m, g, s in zip(Ms, grav_body, pt.psi)),
        lie.ad_transpose(pt.eta, Ms_eta),
    )


def _add_stacked_body(M, F, pt: Point, inertia_diag: tuple, gravity_world: tuple) -> None:
    """``_add_body`` for a stacked point: the sums over rows and Jacobian columns run as
    array operations, so their traced size is independent of both."""
    Ms = tuple(mul(pt.weight, m) for m in inertia_diag)
    w = _body_wrench(pt, Ms, gravity_world)
    arr = lambda a: jnp.broadcast_to(lie.as_array(a), (pt.rows,))  # noqa: E731
    live = [r for r in range(6) if not lie.is_zero(Ms[r])]
    Fv = sum(jnp.einsum("i,ij->j", arr(w[r]), pt.J[r]) for r in range(6) if not lie.is_zero(w[r]))
    Mm = sum(jnp.einsum("i,ij,ik->jk", arr(Ms[r]), pt.J[r], pt.J[r]) for r in live)
    pairs = [(j, k) for j, a in enumerate(pt.cols) if a >= 0 for k, b in enumerate(pt.cols[: j + 1]) if b >= 0]
    if not isinstance(Fv, int):
        for j, f in zip([j for j, a in enumerate(pt.cols) if a >= 0],
                        linalg.entries(Fv, tuple(a for a in pt.cols if a >= 0))):
            F[j] = add(F[j], f)
    if not isinstance(Mm, int):
        m = Mm.shape[1]
        flat = tuple(pt.cols[j] * m + pt.cols[k] for j, k in pairs)
        for (j, k), e in zip(pairs, linalg.entries(Mm.reshape(-1), flat)):
            M[j][k] = add(M[j][k], e)


def _add_wrench(F, pt: Point, wrench: Sequence, local: bool, weight=1.0) -> None:
    """F += weight J^T w, w = (moment, force) given in the section's frame or the world's."""
    w = tuple(wrench) if local else lie.matTvec(pt.R, tuple(wrench[:3])) + lie.matTvec(pt.R, tuple(wrench[3:]))
    for j in range(len(F)):
        F[j] = add(F[j], mul(weight, dot(pt.J[j], w)))


def mass_and_forces(
    robot: Robot, q: Sequence, qd: Sequence, tension: Sequence = (), joint_force: Sequence = (),
    wrench: Sequence = (), t=0.0,
) -> tuple[list[list], list]:
    """M (lower triangle filled, scalar algebra) and F with every force included.

    q, qd: n scalars each; tension: one value per tendon (N, >= 0); joint_force:
    one generalized force per ``robot.actuated`` coordinate (N m or N), or empty;
    wrench: one 6-vector (moment, force) per ``robot.wrenches`` entry, or empty;
    t: the time the distributed load and moving obstacles are evaluated at.
    """
    n = robot.n_dofs
    points = forward(robot, q, qd, with_psi=True)
    g_world = tuple(mul(robot.gravity, const(c)) for c in robot.gravity_direction)
    M = [[0] * n for _ in range(n)]
    F = [0] * n
    n_links = len(robot.links)
    for pt in points:
        link = robot.links[pt.link]
        if pt.rows:
            # a stacked point's X is a numpy array over its rows: in float64 it would lift a float32 run
            X = jnp.asarray(pt.X, lie.as_array(pt.weight).dtype)
            _add_stacked_body(M, F, pt, section(link, X).inertia, g_world)
        elif pt.kind == "soft" and not lie.is_zero(pt.weight):
            _add_body(M, F, pt, section(link, pt.X).inertia, pt.weight, g_world)
        elif pt.kind == "rigid":
            _add_body(M, F, pt, _rigid_inertia(link), 1.0, g_world)
    for pm in robot.masses:
        pt = point_at(points, pm.link, pm.X, n_links)
        _add_body(M, F, pt, (0, 0, 0, pm.mass, pm.mass, pm.mass), 1.0, g_world)
    if robot.distributed is not None:
        for pt in rows(points):  # the user's law sees one material point X (a float) at a time
            if pt.kind == "soft" and not lie.is_zero(pt.weight):
                _add_wrench(F, pt, _distributed(robot, pt, t), True, pt.weight)
    if robot.contact is not None:
        F = [add(f, c) for f, c in zip(F, contact.evaluate(robot, points, q, qd, t)[0])]
    for site, w in zip(robot.wrenches, wrench):
        _add_wrench(F, point_at(points, site.link, site.X, n_links), w, site.local)
    for load in robot.loads:
        pt = point_at(points, load.link, load.X, n_links)
        f = tuple(mul(load.magnitude, const(c)) for c in load.direction)
        f_body = f if load.follower else lie.matTvec(pt.R, f)
        wrench = (f_body + (0, 0, 0)) if load.moment else ((0, 0, 0) + f_body)
        for j in range(n):
            F[j] = add(F[j], dot(pt.J[j], wrench))
    K, D = stiffness_and_damping(robot)
    tau = tendons.generalized_force(robot, q, tension) if robot.tendons else [0] * n
    for i, f in zip(robot.actuated, joint_force):
        tau[i] = add(tau[i], f)
    for j in range(n):
        elastic = total([mul(K[j][k], q[k]) for k in range(n)] + [mul(D[j][k], qd[k]) for k in range(n)])
        F[j] = add(sub(F[j], elastic), tau[j])
    return M, F


# ----------------------------------------------------------------------------
# prescribed / free partition


def split_solve(robot: Robot, M, F, qdd_a: Sequence) -> list:
    """qdd_u from M_uu qdd_u = F_u - M_ua qdd_a."""
    a, u = robot.prescribed, robot.free
    Mf = lambda i, j: M[i][j] if i >= j else M[j][i]  # noqa: E731 (symmetric lookup)
    rhs = [sub(F[i], total([mul(Mf(i, k), x) for k, x in zip(a, qdd_a)])) for i in u]
    A = [[Mf(i, j) for j in u] for i in u]
    return linalg.solve_spd(A, rhs)


def prescribed_effort(robot: Robot, M, F, qdd: Sequence) -> list:
    """Inverse dynamics of the prescribed DoFs: tau_a = M_a. qdd - F_a (N m or N)."""
    n = robot.n_dofs
    Mf = lambda i, j: M[i][j] if i >= j else M[j][i]  # noqa: E731
    return [sub(total([mul(Mf(i, k), qdd[k]) for k in range(n)]), F[i]) for i in robot.prescribed]


def full_matrix(M, n: int) -> jnp.ndarray:
    """The symmetric n x n array from a lower-triangle scalar-algebra matrix."""
    rows = [[lie.as_array(M[i][j] if i >= j else M[j][i]) for j in range(n)] for i in range(n)]
    return jnp.stack([jnp.stack(r) for r in rows])


# ----------------------------------------------------------------------------
# energy (for tests and monitoring)


def energy(robot: Robot, q: jnp.ndarray, qd: jnp.ndarray) -> dict[str, Any]:
    """Kinetic, elastic and potential (gravity and constant world-fixed loads) energy, J."""
    n = robot.n_dofs
    coords(robot, q, "q")  # shape checks only: q and qd are used as given
    coords(robot, qd, "qd")
    qs = [q[i] for i in range(n)]
    qds = [qd[i] for i in range(n)]
    points = forward(robot, qs, qds, with_psi=False, jacobian=False)
    g_world = tuple(mul(robot.gravity, const(c)) for c in robot.gravity_direction)
    kinetic, grav, loads = 0, 0, 0

    def body(pt, diag, weight):
        nonlocal kinetic, grav
        eta_M_eta = dot(pt.eta, tuple(mul(m, e) for m, e in zip(diag, pt.eta)))
        dk = mul(0.5, mul(weight, eta_M_eta))
        dg = mul(mul(weight, diag[3]), dot(g_world, pt.p))
        if pt.rows:
            dk, dg = (a if lie.is_zero(a) else jnp.sum(a) for a in (dk, dg))
        kinetic = add(kinetic, dk)
        grav = sub(grav, dg)

    for pt in points:
        link = robot.links[pt.link]
        if pt.rows:
            body(pt, section(link, jnp.asarray(pt.X, lie.as_array(pt.weight).dtype)).inertia, pt.weight)
        elif pt.kind == "soft" and not lie.is_zero(pt.weight):
            body(pt, section(link, pt.X).inertia, pt.weight)
        elif pt.kind == "rigid":
            body(pt, _rigid_inertia(link), 1.0)
    for pm in robot.masses:
        body(point_at(points, pm.link, pm.X, len(robot.links)), (0, 0, 0, pm.mass, pm.mass, pm.mass), 1.0)
    for load in robot.loads:
        if load.follower or load.moment:
            continue  # follower loads and couples are left out (no simple potential)
        pt = point_at(points, load.link, load.X, len(robot.links))
        f = tuple(mul(load.magnitude, const(c)) for c in load.direction)
        loads = sub(loads, dot(f, pt.p))
    K, _ = stiffness_and_damping(robot)
    elastic = mul(0.5, total([mul(mul(K[j][k], qs[j]), qs[k]) for j in range(n) for k in range(n)]))
    parts = dict(kinetic=kinetic, elastic=elastic, gravity=grav, loads=loads)
    return {k: lie.as_array(v) for k, v in parts.items()}
