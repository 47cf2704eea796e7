"""The obstacle tasks' scenes: the 2D posts and the 3D random capsules, as capsule ends (m, 2, 3)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

POSTS_XZ = ((0.2, 0.12), (0.6, 0.12), (0.4, 0.0), (0.4, 0.37), (0.4, 0.57), (0.4, 0.77))  # m
# bars along y through the posts: the planar arm stays at y = 0, so only their circle in the x-z plane is met
POSTS_2D = np.array([[[x, -0.5, z], [x, 0.5, z]] for x, z in POSTS_XZ])

BOX_LOW = np.array([0.3, -0.6, -0.1])  # m, where the random capsules lie (both ends inside)
BOX_HIGH = np.array([0.6, 0.6, 0.8])
LENGTH = 1.0  # m, each capsule's
GAP = 0.015  # m, the least distance between two capsules' axes
# draws per capsule, the first that fits kept: ~1.2% land inside the box (~100 of 8192); of the first
# SHORTLIST inside it, the first clear of the others is kept (rejection sampling, in a fixed-size program)
CANDIDATES = 8192
SHORTLIST = 32


def segment_distance(p0, p1, q0, q1) -> jax.Array:
    """The least distance between segments p0-p1 and q0-q1 (3,) (the clamped closest points)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f = d1 @ d1, d2 @ d2, d2 @ r
    c, b = d1 @ r, d1 @ d2
    denom = a * e - b * b
    s = jnp.where(denom > 1e-12, jnp.clip((b * f - c * e) / jnp.where(denom > 1e-12, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / e
    s = jnp.where(t < 0.0, jnp.clip(-c / a, 0.0, 1.0), jnp.where(t > 1.0, jnp.clip((b - c) / a, 0.0, 1.0), s))
    t = jnp.clip(t, 0.0, 1.0)
    return jnp.linalg.norm(p0 + s * d1 - (q0 + t * d2))


def random_capsules(key: jax.Array, n: int = 8) -> jax.Array:
    """(n, 2, 3) ends of n capsules drawn as the benchmark does: a centre uniform in the box, a
    uniformly random direction, both ends inside the box, at least ``GAP`` from those drawn before."""
    low, high = jnp.asarray(BOX_LOW), jnp.asarray(BOX_HIGH)

    def one(placed, inputs):
        i, k = inputs
        k_c, k_d = jax.random.split(k)
        centre = jax.random.uniform(k_c, (CANDIDATES, 3), minval=low, maxval=high)
        u = jax.random.normal(k_d, (CANDIDATES, 3))
        u = u / jnp.linalg.norm(u, axis=1, keepdims=True)
        a, b = centre - 0.5 * LENGTH * u, centre + 0.5 * LENGTH * u
        inside = jnp.all((a >= low) & (a <= high) & (b >= low) & (b <= high), axis=1)
        short = jnp.nonzero(inside, size=SHORTLIST, fill_value=0)[0]
        dist = jax.vmap(lambda p, q: jax.vmap(lambda s: segment_distance(p, q, s[0], s[1]))(placed))(a[short],
                                                                                                  b[short])
        apart = jnp.all((dist >= GAP) | (jnp.arange(n)[None, :] >= i), axis=1) & inside[short]
        pick = short[jnp.argmax(apart)]
        ends = jnp.stack([a[pick], b[pick]])
        return placed.at[i].set(ends), None

    placed, _ = jax.lax.scan(one, jnp.zeros((n, 2, 3)), (jnp.arange(n), jax.random.split(key, n)))
    return placed
