"""gvsjax: Geometric Variable-Strain soft-rod simulation and PPO control in JAX.

    import gvsjax as gv
    arm = gv.paper_arm(tip_force=5.886)
    traj = gv.simulate(arm, 1.0, 2e-3, base_angle=lambda t: 3.665 * (t / 2.0) ** 2)
"""

import os

# XLA's newer CPU fusion emitter recomputes shared subexpressions of the long
# scalar chains the GVS recursion produces (measured: 40x slower per step and
# minutes of compile). The classic emitter handles them well. The flag must be
# set before JAX creates its CPU backend, so import gvsjax before using JAX.
_FLAG = "--xla_cpu_use_fusion_emitters=false"
_USER_SET_FLAG = _FLAG.split("=")[0] in os.environ.get("XLA_FLAGS", "")
if not _USER_SET_FLAG:
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " " + _FLAG).strip()

import jax  # noqa: E402


def _warn_if_backend_started() -> None:
    try:  # private API: a missing function only means we cannot tell
        from jax._src import xla_bridge

        started = xla_bridge.backends_are_initialized() and not _USER_SET_FLAG
    except Exception:  # pragma: no cover
        return
    if started:
        import warnings

        warnings.warn(
            "gvsjax was imported after JAX started its CPU backend, so the XLA flag "
            f"{_FLAG} could not take effect: simulations will compile and run far slower. "
            "Import gvsjax first, or set XLA_FLAGS yourself.",
            stacklevel=3,
        )


_warn_if_backend_started()

# Physics runs in float64 by default: a throw's release state is sensitive at the
# 1e-6 level. ``simulate(dtype=jnp.float32)`` opts in to float32 for batched
# throughput (docs/physics.md, "Precision").
jax.config.update("jax_enable_x64", True)

# two modules reached as namespaces: gv.contact.sites(robot), gv.dynamics.full_matrix(...)
from gvsjax.core import contact as contact  # noqa: E402
from gvsjax.core import dynamics as dynamics  # noqa: E402
from gvsjax.core.contact import Box, Capsule, Contact, ContactSite, Penalty, Plane, Sphere  # noqa: E402
from gvsjax.core.curvature_arm import CURVATURE_ARM, curvature_arm  # noqa: E402
from gvsjax.core.dynamics import energy, mass_and_forces, stiffness_and_damping  # noqa: E402
from gvsjax.core.identify import Fit, fit_parameters  # noqa: E402
from gvsjax.core.kinematics import (  # noqa: E402
    backbone,
    end_row,
    frames,
    jacobian_rates,
    jacobians,
    sample_sites,
    tip_frame,
    tip_state,
)
from gvsjax.core.model import (  # noqa: E402
    Joint,
    Material,
    PointLoad,
    PointMass,
    PointWrench,
    RestStrainSegments,
    RigidLink,
    Robot,
    RoutedTendon,
    SoftLink,
    StrainBasis,
    Tendon,
    TendonPath,
    axis_rotation,
)
from gvsjax.core.muscles import control_points, moment_map  # noqa: E402
from gvsjax.core.robots import (  # noqa: E402
    PAPER_ARM,
    PAPER_ARM_3D,
    SOFT_ARM,
    TENDON_ARM,
    paper_arm,
    paper_arm_3d,
    rod_3d,
    soft_arm,
    tendon_arm,
)
from gvsjax.core.simulation import simulate  # noqa: E402
from gvsjax.core.stability import stable_step_estimate  # noqa: E402
from gvsjax.core.statics import equilibrium, inverse_statics  # noqa: E402
from gvsjax.core.trajectory import Trajectory  # noqa: E402

__all__ = [
    "Joint", "Material", "PointLoad", "PointMass", "PointWrench", "RestStrainSegments", "RigidLink", "Robot",
    "SoftLink", "StrainBasis",
    "Tendon", "RoutedTendon", "TendonPath", "PAPER_ARM", "paper_arm", "PAPER_ARM_3D", "paper_arm_3d", "rod_3d",
    "TENDON_ARM", "tendon_arm",
    "SOFT_ARM", "soft_arm", "CURVATURE_ARM", "curvature_arm", "simulate", "Trajectory", "stable_step_estimate",
    "axis_rotation", "backbone", "frames", "sample_sites", "end_row",
    "tip_frame", "tip_state", "jacobians", "jacobian_rates", "energy", "mass_and_forces",
    "stiffness_and_damping", "equilibrium", "inverse_statics", "fit_parameters", "Fit", "moment_map", "control_points",
    "Contact", "ContactSite", "Penalty", "Plane", "Sphere", "Capsule", "Box",
]
