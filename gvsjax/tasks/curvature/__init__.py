"""The field's soft-arm benchmark (Choi & Tong, arXiv 2511.06667) on gvsjax: four tasks controlling
the arm's natural curvature (``gv.curvature_arm``): follow_target, ik_4d, obstacles_2d, obstacles_3d."""

from gvsjax.tasks.curvature.follow import FollowTarget
from gvsjax.tasks.curvature.ik import IK4D
from gvsjax.tasks.curvature.obstacles import Obstacles2D, Obstacles3D

__all__ = ["FollowTarget", "IK4D", "Obstacles2D", "Obstacles3D"]
