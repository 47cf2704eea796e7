"""Tasks: functional environments (gymnax style) over the GVS simulator.

A task is one module or folder under ``gvsjax/tasks`` and one line below.
"""

from gvsjax.tasks.base import Box, Controller, Environment, EvalResult, auto_reset_step, make, register, registered

__all__ = ["DEFAULT_TASK", "Box", "Controller", "Environment", "EvalResult", "auto_reset_step", "make", "register",
           "registered"]

DEFAULT_TASK = "basketball"
"""The task the command line and Gymnasium run when none is named."""

register("basketball", "gvsjax.tasks.basketball:Basketball")
register("pickplace", "gvsjax.tasks.pickplace:PickPlace")
register("track3d", "gvsjax.tasks.track3d:Track3D")
register("track3d_muscle", "gvsjax.tasks.track3d:Track3DMuscle")
register("reach_pose", "gvsjax.tasks.reach_pose:ReachPose")
register("reach_pose_muscle", "gvsjax.tasks.reach_pose:ReachPoseMuscle")
register("balance", "gvsjax.tasks.balance:Balance")
register("reach_obstacles", "gvsjax.tasks.reach_obstacles:ReachObstacles")
register("reach_obstacles_2d", "gvsjax.tasks.reach_obstacles:ReachObstacles2D")
register("throw3d", "gvsjax.tasks.throw3d:Throw3D")
register("follow_target", "gvsjax.tasks.curvature:FollowTarget")
register("ik_4d", "gvsjax.tasks.curvature:IK4D")
register("ik_4d_frame", "gvsjax.tasks.curvature:IK4DFrame")
register("obstacles_2d", "gvsjax.tasks.curvature:Obstacles2D")
register("obstacles_3d", "gvsjax.tasks.curvature:Obstacles3D")
