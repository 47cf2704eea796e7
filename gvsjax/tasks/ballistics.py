"""A ball's drag-free flight from release, in 2D or 3D: the vertical is the last component.

p(tau) = p0 + v0 tau - g e_v tau^2 / 2 until the ball, descending, reaches a
floor height; the exact closest distance between that path and a target is a
cubic's root. Every throwing task scores its throws with these functions.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def _down(x: jax.Array, g) -> jax.Array:
    """The acceleration (-g along the last axis) shaped like the points ``x``."""
    return jnp.zeros(x.shape[-1]).at[-1].set(-1.0) * jnp.asarray(g)


def flight_point(p0, v0, tau, g):
    """Ball position (..., d) after flight time tau (s)."""
    tau = jnp.asarray(tau)[..., None]
    return p0 + v0 * tau + 0.5 * _down(p0, g) * tau**2


def floor_time(p0, v0, g, floor):
    """Flight time (s) at which the ball, descending, reaches height ``floor`` (0 if never)."""
    disc = v0[..., -1] ** 2 + 2.0 * g * (p0[..., -1] - floor)
    return jnp.maximum((v0[..., -1] + jnp.sqrt(jnp.maximum(disc, 0.0))) / g, 0.0)


def _cubic_real_roots(b, c, d):
    """Three candidate real roots of x^3 + b x^2 + c x + d (repeats when only one is real)."""
    p = c - b * b / 3.0
    q = 2.0 * b**3 / 27.0 - b * c / 3.0 + d
    disc = (q / 2.0) ** 2 + (p / 3.0) ** 3
    one = disc > 0.0
    sq = jnp.sqrt(jnp.where(one, disc, 1.0))
    x1 = jnp.cbrt(-q / 2.0 + sq) + jnp.cbrt(-q / 2.0 - sq)
    p_neg = jnp.where(one, -1.0, jnp.minimum(p, -1e-300))
    m = 2.0 * jnp.sqrt(-p_neg / 3.0)
    arg = jnp.clip(3.0 * q / (p_neg * m), -1.0, 1.0)
    phi = jnp.arccos(arg) / 3.0
    xs = jnp.stack([m * jnp.cos(phi - 2.0 * jnp.pi * i / 3.0) for i in range(3)], -1)
    xs = jnp.where(one[..., None], x1[..., None], xs)
    return xs - b[..., None] / 3.0


def closest_offset(p0, v0, target, g, tau_end):
    """The path's closest point to ``target`` minus the target (d,), 0 <= tau <= tau_end: ``(offset, tau*)``.

    d/dtau |p - target|^2 / 2 is the cubic (g^2/2) tau^3 - (3/2) g v0z tau^2 + (|v0|^2 - g dz) tau
    + d.v0 with d = p0 - target and z the vertical; its real roots (closed form, two Newton
    polishes) and the two ends are the candidates. tau* carries no gradient; where it is interior,
    the offset's derivative is projected across the flight (tau* re-absorbs any motion along it),
    which makes it the derivative of the offset p(tau*(a)) - target to first order: a residual for
    Gauss-Newton whose norm is the miss.
    """
    d = p0 - target
    c3 = 0.5 * g * g
    c2 = -1.5 * g * v0[..., -1]
    c1 = jnp.sum(v0 * v0, -1) - g * d[..., -1]
    c0 = jnp.sum(d * v0, -1)
    roots = _cubic_real_roots(c2 / c3, c1 / c3, c0 / c3)
    for _ in range(2):  # Newton polish: closed-form roots lose digits near double roots
        f = ((c3 * roots + c2[..., None]) * roots + c1[..., None]) * roots + c0[..., None]
        fp = (3.0 * c3 * roots + 2.0 * c2[..., None]) * roots + c1[..., None]
        step = jnp.where(jnp.abs(fp) > 1e-12, f / jnp.where(fp == 0.0, 1.0, fp), 0.0)
        roots = roots - step
    tau_end = jax.lax.stop_gradient(jnp.asarray(tau_end))
    cands = jnp.concatenate([jnp.clip(roots, 0.0, tau_end[..., None]),
                             jnp.zeros_like(roots[..., :1]), tau_end[..., None]], -1)
    cands = jax.lax.stop_gradient(cands)
    dist2 = jnp.sum((flight_point(p0[..., None, :], v0[..., None, :], cands, g)
                     - target[..., None, :]) ** 2, -1)
    tau = jnp.take_along_axis(cands, jnp.argmin(dist2, -1)[..., None], -1)[..., 0]
    r = flight_point(p0, v0, tau, g) - target
    vel = jax.lax.stop_gradient(v0 + _down(p0, g) * tau[..., None])
    u = vel / jnp.maximum(jnp.linalg.norm(vel, axis=-1, keepdims=True), 1e-12)
    dr = r - jax.lax.stop_gradient(r)
    across = dr - jnp.sum(dr * u, -1, keepdims=True) * u
    interior = ((tau > 0.0) & (tau < tau_end))[..., None]
    return jax.lax.stop_gradient(r) + jnp.where(interior, across, dr), tau


def distance(offset):
    """|offset| over the last axis, its derivative finite at 0 (sqrt(0) has an infinite one)."""
    sq = jnp.sum(offset * offset, -1)
    return jnp.where(sq > 0.0, jnp.sqrt(jnp.where(sq > 0.0, sq, 1.0)), 0.0)


def closest_approach(p0, v0, target, g, tau_end):
    """Exact closest distance (m) between the path p(tau), 0 <= tau <= tau_end, and target:
    ``(distance, tau*)``, the norm of ``closest_offset``. By the envelope theorem the distance's
    gradient is exact although tau* carries none."""
    r, tau = closest_offset(p0, v0, target, g, tau_end)
    return distance(r), tau


def miss_metrics(miss: np.ndarray) -> dict[str, float]:
    """Summary of misses (m): success < 10 cm, shares within 1 cm and 5 mm, quantiles."""
    return {
        "n_targets": int(len(miss)),
        "success_rate_10cm": float(np.mean(miss < 0.10)),
        "within_1cm": float(np.mean(miss < 0.01)),
        "within_5mm": float(np.mean(miss < 0.005)),
        "median_m": float(np.median(miss)),
        "p95_m": float(np.percentile(miss, 95)),
        "max_m": float(np.max(miss)),
        "mean_m": float(np.mean(miss)),
    }
