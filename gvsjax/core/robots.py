"""Ready-made robots. ``paper_arm`` is the 1 m soft arm of Armanini et al.; ``tendon_arm``
a hanging 3D arm driven by routed tendons from a torque-controlled hub; ``soft_arm`` the
upright 3D tendon arm of the closed-loop tasks."""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp
import numpy as np

from gvsjax.core.model import (
    Joint,
    Material,
    PointLoad,
    PointMass,
    RigidLink,
    Robot,
    RoutedTendon,
    SoftLink,
    StrainBasis,
    Tendon,
    TendonPath,
)
from gvsjax.core.validation import check_robot, concrete, finite, nonnegative, positive, require

# At joint angle 0 the rod's local x axis points along world -y (hanging).
HANGING = ((0.0, 1.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, 1.0))

PAPER_ARM = dict(
    length=1.0,  # m
    radius=0.05,  # m, circular section
    youngs_modulus=5e6,  # Pa
    density=1000.0,  # kg/m^3
    damping=1e5,  # Pa s, SoRoSim material damping eta (bending uses 3*eta*I)
    poisson=0.5,  # SoRoSim default: G = E/3
    gravity=9.81,  # m/s^2, along world -y
    n_modes=2,  # polynomial terms of the bending curvature (2 = the paper's linear basis)
    n_gauss=5,  # Gauss points along the arm (SoRoSim default)
    basis="monomial",  # or "legendre" (better conditioned for many modes)
    tip_force=0.0,  # N, constant force on the tip along world -y
    tip_mass=0.0,  # kg, inertial point mass at the tip (also weighed by gravity)
    tendon_offset=None,  # m, straight tendon at this offset (local +y); None = no tendon
    base="prescribed",  # the base joint: "prescribed" (position control) or "torque" (a joint_force input)
)
"""The paper's arm: ``paper_arm``'s default keywords (SI units); ``paper_arm(**overrides)`` replaces any."""


def paper_arm(**overrides: Any) -> Robot:
    """The paper's planar arm: a revolute base and a soft link bending about z with
    ``n_modes`` polynomial curvature terms.

    q = (theta, q_1, ..., q_n_modes); theta = 0 hangs the arm along -y, theta =
    pi/2 points it along +x, theta = pi stands it upright. Curvature kappa(s) =
    sum_k q_k (s/L)^k / L. ``base="prescribed"`` (the paper's) moves the base by a
    given law (``simulate``'s ``base_angle``); ``base="torque"`` leaves it free,
    driven by ``simulate``'s ``joint_force`` (N m, ``robot.actuated == (0,)``).
    Keyword overrides (SI units): see ``PAPER_ARM``.
    """
    unknown = sorted(set(overrides) - set(PAPER_ARM))
    if unknown:
        raise ValueError(f"paper_arm got unknown parameter(s) {unknown}; valid: {sorted(PAPER_ARM)}")
    p = {**PAPER_ARM, **overrides}
    for key in ("length", "radius", "youngs_modulus", "density"):
        positive(key, p[key])
    for key in ("damping", "gravity", "tip_mass"):
        nonnegative(key, p[key])
    finite("tip_force", p["tip_force"])
    for key in ("n_modes", "n_gauss"):
        require(isinstance(p[key], int) and not isinstance(p[key], bool) and p[key] >= 1, key, p[key], "an int >= 1")
    require(p["n_gauss"] >= p["n_modes"], "n_gauss", p["n_gauss"],
            f">= n_modes={p['n_modes']} so that the stiffness is integrated exactly")
    require(p["basis"] in ("monomial", "legendre"), "basis", p["basis"], "'monomial' or 'legendre'")
    require(p["base"] in ("prescribed", "torque"), "base", p["base"], "'prescribed' or 'torque'")
    tendons: tuple[Tendon, ...] = ()
    if p["tendon_offset"] is not None:
        finite("tendon_offset", p["tendon_offset"])
        # checked here so the error names paper_arm's parameter; only concrete numbers can be compared
        if concrete(p["tendon_offset"]) and concrete(p["radius"]):
            require(abs(float(p["tendon_offset"])) <= float(p["radius"]), "tendon_offset", p["tendon_offset"],
                    f"|tendon_offset| <= radius={float(p['radius'])} m (the tendon runs inside the rod)")
        tendons = (Tendon(offset=p["tendon_offset"], link=0, direction=(1.0, 0.0)),)
    link = SoftLink(
        length=p["length"],
        radius=p["radius"],
        material=Material(p["youngs_modulus"], p["density"], p["damping"], p["poisson"]),
        basis=StrainBasis(orders=(-1, -1, p["n_modes"] - 1, -1, -1, -1), kind=p["basis"]),
        joint=Joint("revolute", (0.0, 0.0, 1.0)),
        n_gauss=p["n_gauss"],
    )
    robot = Robot(
        links=(link,),
        gravity=p["gravity"],
        loads=(PointLoad(magnitude=p["tip_force"], link=0, X=1.0, direction=(0.0, -1.0, 0.0)),),
        masses=(PointMass(mass=p["tip_mass"], link=0, X=1.0),),
        tendons=tendons,
        base_rotation=HANGING,
        prescribed=(0,) if p["base"] == "prescribed" else (),
    )
    check_robot(robot)
    return robot


def rod_3d(length=1.0, radius=0.05, youngs_modulus=5e6, density=1000.0, damping=1e5, poisson=0.5,
           order=1, n_gauss=5, basis="legendre", gravity=0.0) -> Robot:
    """A straight rod clamped at the origin along +x with all six strains active.

    order: one polynomial order for every strain, or six (-1 = inactive)."""
    # validated here so that errors name rod_3d's own parameters, not the SoftLink fields
    for key, value in (("length", length), ("radius", radius), ("youngs_modulus", youngs_modulus),
                       ("density", density)):
        positive(key, value)
    nonnegative("damping", damping)
    nonnegative("gravity", gravity)
    orders = tuple(order) if isinstance(order, (tuple, list)) else (order,) * 6
    require(len(orders) == 6 and all(isinstance(o, int) and not isinstance(o, bool) and o >= -1
                                     for o in orders) and max(orders) >= 0,
            "order", order, "an int >= 0, or six ints >= -1 (-1 = inactive) with one >= 0")
    require(isinstance(n_gauss, int) and not isinstance(n_gauss, bool) and n_gauss >= max(orders) + 1,
            "n_gauss", n_gauss, f"an int >= {max(orders) + 1} (highest order + 1)")
    require(basis in ("monomial", "legendre"), "basis", basis, "'monomial' or 'legendre'")
    link = SoftLink(
        length=length, radius=radius,
        material=Material(youngs_modulus, density, damping, poisson),
        basis=StrainBasis(orders=orders, kind=basis),
        joint=Joint("fixed"), n_gauss=n_gauss,
    )
    robot = Robot(links=(link,), gravity=gravity)
    check_robot(robot)
    return robot


TENDON_ARM = dict(
    length=0.5,  # m, the soft link
    radius=0.025,  # m at the base; circular section
    taper=0.6,  # tip-to-base ratio of the radius
    youngs_modulus=1e6,  # Pa
    density=1000.0,  # kg/m^3
    damping=3e4,  # Pa s, material damping eta (SoRoSim's convention)
    poisson=0.5,
    gravity=9.81,  # m/s^2, along world -y (the arm hangs)
    bending_order=1,  # Legendre order of both bending curvatures (torsion is constant)
    n_gauss=3,
    hub_mass=0.5,  # kg, the rigid hub the soft link hangs from
    hub_inertia=(5e-3, 2.5e-3, 2.5e-3),  # kg m^2, about its centre of mass (axis first)
    hub_length=0.05,  # m
    hub_damping=0.01,  # N m s/rad, viscous friction of the hub's bearing
    tendon_offset=0.018,  # m from the midline at the base; it shrinks with the section
    helix_turns=0.5,  # turns of the fourth tendon about the midline
    tip_mass=0.0,  # kg, a payload at the tip (also weighed by gravity)
)
"""The upright 3D tendon arm of the closed-loop tasks: ``tendon_arm``'s default keywords (SI units)."""


def tendon_arm(**overrides: Any) -> Robot:
    """A hanging 3D tendon-driven arm: a rigid hub on a torque-controlled revolute joint about
    the vertical, and a tapered soft link with four routed tendons.

    q = (hub angle, torsion, then the two bending curvatures' Legendre coefficients); q = 0
    hangs straight down along -y. ``robot.actuated`` is the hub (``joint_force``, N m);
    hold it with ``.replace(prescribed=(0,))`` for position control or statics. Tendons (N,
    in this order): three straight cables at 0, 120 and 240 degrees around the section
    (angle from the local y axis towards z) converging with the taper, and a helical one of
    ``helix_turns`` turns. Keyword overrides (SI units): see ``TENDON_ARM``.
    """
    unknown = sorted(set(overrides) - set(TENDON_ARM))
    if unknown:
        raise ValueError(f"tendon_arm got unknown parameter(s) {unknown}; valid: {sorted(TENDON_ARM)}")
    p = {**TENDON_ARM, **overrides}
    for key in ("length", "radius", "taper", "youngs_modulus", "density", "hub_mass", "hub_length",
                "tendon_offset"):
        positive(key, p[key])
    positive("hub_inertia", p["hub_inertia"], (3,))
    for key in ("damping", "gravity", "hub_damping", "tip_mass"):
        nonnegative(key, p[key])
    finite("helix_turns", p["helix_turns"])
    require(isinstance(p["bending_order"], int) and not isinstance(p["bending_order"], bool)
            and p["bending_order"] >= 0, "bending_order", p["bending_order"], "an int >= 0")
    require(isinstance(p["n_gauss"], int) and not isinstance(p["n_gauss"], bool)
            and p["n_gauss"] >= p["bending_order"] + 1, "n_gauss", p["n_gauss"],
            f"an int >= bending_order + 1 = {p['bending_order'] + 1}")
    for key in ("tendon_offset", "taper", "helix_turns"):  # they shape the helix, a static function of X
        require(concrete(p[key]) and np.ndim(p[key]) == 0, key, p[key], "a concrete number (not traced)")
    if concrete(p["radius"]):
        require(float(p["tendon_offset"]) < float(p["radius"]), "tendon_offset", p["tendon_offset"],
                f"< radius={float(p['radius'])} m (the tendons run inside the rod)")
    d0 = float(p["tendon_offset"])
    d1 = d0 * float(p["taper"])

    def straight(angle: float) -> RoutedTendon:
        u = np.array([np.cos(angle), np.sin(angle)])
        return RoutedTendon(paths=(TendonPath(offsets=np.stack([d0 * u, d1 * u]), link=1, knots=(0.0, 1.0),
                                              n_quad=4),))

    turns = float(p["helix_turns"])
    helix = lambda X: (d0 + (d1 - d0) * X) * jnp.stack([jnp.cos(2 * jnp.pi * turns * X),  # noqa: E731
                                                         jnp.sin(2 * jnp.pi * turns * X)])
    hub = RigidLink(mass=p["hub_mass"], inertia=p["hub_inertia"], com=(p["hub_length"] / 2, 0.0, 0.0),
                    length=p["hub_length"], joint=Joint("revolute", (1.0, 0.0, 0.0)), joint_damping=p["hub_damping"])
    soft = SoftLink(length=p["length"], radius=p["radius"], taper=p["taper"],
                    material=Material(p["youngs_modulus"], p["density"], p["damping"], p["poisson"]),
                    basis=StrainBasis(orders=(0, p["bending_order"], p["bending_order"], -1, -1, -1), kind="legendre"),
                    joint=Joint("fixed"), n_gauss=p["n_gauss"])
    robot = Robot(
        links=(hub, soft),
        gravity=p["gravity"],
        # a zero payload is left out: every point mass adds to the compiled program
        masses=() if concrete(p["tip_mass"]) and float(p["tip_mass"]) == 0.0 else (PointMass(mass=p["tip_mass"],
                                                                                           link=1, X=1.0),),
        tendons=tuple(straight(a) for a in (0.0, 2 * np.pi / 3, 4 * np.pi / 3))
        + (RoutedTendon(paths=(TendonPath(path=helix, link=1, n_quad=8),)),),
        base_rotation=HANGING,
    )
    check_robot(robot)
    return robot


SOFT_ARM = dict(
    length=1.0,  # m
    radius=0.05,  # m, circular section
    youngs_modulus=1e7,  # Pa
    density=1000.0,  # kg/m^3
    damping=1e5,  # Pa s, material damping eta (SoRoSim's convention, as the paper's arm)
    poisson=0.5,
    gravity=9.81,  # m/s^2, along world -z (the arm stands along +z)
    bending_order=2,  # Legendre order of both bending curvatures
    torsion_order=0,  # -1: no torsion
    stretch_order=1,  # -1: inextensible (the lower tendons compress only the lower half: order 1)
    shear_order=-1,  # -1: unshearable (Kirchhoff); 0 or more: both shears
    n_gauss=4,
    recursion="scan",  # see SoftLink.recursion: here the scan compiles ~7x and runs ~1.3x faster
    tendon_offset=0.04,  # m from the midline
    tendon_ends=(1.0, 0.5),  # X where each group of four tendons is anchored (from the base)
)
"""The upright 3D soft arm driven by groups of four tendons: ``soft_arm``'s default keywords (SI units)."""

# At rest the rod's local x axis points along world +z, local y along +x and z along +y.
UPRIGHT = ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0))


def soft_arm(**overrides: Any) -> Robot:
    """An upright 3D soft arm clamped at the origin, driven by groups of four straight tendons.

    The rod stands along world +z with gravity along -z. Each entry X_e of ``tendon_ends``
    adds four tendons running from the base to material point X_e at ``tendon_offset``
    from the midline, at 0, 90, 180 and 270 degrees about it (section y, z, -y, -z; at rest
    world +x, +y, -x, -y): pulling one bends the part below X_e towards it. Two groups
    (the whole arm and its lower half) give the tip a 3D workspace, as in two-section
    continuum arms. q holds the strain coefficients of the active components (torsion,
    the two bending curvatures, stretch, shears) at their Legendre orders (-1: inactive).
    Keyword overrides (SI units): see ``SOFT_ARM``.
    """
    unknown = sorted(set(overrides) - set(SOFT_ARM))
    if unknown:
        raise ValueError(f"soft_arm got unknown parameter(s) {unknown}; valid: {sorted(SOFT_ARM)}")
    p = {**SOFT_ARM, **overrides}
    for key in ("length", "radius", "youngs_modulus", "density", "tendon_offset"):
        positive(key, p[key])
    for key in ("damping", "gravity"):
        nonnegative(key, p[key])
    require(p["recursion"] in ("unrolled", "scan", "auto"), "recursion", p["recursion"],
            "'unrolled', 'scan' or 'auto'")
    for key in ("torsion_order", "stretch_order", "shear_order"):
        require(isinstance(p[key], int) and not isinstance(p[key], bool) and p[key] >= -1, key, p[key],
                "an int >= -1 (-1 = inactive)")
    require(isinstance(p["bending_order"], int) and not isinstance(p["bending_order"], bool)
            and p["bending_order"] >= 0, "bending_order", p["bending_order"], "an int >= 0")
    top = max(p["bending_order"], p["torsion_order"], p["stretch_order"], p["shear_order"])
    require(isinstance(p["n_gauss"], int) and not isinstance(p["n_gauss"], bool) and p["n_gauss"] >= top + 1,
            "n_gauss", p["n_gauss"], f"an int >= {top + 1} (highest order + 1)")
    require(concrete(p["tendon_offset"]) and np.ndim(p["tendon_offset"]) == 0, "tendon_offset",
            p["tendon_offset"], "a concrete number (not traced)")
    if concrete(p["radius"]):
        require(float(p["tendon_offset"]) < float(p["radius"]), "tendon_offset", p["tendon_offset"],
                f"< radius={float(p['radius'])} m (the tendons run inside the rod)")
    require(isinstance(p["tendon_ends"], (tuple, list)), "tendon_ends", p["tendon_ends"],
            "a tuple of material points X in (0, 1]")
    ends = tuple(p["tendon_ends"])
    require(all(isinstance(e, (int, float)) and 0.0 < e <= 1.0 for e in ends), "tendon_ends",
            p["tendon_ends"], "material points X in (0, 1]")
    d = float(p["tendon_offset"])
    tendons = []
    for end in ends:
        for angle in (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi):
            u = d * np.array([np.cos(angle), np.sin(angle)])
            tendons.append(RoutedTendon(paths=(TendonPath(offsets=np.stack([u, u]), link=0,
                                                          knots=(0.0, float(end)), n_quad=4),)))
    shear = p["shear_order"]
    link = SoftLink(length=p["length"], radius=p["radius"],
                    material=Material(p["youngs_modulus"], p["density"], p["damping"], p["poisson"]),
                    basis=StrainBasis(orders=(p["torsion_order"], p["bending_order"], p["bending_order"],
                                              p["stretch_order"], shear, shear), kind="legendre"),
                    joint=Joint("fixed"), n_gauss=p["n_gauss"], recursion=p["recursion"])
    robot = Robot(links=(link,), gravity=p["gravity"], gravity_direction=(0.0, 0.0, -1.0),
                  tendons=tuple(tendons), base_rotation=UPRIGHT)
    check_robot(robot)
    return robot


# At joint angles 0 the rod's local x axis points along world -z (hanging), y along -x, z along +y.
HANGING_Z = ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0), (-1.0, 0.0, 0.0))

PAPER_ARM_3D = dict(
    {k: v for k, v in PAPER_ARM.items() if k not in ("tendon_offset", "base", "basis")},
    gravity=9.81,  # m/s^2, along world -z
    basis="legendre",
    torsion_order=-1,  # -1: no torsion
    stretch_order=-1,  # -1: inextensible
    shear_order=-1,  # -1: unshearable
    recursion="unrolled",  # see SoftLink.recursion
)
"""The paper's arm in 3D: ``paper_arm_3d``'s default keywords (SI units)."""


def paper_arm_3d(**overrides: Any) -> Robot:
    """The paper's arm in 3D on a base that turns about the vertical and swings.

    World z is up (gravity along -z). The base is a universal joint with both
    DoFs prescribed: first the yaw psi about the vertical, then the swing theta
    about the turned frame's horizontal axis. q = (psi, theta, strains); at
    psi = theta = 0 the arm hangs along -z, theta = pi/2 points it along -x,
    theta = pi stands it upright and beyond pi it leans towards +x (the paper's
    throw, turned by psi about z). Both bending curvatures (in the swing plane
    and out of it) have ``n_modes`` polynomial terms in ``basis``; torsion,
    stretch and shear are off unless their orders are >= 0. With psi held at 0
    the motion stays in the x-z plane and is the paper's planar arm. Keyword
    overrides (SI units): see ``PAPER_ARM_3D``.
    """
    unknown = sorted(set(overrides) - set(PAPER_ARM_3D))
    if unknown:
        raise ValueError(f"paper_arm_3d got unknown parameter(s) {unknown}; valid: {sorted(PAPER_ARM_3D)}")
    p = {**PAPER_ARM_3D, **overrides}
    for key in ("length", "radius", "youngs_modulus", "density"):
        positive(key, p[key])
    for key in ("damping", "gravity", "tip_mass"):
        nonnegative(key, p[key])
    finite("tip_force", p["tip_force"])
    require(isinstance(p["n_modes"], int) and not isinstance(p["n_modes"], bool) and p["n_modes"] >= 1,
            "n_modes", p["n_modes"], "an int >= 1")
    for key in ("torsion_order", "stretch_order", "shear_order"):
        require(isinstance(p[key], int) and not isinstance(p[key], bool) and p[key] >= -1, key, p[key],
                "an int >= -1 (-1 = inactive)")
    top = max(p["n_modes"] - 1, p["torsion_order"], p["stretch_order"], p["shear_order"])
    require(isinstance(p["n_gauss"], int) and not isinstance(p["n_gauss"], bool) and p["n_gauss"] >= top + 1,
            "n_gauss", p["n_gauss"], f"an int >= {top + 1} (highest order + 1)")
    require(p["basis"] in ("monomial", "legendre"), "basis", p["basis"], "'monomial' or 'legendre'")
    require(p["recursion"] in ("unrolled", "scan", "auto"), "recursion", p["recursion"], "'unrolled', 'scan' or 'auto'")
    bend, shear = p["n_modes"] - 1, p["shear_order"]
    link = SoftLink(
        length=p["length"], radius=p["radius"],
        material=Material(p["youngs_modulus"], p["density"], p["damping"], p["poisson"]),
        basis=StrainBasis(orders=(p["torsion_order"], bend, bend, p["stretch_order"], shear, shear),
                          kind=p["basis"]),
        # yaw about the hanging rod's axis (world +z), then the swing about its local z (world +y at psi = 0)
        joint=Joint("universal", (-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
        n_gauss=p["n_gauss"], recursion=p["recursion"],
    )
    robot = Robot(
        links=(link,), gravity=p["gravity"], gravity_direction=(0.0, 0.0, -1.0),
        loads=(PointLoad(magnitude=p["tip_force"], link=0, X=1.0, direction=(0.0, 0.0, -1.0)),),
        masses=() if concrete(p["tip_mass"]) and float(p["tip_mass"]) == 0.0 else (PointMass(mass=p["tip_mass"],
                                                                                           link=0, X=1.0),),
        base_rotation=HANGING_Z, prescribed=(0, 1),
    )
    check_robot(robot)
    return robot


__all__ = ["paper_arm", "paper_arm_3d", "PAPER_ARM_3D", "HANGING_Z",
           "rod_3d", "tendon_arm", "soft_arm", "PAPER_ARM", "TENDON_ARM", "SOFT_ARM", "HANGING",
           "UPRIGHT"]
