"""reach_pose's parameters: the arm, the table of reachable target poses, the reward scales."""

from __future__ import annotations

from typing import Any

from flax import struct

from gvsjax.tasks.arm3d import ArmParams


@struct.dataclass
class ReachPoseParams:
    """Task parameters (SI units; the arm's base at the origin, standing along +z).

    ``position`` (m, p x 3), ``axis`` (unit, p x 3) and ``action`` (p x 4) are the
    table of target poses: the arm's static equilibria under the held ``action``
    (``poses.reachable_poses``), so every target is reachable by construction.
    """

    arm: ArmParams = struct.field(default_factory=ArmParams)
    position: Any = None  # (p, 3) m, tip positions
    axis: Any = None  # (p, 3) unit tangents of the rod at the tip
    action: Any = None  # (p, 4) the held actions whose equilibria these are
    # reward per step (exp(-c) + exp(-precision c)) / 2 with c = k_position d + k_angle theta: the
    # first term pulls from afar, the second rewards the last centimetres (with d = 5 cm and theta
    # = 10 deg it is 0.34, with 2 cm and 5 deg 0.49, at the target 1)
    k_position: float = 5.0  # 1/m
    k_angle: float = 1.0  # 1/rad
    precision: float = 10.0
    episode_steps: int = struct.field(pytree_node=False, default=20)  # control steps (2 s)
