"""Obstacles for contact: planes, spheres, capsules and boxes, as pytrees.

Positions and sizes are leaves (they batch with ``vmap`` and differentiate); an
optional ``motion`` (static) is a law ``t -> (3,)`` translating the obstacle
(m), whose velocity is taken by forward-mode autodiff.

Each obstacle answers one question for a straight piece of the rod's
centreline, ``x(u) = p + u t`` for ``u`` in ``[lo, hi]`` (m): the point ``u*``
of the piece nearest it, the signed distance ``g`` from the centreline there to
the obstacle's surface and the outward normal there (where damping and
friction act), and the *gap profile* along the piece, linear (planes, box
faces) or a parabola (spheres, capsules), whose integral is the penalty's
energy (``gvsjax.core.penetration``). The profile's parameters are smooth functions
of the piece's pose, so the law's forces, their derivatives, are exact. All
functions broadcast over leading axes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from flax import struct

TINY = 1e-12  # m: keeps norms and their gradients finite at zero distance
LEAST_BEND = 1e-9  # the least profile curvature, times the radii: a capsule parallel to the piece


def _norm(v):
    return jnp.sqrt(jnp.sum(v * v, axis=-1) + TINY * TINY)


def _dot(a, b):
    return jnp.sum(a * b, axis=-1)


def _shift(motion: Callable | None, t, dtype) -> tuple[Any, Any]:
    """Displacement (3,) and velocity (3,) of a moving obstacle at t (zeros when static)."""
    if motion is None:
        return 0.0, 0.0
    t = jnp.asarray(t, dtype)
    x, v = jax.jvp(lambda s: jnp.reshape(jnp.asarray(motion(s), dtype=t.dtype), (3,)), (t,), (jnp.ones_like(t),))
    return x, v


class Piece(NamedTuple):
    """An obstacle's answer for one rod piece (shapes: the broadcast leading axes).

    u: the piece's point nearest the obstacle (m); gap: signed distance from the
    centreline there to the surface (m; subtract the rod's radius for the
    contact gap); normal (..., 3): unit, from the obstacle towards the rod, there;
    the profile: a flat one is gap + slope (w - u) along the piece (slope: d gap / du),
    a curved one floor + curvature (w - centre)^2 / 2 (floor: its least gap, m;
    curvature 1/m; centre: its vertex along the infinite piece, m); velocity (3,):
    the obstacle's translational velocity (m/s).
    """

    u: Any
    gap: Any
    normal: Any
    floor: Any
    curvature: Any
    centre: Any
    slope: Any
    velocity: Any


@struct.dataclass
class Plane:
    """A half-space: ``point`` (3,) on its surface, ``normal`` (3,) pointing out of the solid
    (normalised when used). Ground: ``Plane(normal=(0, 1, 0))`` with gravity along -y."""

    point: Any = (0.0, 0.0, 0.0)
    normal: Any = (0.0, 1.0, 0.0)
    motion: Any = struct.field(pytree_node=False, default=None)

    def piece(self, p, t, lo, hi, time, rod_radius=0.0) -> Piece:
        x0, v = _shift(self.motion, time, p.dtype)
        n = jnp.asarray(self.normal, p.dtype) / _norm(jnp.asarray(self.normal, p.dtype))
        gap = _dot(p - (jnp.asarray(self.point, p.dtype) + x0), n)
        zero = jnp.zeros_like(gap)
        return Piece(zero, gap, jnp.broadcast_to(n, p.shape), gap, zero, zero, _dot(t, n), v)


@struct.dataclass
class Sphere:
    """A ball of ``radius`` (m) about ``centre`` (3,)."""

    centre: Any = (0.0, 0.0, 0.0)
    radius: Any = 0.1
    motion: Any = struct.field(pytree_node=False, default=None)

    def piece(self, p, t, lo, hi, time, rod_radius=0.0) -> Piece:
        x0, v = _shift(self.motion, time, p.dtype)
        c = jnp.asarray(self.centre, p.dtype) + x0
        centre = _dot(c - p, t)  # the piece's nearest approach to c, unclamped
        u = jnp.clip(centre, lo, hi)
        d = p + u[..., None] * t - c
        dist = _norm(d)
        curv = sphere_curvature(self.radius, rod_radius)
        return Piece(u, dist - self.radius, d / dist[..., None], anchored_floor(dist - self.radius, curv, u, centre),
                     curv, centre, jnp.zeros_like(dist), v)


@struct.dataclass
class Capsule:
    """All points within ``radius`` (m) of the segment from ``start`` (3,) to ``end`` (3,): a
    cylinder with hemispherical caps (a post, a bar, a thin rod)."""

    start: Any = (0.0, 0.0, 0.0)
    end: Any = (0.0, 0.0, 1.0)
    radius: Any = 0.02
    motion: Any = struct.field(pytree_node=False, default=None)

    def piece(self, p, t, lo, hi, time, rod_radius=0.0) -> Piece:
        x0, v = _shift(self.motion, time, p.dtype)
        a = jnp.asarray(self.start, p.dtype) + x0
        e = jnp.asarray(self.end, p.dtype) - jnp.asarray(self.start, p.dtype)
        ee = _dot(e, e)
        r0 = p - a
        te, b2 = _dot(t, e), _dot(e, r0)
        u, sigma, centre, sin2 = segment_closest(te, _dot(t, r0), b2, ee, lo, hi)
        d = r0 + u[..., None] * t - sigma[..., None] * e
        dist = _norm(d)
        curv = sphere_curvature(self.radius, rod_radius) * capsule_bend(te, b2, ee, sin2, lo, hi,
                                                                        self.radius + rod_radius)
        return Piece(u, dist - self.radius, d / dist[..., None], anchored_floor(dist - self.radius, curv, u, centre),
                     curv, centre, jnp.zeros_like(dist), v)


def sphere_curvature(radius, rod_radius):
    """The profile's curvature past a ball of ``radius`` (1/m): 1 / (radius + rod radius), so the
    parabola has the overlap's chord of a shallow contact to second order (and overestimates a
    deep one's, never shrinking as the rod goes deeper)."""
    return 1.0 / (radius + rod_radius)


def anchored_floor(gap, curvature, u, centre):
    """The parabola's least gap, so that it passes through the true ``gap`` at the piece's nearest
    point u (the vertex itself when inside the piece). C^1 in the pose as u leaves the vertex:
    the gap is stationary in u there."""
    return gap - 0.5 * curvature * (u - centre) ** 2


def segment_closest(te, b1, b2, ee, lo, hi):
    """The closest points of a piece p + u t (|t| = 1, u in [lo, hi]) and a segment a + sigma e
    (sigma in [0, 1]) from te = t.e, b1 = t.(p - a), b2 = e.(p - a), ee = e.e: (u, sigma,
    the unclamped u of the lines' closest approach, sin^2 of their angle). Layout-free scalars."""
    sin2 = jnp.maximum(1.0 - te * te / ee, 0.0)
    sigma = jnp.clip((b2 - b1 * te) / jnp.maximum(ee * sin2, TINY), 0.0, 1.0)
    centre = sigma * te - b1
    sigma = jnp.clip((centre * te + b2) / ee, 0.0, 1.0)
    centre = sigma * te - b1
    u = jnp.clip(centre, lo, hi)
    return u, jnp.clip((u * te + b2) / ee, 0.0, 1.0), centre, sin2


def within(x, lo, hi):
    """d clip(x, lo, hi) / dx: 1 strictly inside, else 0."""
    return ((x > lo) & (x < hi)).astype(x.dtype)


def segment_closest_back(te, b1, b2, ee, lo, hi, g_u, g_sigma, g_centre, g_sin2):
    """The reverse pass of ``segment_closest`` by hand: cotangents of (u, sigma, centre, sin2) ->
    those of (te, b1, b2). Its derivatives to rounding (away from the clips' corners, where it
    takes one side); one fused pass instead of autodiff's stored residuals."""
    s2 = 1.0 - te * te / ee
    sin2 = jnp.maximum(s2, 0.0)
    den = jnp.maximum(ee * sin2, TINY)
    r0 = (b2 - b1 * te) / den
    s0 = jnp.clip(r0, 0.0, 1.0)
    c0 = s0 * te - b1
    r1 = (c0 * te + b2) / ee
    s1 = jnp.clip(r1, 0.0, 1.0)
    centre = s1 * te - b1
    u = jnp.clip(centre, lo, hi)
    r2 = (u * te + b2) / ee
    g_r2 = g_sigma * within(r2, 0.0, 1.0)
    g_u = g_u + g_r2 * te / ee
    g_te, g_b2 = g_r2 * u / ee, g_r2 / ee
    g_c = g_centre + g_u * within(centre, lo, hi)
    g_r1 = g_c * te * within(r1, 0.0, 1.0)
    g_te, g_b1 = g_te + g_c * s1, -g_c
    g_c0 = g_r1 * te / ee
    g_te, g_b2 = g_te + g_r1 * c0 / ee, g_b2 + g_r1 / ee
    g_r0 = g_c0 * te * within(r0, 0.0, 1.0)
    g_te, g_b1 = g_te + g_c0 * s0, g_b1 - g_c0
    g_b2, g_b1, g_te = g_b2 + g_r0 / den, g_b1 - g_r0 * te / den, g_te - g_r0 * b1 / den
    g_sin2 = g_sin2 - g_r0 * r0 / den * ee * (ee * sin2 > TINY)
    return g_te - 2.0 * te / ee * g_sin2 * (s2 > 0.0), g_b1, g_b2


def capsule_bend(te, b2, ee, sin2, lo, hi, reach):
    """The capsule's profile curvature over a ball's: along a piece crossing the cylinder at
    angle theta the distance to the axis grows like sqrt(dist^2 + u^2 sin^2 theta), so sin^2;
    past an end cap a ball's, 1. Blended (smoothstep) as the piece's extent, projected on the
    axis, leaves the segment by up to ``reach`` (m), so the energy stays continuous."""
    return _bend(te, b2, ee, sin2, lo, hi, reach)[0]


def _bend(te, b2, ee, sin2, lo, hi, reach):
    s_lo, s_hi = (b2 + lo * te) / ee, (b2 + hi * te) / ee
    below, above = jnp.minimum(s_lo, s_hi) - 1.0, -jnp.maximum(s_lo, s_hi)
    past = jnp.maximum(jnp.maximum(below, above), 0.0)
    x = jnp.minimum(past * jnp.sqrt(ee) / reach, 1.0)
    blend = x * x * (3.0 - 2.0 * x)
    bend = sin2 + (1.0 - sin2) * blend
    return jnp.maximum(bend, LEAST_BEND), (s_lo, s_hi, below, above, past, x, blend, bend)


def capsule_bend_back(te, b2, ee, sin2, lo, hi, reach, g):
    """The reverse pass of ``capsule_bend`` by hand: its cotangent -> those of (te, b2, sin2)."""
    _, (s_lo, s_hi, below, above, past, x, blend, bend) = _bend(te, b2, ee, sin2, lo, hi, reach)
    g = g * (bend > LEAST_BEND)
    g_past = g * (1.0 - sin2) * 6.0 * x * (1.0 - x) * jnp.sqrt(ee) / reach * (past > 0.0)
    g_min, g_max = g_past * (below >= above), -g_past * (below < above)
    first = s_lo <= s_hi  # s_lo is the min
    g_lo = jnp.where(first, g_min, g_max)
    g_hi = jnp.where(first, g_max, g_min)
    return (g_lo * lo + g_hi * hi) / ee, (g_lo + g_hi) / ee, g * (1.0 - blend)


@struct.dataclass
class Box:
    """A box of ``half_extents`` (3,) (m) about ``centre`` (3,), its axes the columns of
    ``rotation`` (3, 3) in the world."""

    centre: Any = (0.0, 0.0, 0.0)
    half_extents: Any = (0.1, 0.1, 0.1)
    rotation: Any = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    motion: Any = struct.field(pytree_node=False, default=None)

    def sdf(self, x, x0=0.0):
        """Signed distance (m) and outward unit normal (world) at world points x (..., 3)."""
        Rb = jnp.asarray(self.rotation, x.dtype)
        h = jnp.asarray(self.half_extents, x.dtype)
        q = (x - (jnp.asarray(self.centre, x.dtype) + x0)) @ Rb  # box coordinates
        a = jnp.abs(q) - h
        outside = jnp.maximum(a, 0.0) * jnp.sign(q)
        d_out = _norm(outside)
        worst = jnp.max(a, axis=-1)
        face = jax.nn.one_hot(jnp.argmax(a, axis=-1), 3, dtype=q.dtype) * jnp.where(q >= 0, 1.0, -1.0)
        is_out = worst > 0
        n_local = jnp.where(is_out[..., None], outside / d_out[..., None], face)
        return jnp.where(is_out, d_out, worst), n_local @ Rb.T

    def piece(self, p, t, lo, hi, time, rod_radius=0.0) -> Piece:
        x0, v = _shift(self.motion, time, p.dtype)
        centre = _dot(jnp.asarray(self.centre, p.dtype) + x0 - p, t)
        u = jnp.clip(centre, lo, hi)
        gap, n = self.sdf(p + u[..., None] * t, x0)
        # faces are flat: the gap is linear along the piece across the face at u
        zero = jnp.zeros_like(gap)
        return Piece(u, gap, n, zero, zero, zero, _dot(t, n), v)


OBSTACLES = (Plane, Sphere, Capsule, Box)
