"""The robot description: immutable pytrees of joints, links, loads and tendons.

Physical numbers (lengths, moduli, masses, forces) are pytree *leaves*, so they
can be traced, batched with ``vmap`` and differentiated. Topology and
discretisation (joint types and axes, which strains are active, basis family,
quadrature size) are *static* fields: they fix the shapes and the structural
sparsity of the computation, and changing them recompiles.

Units are SI throughout. Frames: a link's local x axis is its centreline
tangent; y and z are the section axes. Twists are ``(angular, linear)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from flax import struct

STRAIN_NAMES = ("torsion", "bend_y", "bend_z", "stretch", "shear_y", "shear_z")


_X, _Y, _Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
_IDENTITY = (_X, _Y, _Z)
JOINT_KINDS = ("revolute", "prismatic", "fixed", "universal", "spherical", "planar", "free")


def axis_rotation(axis, angle: float) -> tuple:
    """The 3x3 rotation by ``angle`` (rad) about the unit vector ``axis`` (Rodrigues), as
    nested tuples, e.g. for ``Joint.rotation``."""
    a = np.asarray(axis, dtype=float)
    if a.shape != (3,) or not abs(np.linalg.norm(a) - 1.0) < 1e-9:
        raise ValueError(f"axis={axis!r} must be a unit 3-vector")
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    R = np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K
    return tuple(tuple(float(v) for v in row) for row in R)


@dataclass(frozen=True)
class Joint:
    """A joint at the base of a link, as a product of single-axis motions.

    kind (DoFs, in the order of q):
    "revolute" (1: rotation about ``axis``), "prismatic" (1: translation along
    ``axis``), "fixed" (0), "universal" (2: rotation about ``axis``, then about
    ``axis2`` of the turned frame), "spherical" (3: rotations about x, y, z in
    turn, body-fixed XYZ angles), "planar" (3: translations along x and y, then
    a rotation about z), "free" (6: translations along x, y, z, then rotations
    about x, y, z; a floating base). Axes are unit 3-vectors in the parent's
    frame at the joint. Each single-axis motion is an exact exponential, so the
    recursion treats a multi-DoF joint as a chain of one-DoF joints with no
    length between them; the angle sets are singular where Euler angles are
    (e.g. the middle spherical angle at +-pi/2).

    ``offset`` (m) and ``rotation`` (3x3, its columns the joint frame's axes)
    place the joint's frame in the parent's end frame (the base frame for a link
    on the base): SoRoSim's fixed transformation before a joint, which is how a
    branch leaves its parent at an angle or from a point off the centreline.
    """

    kind: str = "revolute"
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    axis2: tuple[float, float, float] = (0.0, 1.0, 0.0)
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple = _IDENTITY

    def __post_init__(self):
        if self.kind not in JOINT_KINDS:
            raise ValueError(f"Joint.kind={self.kind!r} is not allowed; choose one of {', '.join(JOINT_KINDS)}")
        for name in ("axis", "axis2"):
            v = getattr(self, name)
            if len(v) != 3 or not abs(math.sqrt(sum(a * a for a in v)) - 1.0) < 1e-9:
                raise ValueError(f"Joint.{name}={v!r} must be a unit 3-vector")
        off = np.asarray(self.offset, dtype=float)
        if off.shape != (3,) or not np.all(np.isfinite(off)):
            raise ValueError(f"Joint.offset={self.offset!r} must be 3 finite numbers (m)")
        rot = np.asarray(self.rotation, dtype=float)
        if rot.shape != (3, 3) or not np.allclose(rot.T @ rot, np.eye(3), atol=1e-9) or np.linalg.det(rot) < 0:
            raise ValueError(f"Joint.rotation={self.rotation!r} must be a 3x3 rotation matrix (orthonormal, det +1)")
        # plain tuples keep the joint hashable: it is a static field of the robot
        object.__setattr__(self, "offset", tuple(float(a) for a in off))
        object.__setattr__(self, "rotation", tuple(tuple(float(a) for a in row) for row in rot))

    @property
    def mounted(self) -> bool:
        """Whether the joint frame differs from the parent's end frame."""
        return any(self.offset) or self.rotation != _IDENTITY

    @property
    def n_dofs(self) -> int:
        return len(self.twists())

    def twists(self) -> tuple[tuple[float, ...], ...]:
        """The joint's twist per unit coordinate, one 6-vector per DoF, applied in order."""
        rot = lambda a: tuple(a) + (0.0, 0.0, 0.0)  # noqa: E731
        lin = lambda a: (0.0, 0.0, 0.0) + tuple(a)  # noqa: E731
        return {
            "revolute": (rot(self.axis),),
            "prismatic": (lin(self.axis),),
            "fixed": (),
            "universal": (rot(self.axis), rot(self.axis2)),
            "spherical": (rot(_X), rot(_Y), rot(_Z)),
            "planar": (lin(_X), lin(_Y), rot(_Z)),
            "free": (lin(_X), lin(_Y), lin(_Z), rot(_X), rot(_Y), rot(_Z)),
        }[self.kind]

    def twist_basis(self) -> tuple[float, ...]:
        """Phi_j of a one-DoF joint (zeros for a fixed one)."""
        tw = self.twists()
        if len(tw) > 1:
            raise ValueError(f"Joint.kind={self.kind!r} has {len(tw)} DoFs: use twists()")
        return tw[0] if tw else (0.0,) * 6


@dataclass(frozen=True)
class StrainBasis:
    """Which strain components are active and the polynomial order of each.

    ``orders[c]`` is the polynomial order of strain component ``c`` (in the
    order of ``STRAIN_NAMES``), or -1 when that component is inactive (held at
    its reference value). Component ``c`` with order ``o`` contributes ``o + 1``
    DoFs. ``kind`` is "monomial" (X^j) or "legendre" (P_j(2X - 1), orthogonal on
    [0, 1]; better conditioned for high orders). Columns are component-major.
    """

    orders: tuple[int, int, int, int, int, int] = (-1, -1, 1, -1, -1, -1)
    kind: str = "monomial"

    def __post_init__(self):
        if self.kind not in ("monomial", "legendre"):
            raise ValueError(f"StrainBasis.kind={self.kind!r}; choose monomial or legendre")
        if len(self.orders) != 6 or any((not isinstance(o, int)) or o < -1 for o in self.orders):
            raise ValueError(
                f"StrainBasis.orders={self.orders!r} must be 6 ints >= -1 (-1 = inactive)"
            )

    @property
    def n_dofs(self) -> int:
        return sum(o + 1 for o in self.orders)

    def raw(self, X: float) -> np.ndarray:
        """Phi_raw(X), shape (6, n_dofs), before SoRoSim's 1/L scaling of angular rows."""
        out = np.zeros((6, self.n_dofs))
        col = 0
        for c, order in enumerate(self.orders):
            for j in range(order + 1):
                out[c, col] = self._function(j, X)
                col += 1
        return out

    def _function(self, j: int, X: float) -> float:
        if self.kind == "monomial":
            return X**j
        x = 2.0 * X - 1.0
        p_prev, p = 1.0, x
        if j == 0:
            return 1.0
        for k in range(1, j):
            p_prev, p = p, ((2 * k + 1) * x * p - k * p_prev) / (k + 1)
        return p


@struct.dataclass
class Material:
    """Linear elastic, Kelvin-Voigt viscous material.

    damping is SoRoSim's "material damping" eta (Pa s); see
    ``SoftLink.damping_factors`` for how it maps to each strain.
    """

    youngs_modulus: Any = 5e6
    density: Any = 1000.0
    damping: Any = 1e5
    poisson: Any = 0.5


SECTION_SHAPES = ("circle", "ellipse", "rectangle")
TORSION_CONSTANTS = ("saint_venant", "polar")


@struct.dataclass
class SoftLink:
    """A Cosserat rod: its section, material, strain basis and rest shape.

    Section (``shape``): "circle" of ``radius``; "ellipse" with semi-axes
    ``width``/2 along the local y and ``height``/2 along z; "rectangle"
    ``width`` (y) by ``height`` (z). ``taper`` scales every dimension linearly
    from 1 at the base (X = 0) to ``taper`` at the tip (X = 1). The rest shape
    is the reference strain xi*(X) (``rest_strain``): None is straight and
    unstretched, (0, 0, 0, 1, 0, 0); a (6,) array is a constant one (a
    pre-curved arc, a pre-twisted rod); a (6, k) array holds the coefficients
    of a polynomial in X, column j multiplying X^j. Its angular rows are in
    1/m, its linear rows dimensionless. q measures the strain from xi*.

    ``recursion`` says how the kinematic pass visits the link's sample points:
    "unrolled" (one traced Magnus step per interval: the fastest steps for small
    links), "scan" (one Magnus step traced, the steps composed inside
    ``lax.scan``: a compiled program whose size does not grow with ``n_gauss``
    or the DoFs, for spatial links) or "auto" (scan a link of 2 or more Gauss
    points once the robot has 12 DoFs, or in a robot of at most 6 DoFs once its
    unrolled pass would be large: a 6-DoF spatial rod from 4 Gauss points;
    ``scan.uses_scan``). The results agree to rounding. Scanned links that follow each
    other on joints with no DoFs (a chain, in a robot of more than 6 DoFs) share one
    loop (``scan.chain_groups``).

    ``torsion_constant`` picks the Jt of the torsional stiffness G Jt (see the field).
    The section damping matrix is ``damping * diag(J, 3I, 3I, 3A, A, A)``
    by default (SoRoSim's convention); ``damping_factors`` scales each entry
    of ``diag(J, I, I, A, A, A)``, for other damping conventions.
    """

    length: Any = 1.0
    radius: Any = 0.05
    material: Material = Material()
    width: Any = 0.1  # m, "ellipse" and "rectangle": extent along the section's y axis
    height: Any = 0.1  # m, extent along z
    taper: Any = 1.0  # tip-to-base ratio of every section dimension
    rest_strain: Any = None
    shape: str = struct.field(pytree_node=False, default="circle")
    basis: StrainBasis = struct.field(pytree_node=False, default=StrainBasis())
    joint: Joint = struct.field(pytree_node=False, default=Joint())
    n_gauss: int = struct.field(pytree_node=False, default=5)
    recursion: str = struct.field(pytree_node=False, default="auto")
    damping_factors: tuple = struct.field(pytree_node=False, default=(1.0, 3.0, 3.0, 3.0, 1.0, 1.0))
    # torsional stiffness G Jt: "saint_venant" (the exact torsion constant of the section) or "polar"
    # (Iy + Iz, SoRoSim's choice; the same for a circle, stiffer for an ellipse or a rectangle)
    torsion_constant: str = struct.field(pytree_node=False, default="saint_venant")
    joint_stiffness: Any = 0.0  # N m/rad or N/m, per joint DoF (a scalar applies to each)
    joint_damping: Any = 0.0  # N m s/rad or N s/m, per joint DoF

    @property
    def n_dofs(self) -> int:
        return self.joint.n_dofs + self.basis.n_dofs


@struct.dataclass
class RigidLink:
    """A rigid body: joint at its base, centre of mass at ``com`` (joint
    frame), principal inertia ``inertia`` (kg m^2, about the CoM, joint-frame
    axes) and its far end, where the next link starts, at (length, 0, 0)."""

    mass: Any = 1.0
    inertia: Any = (1e-3, 1e-3, 1e-3)
    com: Any = (0.0, 0.0, 0.0)
    length: Any = 0.0
    joint: Joint = struct.field(pytree_node=False, default=Joint())
    joint_stiffness: Any = 0.0  # N m/rad or N/m, per joint DoF (a scalar applies to each)
    joint_damping: Any = 0.0  # N m s/rad or N s/m, per joint DoF

    @property
    def n_dofs(self) -> int:
        return self.joint.n_dofs


@struct.dataclass
class PointLoad:
    """A force (N) or, with ``moment=True``, a couple (N m) of ``magnitude``
    along the unit vector ``direction``, at material coordinate ``X`` in [0, 1]
    of link ``link`` (for a rigid link, X = 1 is its far end, anything else its
    CoM). ``follower=False``: the direction is fixed in the world; True: it is
    given in the section's frame and turns with it."""

    magnitude: Any = 0.0
    link: int = struct.field(pytree_node=False, default=-1)
    X: float = struct.field(pytree_node=False, default=1.0)
    direction: tuple = struct.field(pytree_node=False, default=(0.0, -1.0, 0.0))
    follower: bool = struct.field(pytree_node=False, default=False)
    moment: bool = struct.field(pytree_node=False, default=False)


@struct.dataclass
class PointMass:
    """An inertial point mass (kg), weighed by gravity, at ``X`` of ``link``."""

    mass: Any = 0.0
    link: int = struct.field(pytree_node=False, default=-1)
    X: float = struct.field(pytree_node=False, default=1.0)


@struct.dataclass
class Tendon:
    """A straight tendon along soft link ``link``, parallel to the midline at
    ``offset`` metres in the section direction ``direction`` (a unit vector in
    the local y-z plane), fixed at the link's tip. Tension is >= 0 and pulls
    the tip towards the base."""

    offset: Any = 0.025
    link: int = struct.field(pytree_node=False, default=-1)
    direction: tuple = struct.field(pytree_node=False, default=(1.0, 0.0))


@struct.dataclass
class TendonPath:
    """Where a routed tendon runs through soft link ``link``: from material point ``X0`` to
    ``X1`` (X in [0, 1]) at the offset d(X) = (y, z), metres, in the section's frame.

    The path is either ``offsets``, an (K, 2) array of (y, z) at the static material points
    ``knots`` (increasing, first X0, last X1), joined by straight pieces (a leaf: it can be
    batched and differentiated; a straight oblique cable is two knots, a converging one too);
    or ``path``, a function ``X -> (y, z)`` written with ``jax.numpy`` (static: evaluated with
    its X-derivative by forward-mode autodiff at the quadrature points; e.g. a helix).
    ``n_quad`` Gauss points integrate each smooth piece.
    """

    offsets: Any = None
    link: int = struct.field(pytree_node=False, default=-1)
    knots: tuple = struct.field(pytree_node=False, default=())
    path: Any = struct.field(pytree_node=False, default=None)
    X0: float = struct.field(pytree_node=False, default=0.0)
    X1: float = struct.field(pytree_node=False, default=1.0)
    n_quad: int = struct.field(pytree_node=False, default=8)

    @property
    def pieces(self) -> tuple[tuple[float, float], ...]:
        """The smooth pieces (X_start, X_end) the quadrature integrates separately."""
        ends = self.knots if self.path is None else (self.X0, self.X1)
        return tuple((float(a), float(b)) for a, b in zip(ends[:-1], ends[1:]))


@struct.dataclass
class RoutedTendon:
    """A cable routed through the sections of a line of soft links (each the parent of the
    next), one ``TendonPath`` per link from base to tip. Its tension (an input, >= 0) pulls it at the start of the first
    path; it is anchored at the end of the last. The load on the rod follows from the cable's
    length l(q) (the arc length of the routed path in the deformed rod): the generalized force
    is -T dl/dq, which holds the distributed load of the cable's curvature along the path and
    the point forces where it ends and where its direction jumps (knots). The part of the
    cable before its first path (towards the actuator) is taken not to change length.
    Consecutive paths meet where one link ends (X1 = 1) and its child starts (X0 = 0); the
    joint between them must be fixed (an offset or a rotation is allowed), because a moving
    joint would change the length of the cable's crossing, which this model does not include."""

    paths: tuple = ()


@struct.dataclass
class PointWrench:
    """Where a 6-D wrench input acts: material point ``X`` of ``link``. Its value,
    (moment N m, force N), is an input of ``simulate`` (``wrench=``: a constant, a law
    of t or of (t, q, qd), or a controller's output), in the world frame or, with
    ``local``, in the section's frame (turning with it)."""

    link: int = struct.field(pytree_node=False, default=-1)
    X: float = struct.field(pytree_node=False, default=1.0)
    local: bool = struct.field(pytree_node=False, default=False)


@struct.dataclass
class RestStrainSegments:
    """Where a time-varying rest strain acts: piecewise-constant changes of link ``link``'s
    rest strain xi*(X) on the segments between ``knots`` (material points 0 <= X_0 < ... <= 1),
    for the strain ``components`` named (``STRAIN_NAMES``). Its value, (n_segments,
    n_components) in 1/m (angular) or dimensionless (linear), is ``simulate``'s ``rest_strain``
    input (a constant, a law of t or of (t, q, qd), or a controller's output); see
    ``gvsjax.core.active_strain``."""

    link: int = struct.field(pytree_node=False, default=0)
    knots: tuple = struct.field(pytree_node=False, default=(0.0, 1.0))
    components: tuple = struct.field(pytree_node=False, default=("bend_y", "bend_z"))

    @property
    def shape(self) -> tuple[int, int]:
        return (len(self.knots) - 1, len(self.components))


@struct.dataclass
class Robot:
    """A chain or a tree of links from a fixed base, with loads and tendons.

    ``parents``: empty for a serial chain (each link starts at the previous
    link's end), or one entry per link, the index of the link it starts from
    (-1: the base), always an earlier link, so ``links`` lists a tree parents
    first. The joint's ``offset``/``rotation`` places it in that end's frame.

    ``prescribed`` lists the indices (into q) of position-controlled DoFs;
    their motion is given to ``simulate`` and the rest is integrated.
    ``base_rotation`` (3x3, static) orients the first joint frame in the world.
    ``wrenches``: points where ``simulate``'s ``wrench`` input acts.
    ``distributed``: None, or a load per unit length on every soft link,
    ``f(X, R, p, eta, t) -> (6,)`` (moment, force) per metre in the section's
    frame, from the material coordinate X in [0, 1], the section's world
    rotation R (3, 3) and position p (3,), its body twist eta (6,) and the time
    (``gvsjax.core.loads`` has drag and uniform-force helpers). Static: a new
    function recompiles.
    ``contact``: None, or a ``gvsjax.core.contact.Contact`` (obstacles and the penalty law).
    ``rest_strains``: ``RestStrainSegments`` where ``simulate``'s ``rest_strain`` input acts.
    ``sample_points``: extra (link, X) material points the recursion samples exactly (observed
    points; ``kinematics.point_states`` adds its own for one pass).
    """

    links: tuple
    gravity: Any = 9.81
    loads: tuple = ()
    masses: tuple = ()
    tendons: tuple = ()
    wrenches: tuple = ()
    contact: Any = None
    rest_strains: tuple = ()
    distributed: Any = struct.field(pytree_node=False, default=None)
    gravity_direction: tuple = struct.field(pytree_node=False, default=(0.0, -1.0, 0.0))
    base_rotation: tuple = struct.field(
        pytree_node=False, default=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    )
    prescribed: tuple = struct.field(pytree_node=False, default=())
    parents: tuple = struct.field(pytree_node=False, default=())
    sample_points: tuple = struct.field(pytree_node=False, default=())

    def parent(self, i: int) -> int:
        """The link that link ``i`` starts from, -1 for the base."""
        return self.parents[i] if self.parents else i - 1

    @property
    def n_dofs(self) -> int:
        return sum(link.n_dofs for link in self.links)

    def dof_slices(self) -> list[tuple[int, int, int]]:
        """Per link: (first joint DoF, first soft DoF, end) indices into q."""
        out, i = [], 0
        for link in self.links:
            nj = link.joint.n_dofs
            ns = link.basis.n_dofs if isinstance(link, SoftLink) else 0
            out.append((i, i + nj, i + nj + ns))
            i += nj + ns
        return out

    @property
    def free(self) -> tuple[int, ...]:
        return tuple(i for i in range(self.n_dofs) if i not in self.prescribed)

    @property
    def joint_dofs(self) -> tuple[int, ...]:
        """Indices into q of every joint coordinate, base to tip."""
        return tuple(i for j0, s0, _ in self.dof_slices() for i in range(j0, s0))

    @property
    def actuated(self) -> tuple[int, ...]:
        """The joint coordinates that are not prescribed, in q order: where ``simulate``'s
        ``joint_force`` acts (N m on a rotation, N on a translation)."""
        return tuple(i for i in self.joint_dofs if i not in self.prescribed)
