"""The contact law against a stack of static spheres or capsules, component by component.

``contact.law`` on one obstacle at a time works on (..., 3) vectors; a batch of
rods then runs many small kernels over a trailing axis of 3, which XLA's CPU
backend vectorises poorly. Here every vector is three arrays (..., n_c, m) (m the
obstacles of the stack) and the obstacles' sums are one reduction: the same
formulas as ``obstacles.Sphere.piece``, ``obstacles.Capsule.piece`` and
``contact.law``, equal to them to float rounding (``tests/test_contact.py``).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from gvsjax import penetration
from gvsjax.obstacles import TINY, Capsule, Sphere, anchored_floor, capsule_bend, segment_closest, sphere_curvature


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(d):
    return jnp.sqrt(_dot(d, d) + TINY * TINY)


def _piece(obs, p, t, lo, hi, r):
    """(u, gap, normal, floor, curvature, centre) of ``Sphere.piece`` / ``Capsule.piece``, p and t
    three (n_c, m) arrays, the stack's leaves (m, ...), r the rod's radius."""
    dtype = p[0].dtype
    radius = jnp.asarray(obs.radius, dtype)
    if isinstance(obs, Sphere):
        c = jnp.asarray(obs.centre, dtype)
        cp = tuple(c[:, i] - p[i] for i in range(3))
        centre = _dot(cp, t)
        u = jnp.clip(centre, lo, hi)
        d = tuple(p[i] + u * t[i] - c[:, i] for i in range(3))
        dist = _norm(d)
        curv = sphere_curvature(radius, r)
        floor = anchored_floor(dist - radius, curv, u, centre)
        return u, dist - radius, tuple(x / dist for x in d), floor, curv, centre
    a = jnp.asarray(obs.start, dtype)
    e_arr = jnp.asarray(obs.end, dtype) - a
    e = tuple(e_arr[:, i] for i in range(3))
    ee = _dot(e, e)
    r0 = tuple(p[i] - a[:, i] for i in range(3))
    te, b2 = _dot(t, e), _dot(e, r0)
    u, sigma, centre, sin2 = segment_closest(te, _dot(t, r0), b2, ee, lo, hi)
    d = tuple(r0[i] + u * t[i] - sigma * e[i] for i in range(3))
    dist = _norm(d)
    curv = sphere_curvature(radius, r) * capsule_bend(te, b2, ee, sin2, lo, hi, radius + r)
    return u, dist - radius, tuple(x / dist for x in d), anchored_floor(dist - radius, curv, u, centre), curv, centre


def stacked_law(obs: Any, p, tangent, omega, vel, radius, lo, hi, pen) -> tuple:
    """World force (3,) and moment about the centre (3,) on every piece from a stack of static
    spheres or capsules (each component (n_c,)), each piece's smallest gap (n_c,) and its
    penalty energy (n_c,).

    p, tangent, omega, vel: (n_c, 3) world; radius, lo, hi: (n_c,) m (``contact.law``)."""
    assert isinstance(obs, (Sphere, Capsule)) and obs.motion is None
    m = jnp.shape(obs.radius)[0]
    col = lambda x: tuple(jnp.broadcast_to(x[..., i, None], x.shape[:-1] + (m,)) for i in range(3))  # noqa: E731
    p, t, omega, vel = col(p), col(tangent), col(omega), col(vel)
    r, lo, hi = radius[..., None], lo[..., None], hi[..., None]
    l, k = pen.smoothing, pen.stiffness

    def profile(p, t):
        u, gap, n, floor, curv, centre = _piece(obs, p, t, lo, hi, r)
        return (floor - r, curv, centre), (u, gap, n)

    (floor, curv, centre), pull, (u, gap, n) = jax.vjp(profile, p, t, has_aux=True)
    energy, I0, I2, I_chi, phi_lo, phi_hi = penetration.curved(floor, curv, lo - centre, hi - centre, l)
    push = k * I0
    d_p, d_t = pull((-push, -k * I2, k * (phi_lo - phi_hi)))
    g = gap - r
    arm = tuple(u * t[i] - r * n[i] for i in range(3))
    w_arm = _cross(omega, arm)
    v_rel = tuple(vel[i] + w_arm[i] for i in range(3))
    v_n = _dot(v_rel, n)
    f_n = jnp.maximum(push - pen.damping * I_chi * v_n, 0.0)
    v_t = tuple(v_rel[i] - v_n * n[i] for i in range(3))
    mu_s = pen.friction if pen.static_friction is None else pen.static_friction
    mu = f_n * penetration.friction_coefficient(_dot(v_t, v_t), mu_s, pen.friction, pen.slip_speed)
    f = tuple((f_n - push) * n[i] - mu * v_t[i] for i in range(3))
    m_el = _cross(t, d_t)
    m_other = _cross(arm, f)
    total = lambda x: jnp.sum(x, axis=-1)  # noqa: E731
    return (tuple(total(f[i] - d_p[i]) for i in range(3)), tuple(total(m_other[i] - m_el[i]) for i in range(3)),
            jnp.min(g, axis=-1), total(k * energy))
