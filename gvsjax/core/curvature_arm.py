"""The soft arm of the field's soft-arm RL benchmark, actuated through its natural curvature.

Choi & Tong, "Rapidly Learning Soft Robot Control via Implicit Time-Stepping" (arXiv
2511.06667), control a 1 m rod (radius 5 cm, E 10 MPa, density 1000 kg/m^3, Poisson 0.5)
clamped upright at the origin under gravity by changing its rest curvature at five
control points. Their rod has 21 nodes 5 cm apart; control point k spreads its
integrated curvature (a turning angle) uniformly over the nodes {2-4}, {5-8},
{9-12}, {13-16}, {17-19}, whose Voronoi regions are the segments

    s in [0.075, 0.225], [0.225, 0.425], [0.425, 0.625], [0.625, 0.825], [0.825, 0.975] m,

and, as their code assigns the nodes, the last segment receives 3/4 of its control
point's value (``SEGMENT_SHARE``). A turning angle theta on a segment of length l is a
rest curvature theta / l there: a piecewise-constant rest strain, which
``Robot.rest_strains`` applies (``gvsjax.core.active_strain``).

``curvature_arm`` builds that rod as seven soft links split at the segments' ends,
each with a constant curvature (and twist) per bending direction (Legendre order
``bending_order``, 0 by default): the piecewise-constant rest curvature is then in the
basis exactly, and the links' strains converge to the continuum rod's as the order
grows (docs/tasks_benchmark.md, "The arm": the tip is ~1 mm off a finer split at order 0,
where a single link with a polynomial basis is still ~1 cm off at order 8).
``planar=True`` keeps the bending in the world x-z plane (the benchmark's 2D tasks).
In 3D the rod twists freely (a torsion coordinate per link, GJ = 2/3 EI), as the
benchmark's rod does: under gravity a 3D shape twists it, which moves the tip by
centimetres (docs/tasks_benchmark.md, "The arm"); ``twist=True`` adds the rest twist
of each segment as an input (the 4D IK task). The rod is inextensible and unshearable
(Kirchhoff), as the benchmark's stiff rods nearly are.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gvsjax.core.model import Joint, Material, RestStrainSegments, Robot, SoftLink, StrainBasis
from gvsjax.core.validation import check_robot, nonnegative, positive, require

SEGMENTS = (0.075, 0.225, 0.425, 0.625, 0.825, 0.975)  # fractions of the length: the control segments' ends
SEGMENT_SHARE = (1.0, 1.0, 1.0, 1.0, 0.75)  # of each control point's turning angle, as the benchmark applies it
CONTROL_NODES = (0.1, 0.3, 0.5, 0.7, 0.9)  # m, the control points (nodes 2, 6, 10, 14, 18)
STATE_NODES = tuple(0.1 * k for k in range(1, 11))  # m along a 1 m arm: the observed nodes 2, 4, ..., 20

CURVATURE_ARM = dict(
    length=1.0,  # m
    radius=0.05,  # m
    youngs_modulus=1e7,  # Pa
    density=1000.0,  # kg/m^3
    poisson=0.5,  # G = E / 3
    # Pa s, Kelvin-Voigt: the first bending mode decays at 3.80 1/s, as the benchmark's Elastica arm with its
    # per-length dissipation nu = 10 (experiments/transfer/dismech_damping.py)
    damping=3.29e5,
    gravity=9.8,  # m/s^2, along world -z
    bending_order=0,  # per link
    n_gauss=None,  # per link; default: bending_order + 1
    planar=False,
    torsion=None,  # free twist: None gives it to the 3D arm (as the benchmark's), never to a planar one
    twist=False,  # the rest twist as an input (implies torsion)
)
"""The benchmark arm of Choi & Tong: ``curvature_arm``'s default keywords (SI units)."""

# At rest the rod's local x axis points along world +z, local y along +x and z along +y: bending about
# the local z axis (``bend_z``) moves the tip along world x, about y along world -y.
UPRIGHT = ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0))


def curvature_arm(**overrides: Any) -> Robot:
    """The benchmark's arm (``CURVATURE_ARM``, SI units): seven soft links split at ``SEGMENTS``,
    links 1-5 carrying the control segments as ``Robot.rest_strains`` (one ``RestStrainSegments``
    each, components ``("bend_z", "bend_y")`` in 3D, ``("bend_z",)`` planar, with
    ``"torsion"`` first when ``twist``). In 3D each link has a torsion coordinate
    unless ``torsion=False`` (the arm rigid in torsion)."""
    unknown = sorted(set(overrides) - set(CURVATURE_ARM))
    if unknown:
        raise ValueError(f"curvature_arm got unknown parameter(s) {unknown}; valid: {sorted(CURVATURE_ARM)}")
    p = {**CURVATURE_ARM, **overrides}
    for key in ("length", "radius", "youngs_modulus", "density"):
        positive(key, p[key])
    for key in ("damping", "gravity"):
        nonnegative(key, p[key])
    order = p["bending_order"]
    require(isinstance(order, int) and not isinstance(order, bool) and order >= 0, "bending_order", order,
            "an int >= 0")
    n_gauss = p["n_gauss"] if p["n_gauss"] is not None else order + 1
    require(isinstance(n_gauss, int) and n_gauss >= order + 1, "n_gauss", n_gauss, f"an int >= {order + 1}")
    planar, twist = bool(p["planar"]), bool(p["twist"])
    require(not (planar and twist), "twist", twist, "False for a planar arm")
    torsion = (not planar) if p["torsion"] is None else bool(p["torsion"])
    require(not (planar and torsion) and (torsion or not twist), "torsion", p["torsion"],
            "None, or False for a planar arm and True with twist")
    orders = (order if torsion else -1, -1 if planar else order, order, -1, -1, -1)
    material = Material(p["youngs_modulus"], p["density"], p["damping"], p["poisson"])
    knots = (0.0, *SEGMENTS, 1.0)
    links = tuple(SoftLink(length=p["length"] * (b - a), radius=p["radius"], material=material,
                           basis=StrainBasis(orders=orders, kind="legendre"), joint=Joint("fixed"), n_gauss=n_gauss,
                           recursion="scan")
                  for a, b in zip(knots[:-1], knots[1:]))
    components = (("torsion",) if twist else ()) + (("bend_z",) if planar else ("bend_z", "bend_y"))
    segments = tuple(RestStrainSegments(link=k, knots=(0.0, 1.0), components=components) for k in range(1, 6))
    robot = Robot(links=links, gravity=p["gravity"], gravity_direction=(0.0, 0.0, -1.0), base_rotation=UPRIGHT,
                  rest_strains=segments)
    check_robot(robot)
    return robot


def segment_lengths(length: float = 1.0) -> np.ndarray:
    """(5,) m, the control segments' lengths on an arm of ``length``."""
    return np.diff(np.asarray(SEGMENTS)) * length


def node_sites(robot: Robot, distances: Any = STATE_NODES) -> list[tuple[int, float]]:
    """(link, X) of the points ``distances`` (fractions of the length) along a ``curvature_arm``."""
    knots = (0.0, *SEGMENTS, 1.0)
    out = []
    for s in distances:
        k = min(int(np.searchsorted(knots, s, side="right")) - 1, len(knots) - 2)
        out.append((k, float((s - knots[k]) / (knots[k + 1] - knots[k]))))
    return out


__all__ = ["CURVATURE_ARM", "SEGMENTS", "SEGMENT_SHARE", "CONTROL_NODES", "STATE_NODES", "curvature_arm",
           "segment_lengths", "node_sites"]
