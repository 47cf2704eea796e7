"""throw3d: the paper's basketball throw from a base that turns about the vertical as it swings.

``params`` (the parameters), ``throw`` (yaw-and-swing physics, the flight from
``gvsjax.tasks.ballistics``), ``targets`` (reachable targets on a court all
around the shooter, by table look-up), ``env`` (the environment), ``figures``.
"""

from gvsjax.tasks.throw3d.env import RELEASE_SPEED_BOUND, Throw3D, Throw3DState
from gvsjax.tasks.throw3d.params import BALL_WEIGHT, COURT, Throw3DParams
from gvsjax.tasks.throw3d.targets import make_params, observe, on_court, sample_target, unobserve
from gvsjax.tasks.throw3d.throw import (
    action_to_physical,
    flight_path,
    physical_to_action,
    release_state,
    swing,
    throw_cost,
    throw_residual,
)

__all__ = [
    "Throw3D", "Throw3DState", "Throw3DParams", "BALL_WEIGHT", "COURT", "RELEASE_SPEED_BOUND", "make_params",
    "observe", "unobserve", "on_court", "sample_target", "action_to_physical", "physical_to_action",
    "release_state", "swing", "flight_path", "throw_cost", "throw_residual",
]
