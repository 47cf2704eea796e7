"""track3d: a closed-loop 3D task, the tip of a soft arm following a moving target.

``params`` (the parameters), ``target`` (the target's motion and where it may go), ``env`` (the
environment, its evaluation and rollout), ``figures`` (drawings and the GIF).
The arm and its actuation are shared with the other 3D tasks (``gvsjax.tasks.arm3d``).
"""

from gvsjax.tasks.track3d.env import Track3D, Track3DMuscle, Track3DState, distance_summary, observe, rest_tip, rollout
from gvsjax.tasks.track3d.params import TARGET_SETS, Track3DParams
from gvsjax.tasks.track3d.target import holdable_tips, inside, make_params, move, random_direction, start

__all__ = ["Track3D", "Track3DMuscle", "Track3DState", "Track3DParams", "TARGET_SETS",
           "distance_summary", "observe", "rest_tip", "rollout",
           "holdable_tips", "inside", "make_params", "move", "random_direction", "start"]
