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

from gvsjax.obstacles import TINY, Capsule, Sphere, capsule_curvature, segment_closest


def smooth_depth(gap, l):
    return l * jax.nn.softplus(-gap / l)


def curved_area(gap, curv, u, centre, lo, hi, l):
    """For a gap growing like curv (w - centre)^2 / 2 about its minimum at ``centre`` (gap at u):
    the integral over [lo, hi] of the depth (its peak smoothed), the length where it is
    positive, and u (where the force acts)."""
    peak = smooth_depth(gap - 0.5 * curv * (u - centre) ** 2, l)
    half = jnp.sqrt(2.0 * peak / curv + TINY * TINY)
    a = jnp.clip(centre - half, lo, hi)
    b = jnp.clip(centre + half, lo, hi)
    return peak * (b - a) - curv * ((b - centre) ** 3 - (a - centre) ** 3) / 6.0, b - a, u


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _piece(obs, p, t, lo, hi):
    """(u, gap, normal, curvature, centre) of ``Sphere.piece`` / ``Capsule.piece``, p and t three
    (n_c, 1) arrays, the stack's leaves (m, ...)."""
    dtype = p[0].dtype
    if isinstance(obs, Sphere):
        c = jnp.asarray(obs.centre, dtype)
        cp = tuple(c[:, i] - p[i] for i in range(3))
        centre = _dot(cp, t)
        u = jnp.clip(centre, lo, hi)
        d = tuple(p[i] + u * t[i] - c[:, i] for i in range(3))
        dist = jnp.sqrt(_dot(d, d) + TINY * TINY)
        return u, dist - jnp.asarray(obs.radius, dtype), tuple(x / dist for x in d), 1.0 / dist, centre
    a = jnp.asarray(obs.start, dtype)
    e_arr = jnp.asarray(obs.end, dtype) - a
    e = tuple(e_arr[:, i] for i in range(3))
    ee = _dot(e, e)
    r0 = tuple(p[i] - a[:, i] for i in range(3))
    u, sigma, centre, sin2 = segment_closest(_dot(t, e), _dot(t, r0), _dot(e, r0), ee, lo, hi)
    d = tuple(r0[i] + u * t[i] - sigma * e[i] for i in range(3))
    dist = jnp.sqrt(_dot(d, d) + TINY * TINY)
    curv = capsule_curvature(sigma, sin2, dist)
    return u, dist - jnp.asarray(obs.radius, dtype), tuple(x / dist for x in d), curv, centre


def stacked_law(obs: Any, p, tangent, omega, vel, radius, lo, hi, pen) -> tuple:
    """World force (3,) and moment about the centre (3,) on every piece from a stack of static
    spheres or capsules (each component (n_c,)), and each piece's smallest gap (n_c,).

    p, tangent, omega, vel: (n_c, 3) world; radius, lo, hi: (n_c,) m (``contact.law``)."""
    assert isinstance(obs, (Sphere, Capsule)) and obs.motion is None
    col = lambda x: tuple(x[..., i, None] for i in range(3))  # noqa: E731
    p, t, omega, vel = col(p), col(tangent), col(omega), col(vel)
    r, lo, hi = radius[..., None], lo[..., None], hi[..., None]
    l = pen.smoothing
    u, gap, n, curv, centre = _piece(obs, p, t, lo, hi)
    g = gap - r
    area, length, u = curved_area(g, curv, u, centre, lo, hi, l)
    chi = jax.nn.sigmoid(-g / l)
    arm = tuple(u * t[i] - r * n[i] for i in range(3))
    w_arm = _cross(omega, arm)
    v_rel = tuple(vel[i] + w_arm[i] for i in range(3))
    v_n = _dot(v_rel, n)
    f_n = jnp.maximum(pen.stiffness * area - pen.damping * chi * v_n * length, 0.0)
    v_t = tuple(v_rel[i] - v_n * n[i] for i in range(3))
    slip = jnp.sqrt(_dot(v_t, v_t) + pen.slip_speed**2)
    f = tuple(f_n * (n[i] - pen.friction * v_t[i] / slip) for i in range(3))
    m = _cross(arm, f)
    total = lambda x: jnp.sum(x, axis=-1)  # noqa: E731
    return tuple(total(x) for x in f), tuple(total(x) for x in m), jnp.min(g, axis=-1)
