"""reach_pose: a closed-loop 3D task, the tip of a soft arm brought to a target position and direction.

``params`` (the parameters), ``poses`` (the table of reachable targets), ``env``
(the environment, its evaluation and rollout), ``figures`` (drawings and the GIF).
The arm and its actuation are shared with the other 3D tasks (``gvsjax.tasks.arm3d``).
"""

from gvsjax.tasks.reach_pose.env import (
    ReachPose,
    ReachPoseMuscle,
    ReachPoseState,
    angle,
    final_summary,
    observe,
    rollout,
    start,
)
from gvsjax.tasks.reach_pose.params import ReachPoseParams
from gvsjax.tasks.reach_pose.poses import make_params, reachable_poses

__all__ = ["ReachPose", "ReachPoseMuscle", "ReachPoseState", "ReachPoseParams", "angle", "final_summary", "observe",
           "rollout", "start", "make_params", "reachable_poses"]
