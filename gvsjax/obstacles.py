"""Obstacles for contact: planes, spheres, capsules and boxes, as pytrees.

Positions and sizes are leaves (they batch with ``vmap`` and differentiate); an
optional ``motion`` (static) is a law ``t -> (3,)`` translating the obstacle
(m), whose velocity is taken by forward-mode autodiff.

Each obstacle answers one question for a straight piece of the rod's
centreline, ``x(u) = p + u t`` for ``u`` in ``[lo, hi]`` (m): where along it
the contact acts (``u*``), the signed distance ``g`` from the centreline there
to the obstacle's surface, the outward normal there, and the *overlap
profile*, so that the contact law can integrate a penalty per unit length over
the piece in closed form. All functions broadcast over leading axes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from flax import struct

TINY = 1e-12  # m: keeps norms and their gradients finite at zero distance
FLAT = 1e6  # m: the profile radius standing for "flat" (a plane, a parallel capsule)


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

    u: where the force acts along the piece (m); gap: signed distance from the
    centreline there to the surface (m; subtract the rod's radius for the
    contact gap); normal (..., 3): unit, from the obstacle towards the rod;
    curvature: of the gap along the piece, gap ~ gap_min + curvature (u - centre)^2 / 2 (1/m;
    0 when flat);
    centre: where along the (infinite) piece the profile peaks (m);
    slope: d(gap)/du along the piece for a flat profile; velocity (3,): the
    obstacle's translational velocity (m/s).
    """

    u: Any
    gap: Any
    normal: Any
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

    def piece(self, p, t, lo, hi, time) -> Piece:
        x0, v = _shift(self.motion, time, p.dtype)
        n = jnp.asarray(self.normal, p.dtype) / _norm(jnp.asarray(self.normal, p.dtype))
        gap = _dot(p - (jnp.asarray(self.point, p.dtype) + x0), n)
        zero = jnp.zeros_like(gap)
        # the gap is linear along the piece: the law integrates it exactly; the force acts at u = 0
        return Piece(zero, gap, jnp.broadcast_to(n, p.shape), zero, zero, _dot(t, n), v)


@struct.dataclass
class Sphere:
    """A ball of ``radius`` (m) about ``centre`` (3,)."""

    centre: Any = (0.0, 0.0, 0.0)
    radius: Any = 0.1
    motion: Any = struct.field(pytree_node=False, default=None)

    def piece(self, p, t, lo, hi, time) -> Piece:
        x0, v = _shift(self.motion, time, p.dtype)
        c = jnp.asarray(self.centre, p.dtype) + x0
        centre = _dot(c - p, t)  # the piece's nearest approach to c, unclamped
        u = jnp.clip(centre, lo, hi)
        d = p + u[..., None] * t - c
        dist = _norm(d)
        # along the piece the centreline's distance to c grows like sqrt(dist^2 + u^2)
        return Piece(u, dist - self.radius, d / dist[..., None], 1.0 / dist, centre, jnp.zeros_like(dist), v)


@struct.dataclass
class Capsule:
    """All points within ``radius`` (m) of the segment from ``start`` (3,) to ``end`` (3,): a
    cylinder with hemispherical caps (a post, a bar, a thin rod)."""

    start: Any = (0.0, 0.0, 0.0)
    end: Any = (0.0, 0.0, 1.0)
    radius: Any = 0.02
    motion: Any = struct.field(pytree_node=False, default=None)

    def piece(self, p, t, lo, hi, time) -> Piece:
        x0, v = _shift(self.motion, time, p.dtype)
        a = jnp.asarray(self.start, p.dtype) + x0
        e = jnp.asarray(self.end, p.dtype) - jnp.asarray(self.start, p.dtype)
        ee = _dot(e, e)
        r0 = p - a
        u, sigma, centre, sin2 = segment_closest(_dot(t, e), _dot(t, r0), _dot(e, r0), ee, lo, hi)
        d = r0 + u[..., None] * t - sigma[..., None] * e
        dist = _norm(d)
        return Piece(u, dist - self.radius, d / dist[..., None], capsule_curvature(sigma, sin2, dist), centre,
                     jnp.zeros_like(dist), v)


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


def capsule_curvature(sigma, sin2, dist):
    """Along the piece the distance to the axis grows like sqrt(dist^2 + u^2 sin^2): a crossing bar
    is a profile of curvature sin^2 / dist; past the capsule's ends it is a sphere's, 1 / dist."""
    inside = (sigma > 0.0) & (sigma < 1.0)
    return jnp.where(inside, jnp.maximum(sin2, 1.0 / FLAT), 1.0) / dist


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

    def piece(self, p, t, lo, hi, time) -> Piece:
        x0, v = _shift(self.motion, time, p.dtype)
        centre = _dot(jnp.asarray(self.centre, p.dtype) + x0 - p, t)
        u = jnp.clip(centre, lo, hi)
        gap, n = self.sdf(p + u[..., None] * t, x0)
        # faces are flat: the law spreads the penalty over the piece (linear in u across a face)
        return Piece(u, gap, n, jnp.zeros_like(gap), jnp.zeros_like(gap), _dot(t, n), v)


OBSTACLES = (Plane, Sphere, Capsule, Box)
