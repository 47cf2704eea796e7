"""Pick and place (paper section IV-B): two motions of a tendon arm to two targets.

``params`` (the parameters), ``motion`` (one step's simulated motion),
``targets`` (reachable pairs by table look-up), ``env`` (the environment),
``figures`` (Fig. 6, the GIF).
"""

from gvsjax.tasks.pickplace.env import PickPlace, PickPlaceState, error_summary, observe, rollout, target_features
from gvsjax.tasks.pickplace.motion import (
    action_to_physical,
    controls,
    cycloid,
    episode,
    episode_distances,
    physical_to_action,
    reward_of,
    run_step,
)
from gvsjax.tasks.pickplace.params import DRAWING_INTEGRATION, PAPER_PAIR, PickPlaceParams
from gvsjax.tasks.pickplace.targets import eval_targets, make_params, row_range, sample_targets

__all__ = [
    "PickPlace", "PickPlaceState", "PickPlaceParams", "PAPER_PAIR", "DRAWING_INTEGRATION", "error_summary",
    "observe", "rollout", "target_features", "action_to_physical", "physical_to_action", "controls", "cycloid",
    "episode", "episode_distances", "reward_of", "run_step", "eval_targets", "make_params", "row_range",
    "sample_targets",
]
