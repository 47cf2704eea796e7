"""The field's soft-arm benchmark (Choi & Tong, arXiv 2511.06667) on gvsjax: four tasks controlling
the arm's natural curvature (``gv.curvature_arm``): follow_target, ik_4d, obstacles_2d, obstacles_3d
(and ``ik_4d_frame``, ik_4d with another observation of the orientations)."""

from gvsjax.tasks.curvature.follow import FollowTarget
from gvsjax.tasks.curvature.ik import IK4D, IK4DFrame
from gvsjax.tasks.curvature.obstacles import Obstacles2D, Obstacles3D

__all__ = ["FollowTarget", "IK4D", "IK4DFrame", "Obstacles2D", "Obstacles3D"]
