"""Basketball (paper section IV-A): throw a ball at a target with a soft arm.

``params`` (the parameters), ``throw`` (swing and flight physics), ``targets``
(reachable targets by table look-up), ``env`` (the environment), ``figures``
(Fig. 2, Fig. 4, the GIF), ``baseline`` (Gauss-Newton through the simulator).
"""

from gvsjax.tasks.basketball.env import RELEASE_SPEED_BOUND, TRAIN_TARGETS, Basketball, BasketballState, miss_metrics
from gvsjax.tasks.basketball.params import BALL_WEIGHT, HOOP, WINDOW, BasketballParams
from gvsjax.tasks.basketball.targets import denormalise, make_params, normalise, sample_target
from gvsjax.tasks.basketball.throw import (
    action_to_physical,
    closest_approach,
    flight_path,
    flight_point,
    floor_time,
    physical_to_action,
    release,
    release_state,
    swing,
    throw_cost,
)

__all__ = [
    "Basketball", "BasketballState", "BasketballParams", "BALL_WEIGHT", "HOOP", "WINDOW",
    "RELEASE_SPEED_BOUND", "TRAIN_TARGETS", "miss_metrics", "make_params", "normalise", "denormalise",
    "sample_target", "action_to_physical", "physical_to_action", "swing", "release", "release_state",
    "flight_point", "flight_path", "floor_time", "closest_approach", "throw_cost",
]
