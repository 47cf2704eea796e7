"""A rest strain that changes in time: active strain as a generalized force.

Pneumatic chambers, muscle fibres and shape-memory wires do not push on a rod from
outside: they change the shape the rod would take unloaded, its rest (natural)
strain xi*(X). In the GVS model the elastic force is

    F_el = -int_0^L Phi(s)^T Sigma(s) (xi(s) - xi*(s)) ds,

so adding delta(X) to the rest strain adds the generalized force

    tau = int_0^L Phi(s)^T Sigma(s) delta(s) ds,

which depends on the basis and the section's stiffness only, not on q: it is linear
in delta, and the rest strain enters the dynamics exactly as a constant or
time-varying force through the strain basis. A rod with no other load settles where
its strain is the basis' stiffness-weighted projection of xi* (exactly xi* when the
basis can represent it: a constant rest curvature on a basis with a constant bending
term gives an arc of exactly that curvature).

``Robot.rest_strains`` lists ``RestStrainSegments``: piecewise-constant deltas on
segments of a link, one value per segment and strain component; ``simulate(...,
rest_strain=u)`` and ``equilibrium(..., rest_strain=u)`` take the values ``u``, shape
``(n_values,)`` (the entries' ``(n_segments, n_components)`` blocks flattened, segment
by segment, and concatenated) or ``(n_segments, n_components)`` for a single entry.
A piecewise-constant delta is not in a polynomial basis: its projection shows Gibbs
ripples along the link, but the tip pose, an integral of the strain, converges fast
with the basis order (docs/modelling.md, "Rest-strain inputs").

``force_map(robot)`` is the (n_dofs, n_values) matrix B with tau = B u, integrated
exactly (Gauss-Legendre on each segment) and traced from the robot's leaves, so a
batched or differentiated material gives its own B.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from gvsjax.core.dynamics import section
from gvsjax.core.model import STRAIN_NAMES, RestStrainSegments, Robot, SoftLink
from gvsjax.core.validation import concrete, require


def size(robot: Robot) -> int:
    """The number of rest-strain values ``simulate``'s ``rest_strain`` takes (0 without ``rest_strains``)."""
    return sum(int(np.prod(seg.shape)) for seg in robot.rest_strains)


def _segment_rows(link: SoftLink, seg: RestStrainSegments, a: float, b: float):
    """[(component index, (n_gauss, n_soft) raw basis row at the points, points, weights)] on [a, b]."""
    order = max(link.basis.orders)
    nodes, weights = np.polynomial.legendre.leggauss(order // 2 + 4)  # degree order + 4 (a taper's I ~ X^4)
    X = 0.5 * (b - a) * nodes + 0.5 * (a + b)
    w = 0.5 * (b - a) * weights
    raw = np.stack([link.basis.raw(x) for x in X])  # (n_gauss, 6, n_soft)
    return [(STRAIN_NAMES.index(c), raw[:, STRAIN_NAMES.index(c), :], X, w) for c in seg.components]


def force_map(robot: Robot) -> jnp.ndarray:
    """B, (n_dofs, n_values): the generalized force of unit rest-strain values, tau = B u."""
    n = robot.n_dofs
    cols = []
    slices = robot.dof_slices()
    for seg in robot.rest_strains:
        link = robot.links[seg.link]
        _, s0, end = slices[seg.link % len(robot.links)]
        for a, b in zip(seg.knots[:-1], seg.knots[1:]):
            for c, rows, X, w in _segment_rows(link, seg, float(a), float(b)):
                # the angular rows carry SoRoSim's 1/L, which cancels ds = L dX
                length = 1.0 if c < 3 else link.length
                stiff = jnp.stack([jnp.asarray(section(link, x).stiffness[c]) for x in X])  # (n_gauss,)
                col = length * jnp.einsum("g,g,gj->j", jnp.asarray(w), stiff, jnp.asarray(rows))
                cols.append(jnp.zeros(n, col.dtype).at[s0:end].set(col))
    if not cols:
        return jnp.zeros((n, 0))
    return jnp.stack(cols, axis=1)


def check_value(robot: Robot, value, name: str = "rest_strain"):
    """A constant rest-strain input as a (n_values,) array; the shape is checked always, the numbers
    when concrete (finite). A callable passes through."""
    m = size(robot)
    require(m > 0 or value is None, name, value, "None: this robot has no rest_strains (Robot.rest_strains)")
    if value is None or callable(value):
        return value
    shapes = [(m,)] + ([robot.rest_strains[0].shape] if len(robot.rest_strains) == 1 else [])
    require(not isinstance(value, (str, bytes, bool)) and tuple(np.shape(value)) in shapes, name, value,
            f"an array of shape {' or '.join(str(s) for s in shapes)} (one value per segment and component), "
            "or a callable")
    if concrete(value):  # traced values are checked where they are used (a task flags a non-finite state)
        require(bool(np.all(np.isfinite(np.asarray(value, dtype=float)))), name, value,
                "finite values (1/m for angular strains, dimensionless for linear ones)")
    return jnp.reshape(jnp.asarray(value, dtype=float), (m,))


__all__ = ["size", "force_map", "check_value"]
