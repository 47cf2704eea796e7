"""The contact law against a stack of static spheres or capsules, component by component.

``contact.law`` on one obstacle at a time works on (..., 3) vectors; a batch of
rods then runs many small kernels over a trailing axis of 3, which XLA's CPU
backend vectorises poorly. Here every vector is three arrays (..., n_c, m) (m the
obstacles of the stack) and the obstacles' sums are one reduction: the same
formulas as ``obstacles.Sphere.piece``, ``obstacles.Capsule.piece`` and
``contact.law``, equal to them to float rounding (``tests/test_contact.py``).
The profile's derivatives (the elastic force and moment) are its reverse pass
written out, one elementwise pass instead of autodiff's stored residuals
(``tests/test_contact_gradients.py``); ``nearest`` is the optional broad phase.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from gvsjax.core import penetration
from gvsjax.core.obstacles import (
    TINY,
    Capsule,
    Sphere,
    anchored_floor,
    capsule_bend,
    capsule_bend_back,
    segment_closest,
    segment_closest_back,
    sphere_curvature,
    within,
)


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(d):
    return jnp.sqrt(_dot(d, d) + TINY * TINY)


def _sphere(obs, p, t, lo, hi, r):
    """``Sphere.piece``'s profile and its reverse pass: (u, gap, normal, floor, curvature, centre) and
    back((g_floor, g_curvature, g_centre)) -> (d/dp, d/dt), each a 3-tuple."""
    dtype = p[0].dtype
    radius = jnp.asarray(obs.radius, dtype)
    c = jnp.asarray(obs.centre, dtype)
    cp = tuple(c[..., i] - p[i] for i in range(3))
    centre = _dot(cp, t)
    u = jnp.clip(centre, lo, hi)
    d = tuple(p[i] + u * t[i] - c[..., i] for i in range(3))
    dist = _norm(d)
    n = tuple(x / dist for x in d)
    curv = sphere_curvature(radius, r)
    floor = anchored_floor(dist - radius, curv, u, centre)

    def back(g):
        g_floor, _, g_centre = g  # the curvature is the radii's alone
        g_w = -curv * (u - centre) * g_floor
        g_d = tuple(g_floor * x for x in n)
        g_u = g_w + _dot(g_d, t)
        g_c = g_centre - g_w + g_u * within(centre, lo, hi)
        return tuple(g_d[i] - g_c * t[i] for i in range(3)), tuple(u * g_d[i] + g_c * cp[i] for i in range(3))

    return (u, dist - radius, n, floor, curv, centre), back


def _capsule(obs, p, t, lo, hi, r):
    """``Capsule.piece``'s profile and its reverse pass, as ``_sphere``'s."""
    dtype = p[0].dtype
    radius = jnp.asarray(obs.radius, dtype)
    a = jnp.asarray(obs.start, dtype)
    e_arr = jnp.asarray(obs.end, dtype) - a
    e = tuple(e_arr[..., i] for i in range(3))
    ee = _dot(e, e)
    r0 = tuple(p[i] - a[..., i] for i in range(3))
    te, b1, b2 = _dot(t, e), _dot(t, r0), _dot(e, r0)
    u, sigma, centre, sin2 = segment_closest(te, b1, b2, ee, lo, hi)
    d = tuple(r0[i] + u * t[i] - sigma * e[i] for i in range(3))
    dist = _norm(d)
    n = tuple(x / dist for x in d)
    ball = sphere_curvature(radius, r)
    curv = ball * capsule_bend(te, b2, ee, sin2, lo, hi, radius + r)
    floor = anchored_floor(dist - radius, curv, u, centre)

    def back(g):
        g_floor, g_curv, g_centre = g
        w = u - centre
        g_w = -curv * w * g_floor
        g_d = tuple(g_floor * x for x in n)  # the gap's: |d| - radius
        g_te, g_b2, g_sin2 = capsule_bend_back(te, b2, ee, sin2, lo, hi, radius + r,
                                               (g_curv - 0.5 * w * w * g_floor) * ball)
        g_te2, g_b1, g_b22 = segment_closest_back(te, b1, b2, ee, lo, hi, g_w + _dot(g_d, t), -_dot(g_d, e),
                                                  g_centre - g_w, g_sin2)
        g_te, g_b2 = g_te + g_te2, g_b2 + g_b22
        return (tuple(g_d[i] + g_b1 * t[i] + g_b2 * e[i] for i in range(3)),
                tuple(u * g_d[i] + g_te * e[i] + g_b1 * r0[i] for i in range(3)))

    return (u, dist - radius, n, floor, curv, centre), back


def nearest(obs: Any, p, t, lo, hi, r, count: int) -> tuple[Any, Any]:
    """The broad phase: each piece's ``count`` obstacles of the stack nearest it (by the exact gap
    from its centreline segment), as a stack with leaves (n_c, count, ...), and each piece's
    smallest gap over the whole stack (n_c, 1), m. p, t: three (n_c, m) arrays."""
    gap = _profile(obs)(obs, p, t, lo, hi, r)[0][1]  # the law's closest points alone: the rest is never built
    m = gap.shape[-1]
    picks, left = [], gap
    for _ in range(count):  # a few argmins: cheaper than a sort for small counts
        j = jnp.argmin(left, axis=-1)
        picks.append(j)
        left = jnp.where(jnp.arange(m) == j[..., None], jnp.inf, left)
    idx = jnp.stack(picks, -1)
    return jax.tree.map(lambda x: jnp.take(x, idx, axis=0), obs), jnp.min(gap, axis=-1, keepdims=True)


def compact(obs: Any, p, t, lo, hi, r, count: int, reach) -> tuple[Any, Any, Any, Any]:
    """The broad phase over the whole rod: up to ``count`` of its (piece, obstacle) pairs closer than
    ``reach`` (m, between the surfaces), the first in the rod's order. Returns the picked obstacles as
    a stack with leaves (count, ...), the picked pieces' indices (count,), which of the picks are real
    (count,; the rest point at pair 0 and count for nothing) and each piece's smallest gap over the
    whole stack (n_c,), m. p, t: three (n_c, m) arrays; lo, hi, r: (n_c, 1)."""
    gap = _profile(obs)(obs, p, t, lo, hi, r)[0][1] - r
    m = gap.shape[-1]
    near = gap.reshape(-1) < reach
    # a mask's first count entries: no sort, no argmin passes (each pass costs as much as the gaps)
    idx = jnp.nonzero(near, size=count, fill_value=0)[0]
    real = jnp.arange(count) < jnp.sum(near)
    return jax.tree.map(lambda x: jnp.take(x, idx % m, axis=0), obs), idx // m, real, jnp.min(gap, axis=-1)


def _profile(obs):
    return _sphere if isinstance(obs, Sphere) else _capsule


def stacked_law(obs: Any, p, tangent, omega, vel, radius, lo, hi, pen, count: int | None = None,
                pairs: int | None = None) -> tuple:
    """World force (3,) and moment about the centre (3,) on every piece from a stack of static
    spheres or capsules (each component (n_c,)), each piece's smallest gap (n_c,) and its
    penalty energy (n_c,).

    p, tangent, omega, vel: (n_c, 3) world; radius, lo, hi: (n_c,) m (``contact.law``); count: if
    fewer than the stack's, the law runs on each piece's ``count`` nearest obstacles alone (exact
    while no piece is within the smoothing length of more of them at once); pairs: if fewer than
    the pieces times the stack, the law runs on at most ``pairs`` (piece, obstacle) pairs
    within the smoothing length, the first in the rod's order (exact while no more are at once)."""
    assert isinstance(obs, (Sphere, Capsule)) and obs.motion is None
    m, n_c = jnp.shape(obs.radius)[0], p.shape[0]
    col = lambda x, m: tuple(jnp.broadcast_to(x[..., i, None], x.shape[:-1] + (m,)) for i in range(3))  # noqa: E731
    r, lo, hi = radius[..., None], lo[..., None], hi[..., None]
    gap_min, total = None, lambda x: jnp.sum(x, axis=-1)  # noqa: E731
    if pairs is not None and pairs < n_c * m:
        obs, piece, real, gap_min = compact(obs, col(p, m), col(tangent, m), lo, hi, r, pairs, pen.smoothing)
        p, tangent, omega, vel, r, lo, hi = (jnp.take(x, piece, axis=0) for x in (p, tangent, omega, vel, r, lo, hi))
        obs = jax.tree.map(lambda x: x[:, None], obs)
        m, gap_min = 1, gap_min[:, None]
        # back onto the pieces: a one-hot sum, which fuses where a scatter would not
        spread = ((piece[:, None] == jnp.arange(n_c)) & real[:, None]).astype(p.dtype)
        total = lambda x: jnp.sum(x * spread, axis=0)  # noqa: E731
    elif count is not None and count < m:
        obs, gap_min = nearest(obs, col(p, m), col(tangent, m), lo, hi, r, count)
        m, gap_min = count, gap_min - r
    p, t, omega, vel = col(p, m), col(tangent, m), col(omega, m), col(vel, m)
    l, k = pen.smoothing, pen.stiffness

    (u, gap, n, floor, curv, centre), back = _profile(obs)(obs, p, t, lo, hi, r)
    energy, I0, I2, I_chi, phi_lo, phi_hi = penetration.curved(floor - r, curv, lo - centre, hi - centre, l)
    push = k * I0
    d_p, d_t = back((-push, -k * I2, k * (phi_lo - phi_hi)))
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
    return (tuple(total(f[i] - d_p[i]) for i in range(3)), tuple(total(m_other[i] - m_el[i]) for i in range(3)),
            jnp.min(g if gap_min is None else gap_min, axis=-1), total(k * energy))
