"""The penalty's smoothed penetration and its integrals along a straight piece of rod.

At gap g (m, negative inside) the penalty pushes with k delta(g) per metre, from the
energy k Phi(g) per metre (Phi' = -delta). delta is the penetration with its corner
rounded over |g| < l (l: the smoothing length) by a parabola, so the force is C^1 in g:

    delta = -g (g <= -l),  (l - g)^2 / (4 l) (|g| < l),  0 (g >= l)
    Phi = g^2 / 2 + l^2 / 6,  (l - g)^3 / (12 l),  0
    chi = -delta' = 1,  (l - g) / (2 l),  0          (weights the damping)

A piece's energy is k times the integral of Phi over it, with the gap along the piece
linear (planes, box faces) or a parabola (spheres, capsules). Both integrals are exact
here, sums of Gauss-Legendre rules over the sub-intervals where the integrand is one
polynomial, so forces and moments are exact derivatives of one energy (a conservative
penalty with a symmetric stiffness), smooth where the piece lies parallel to a plane.
All functions broadcast over leading axes.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

STRIBECK = 10.0  # the static coefficient gives way to the kinetic one around STRIBECK slip speeds
TINY_SLOPE = 1e-12  # |d gap / du| below which a piece counts as parallel when placing breakpoints

_G2 = np.polynomial.legendre.leggauss(2)
_G3 = np.polynomial.legendre.leggauss(3)
_G4 = np.polynomial.legendre.leggauss(4)


def depth(g, l):
    """The smoothed penetration delta(g) (m)."""
    band = (l - g) ** 2 / (4.0 * l)
    return jnp.where(g <= -l, -g, jnp.where(g < l, band, 0.0))


def indicator(g, l):
    """chi(g) = -delta'(g): 1 when deep, 0 when clear."""
    return jnp.clip((l - g) / (2.0 * l), 0.0, 1.0)


def energy_density(g, l):
    """Phi(g) (m^2): the penalty's energy per metre and per unit stiffness."""
    return jnp.where(g <= -l, 0.5 * g * g + l * l / 6.0, jnp.where(g < l, (l - jnp.maximum(g, -l)) ** 3 / (12.0 * l),
                                                                      0.0))


def _gauss(a, b, rule, f):
    """Gauss-Legendre ``rule`` for the integral of f over [a, b] (f returns a tuple)."""
    m, h = 0.5 * (a + b), 0.5 * (b - a)
    total = None
    for x, w in zip(*rule):
        terms = f(m + float(x) * h)
        wh = float(w) * h  # Python floats: a float32 run stays float32
        total = [wh * t for t in terms] if total is None else [s + wh * t for s, t in zip(total, terms)]
    return total


def _deep(g, l):
    return -g, 1.0 + 0.0 * g, 0.5 * g * g + l * l / 6.0


def _band(g, l):
    c = l - g
    return c * c / (4.0 * l), c / (2.0 * l), c * c * c / (12.0 * l)


def flat(g0, slope, lo, hi, l):
    """A gap linear along the piece, g(u) = g0 + slope u on [lo, hi] (m).

    Returns (E, I0, I1, Ic): E = int Phi du (the energy / k, m^3), I0 = int delta du
    (m^2), I1 = int u delta du (m^3), Ic = int chi du (m). Then dE/dg0 = -I0 and
    dE/dslope = -I1: the force on the piece is k I0 along the normal, its moment about
    the sample k I1 t x n."""
    s = jnp.where(slope >= 0.0, jnp.maximum(slope, TINY_SLOPE), jnp.minimum(slope, -TINY_SLOPE))
    at = lambda b: jnp.clip((b - g0) / s, lo, hi)  # noqa: E731  (where g crosses b)
    u_deep, u_clear = at(-l), at(l)
    up = slope >= 0.0  # the gap grows with u: the deep part comes first
    deep_a, deep_b = jnp.where(up, lo, u_deep), jnp.where(up, u_deep, hi)
    band_a, band_b = jnp.minimum(u_deep, u_clear), jnp.maximum(u_deep, u_clear)

    def part(piece):
        def f(u):
            d, c, e = piece(g0 + slope * u, l)
            return e, d, u * d, c
        return f

    deep = _gauss(deep_a, deep_b, _G2, part(_deep))
    band = _gauss(band_a, band_b, _G2, part(_band))
    return tuple(x + y for x, y in zip(deep, band))


def curved(floor, curvature, lo, hi, l):
    """A parabolic gap along the piece, g(w) = floor + curvature w^2 / 2, w in [lo, hi] (m,
    measured from the parabola's vertex; curvature > 0, 1/m).

    Returns (E, I0, I2, Ic, Phi_lo, Phi_hi): E = int Phi dw, I0 = int delta dw, I2 = int
    delta w^2 / 2 dw, Ic = int chi dw and Phi at the two ends. Then dE/dfloor = -I0,
    dE/dcurvature = -I2, and moving the vertex by dc changes E by (Phi_lo - Phi_hi) dc."""
    def reach(b):  # |w| where g crosses b; 0 if it never does (a safe sqrt: finite gradients)
        x = 2.0 * (b - floor) / curvature
        return jnp.where(x > 0.0, jnp.sqrt(jnp.where(x > 0.0, x, 1.0)), 0.0)

    w_deep, w_clear = reach(-l), reach(l)
    clip = lambda w: jnp.clip(w, lo, hi)  # noqa: E731

    def part(piece):
        def f(w):
            d, c, e = piece(floor + 0.5 * curvature * w * w, l)
            return e, d, 0.5 * w * w * d, c
        return f

    deep = _gauss(clip(-w_deep), clip(w_deep), _G3, part(_deep))
    left = _gauss(clip(-w_clear), clip(-w_deep), _G4, part(_band))
    right = _gauss(clip(w_deep), clip(w_clear), _G4, part(_band))
    ends = (energy_density(floor + 0.5 * curvature * w * w, l) for w in (lo, hi))
    return (*(x + y + z for x, y, z in zip(deep, left, right)), *ends)


def friction_coefficient(speed2, static, kinetic, slip_speed):
    """mu(v) / sqrt(v^2 + v_s^2) at slip speed^2 ``speed2`` (m^2/s^2): times the normal force
    and -v_t, the regularised friction. mu falls from ``static`` (slow slip) to ``kinetic``
    (fast) around STRIBECK slip speeds: mu = mu_k + (mu_s - mu_k) / (1 + (v / (STRIBECK v_s))^4)."""
    ratio = speed2 / (STRIBECK * slip_speed) ** 2
    mu = kinetic + (static - kinetic) / (1.0 + ratio * ratio)
    return mu / jnp.sqrt(speed2 + slip_speed * slip_speed)
