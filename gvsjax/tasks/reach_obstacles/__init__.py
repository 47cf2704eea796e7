"""reach_obstacles: a closed-loop 3D task, the tip of a soft arm brought to a target among obstacles.

``params`` (the parameters), ``layouts`` (the obstacles and the contact law),
``env`` (the environment and its planar variant, their evaluation and rollout),
``figures`` (drawings and the GIF). The arm and its actuation are shared with the
other 3D tasks (``gvsjax.tasks.arm3d``); contact is ``gvsjax.core.contact``'s.
"""

from gvsjax.tasks.reach_obstacles.env import (
    ReachObstacles,
    ReachObstacles2D,
    ReachObstaclesState,
    absolute,
    applied,
    held_policy,
    ramped_reference,
    rollout,
    scene,
)
from gvsjax.tasks.reach_obstacles.layouts import cage, contact_arm, posts
from gvsjax.tasks.reach_obstacles.params import ReachObstaclesParams

__all__ = ["ReachObstacles", "ReachObstacles2D", "ReachObstaclesState", "ReachObstaclesParams", "absolute", "applied",
           "cage", "contact_arm", "held_policy", "posts", "ramped_reference", "rollout", "scene"]
