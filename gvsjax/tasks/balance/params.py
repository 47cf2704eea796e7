"""balance's parameters: the arm on a free base, the torque limit, the control rate, the reward."""

from __future__ import annotations

from flax import struct

from gvsjax.core.model import Robot
from gvsjax.core.robots import paper_arm


def torque_arm() -> Robot:
    """The paper's arm (``gv.paper_arm``) with its base joint driven by a torque."""
    return paper_arm(base="torque")


@struct.dataclass
class BalanceParams:
    """Task parameters (SI units; the base at the origin, gravity along world -y, upright is +y).

    ``torque_max``: 20 N m is 52% of the m g L / 2 = 38.5 N m that holds the straight arm
    horizontal, so the arm cannot be lifted directly (a slow lift stalls 31 degrees from
    hanging, where m g L / 2 sin(theta) = 20 N m) and the policy must pump energy into a swing;
    upright it still rights a tilt of up to 31 degrees (docs/tasks/balance.md).
    """

    arm: Robot = struct.field(default_factory=torque_arm)
    torque_max: float = 20.0  # N m, base torque = action x torque_max
    control_dt: float = 0.05  # s between actions (zero-order hold)
    start_angle: float = 0.1  # rad: the base starts at a uniform angle in +-start_angle from hanging
    start_rate: float = 0.3  # rad/s: and a uniform base rate in +-start_rate
    upright_deg: float = 5.0  # success: the tip within this angle of straight above the base
    action_cost: float = 0.2  # reward x (1 - action_cost a^2), in [0, 1]
    speed_scale: float = 2.0  # m/s: reward / (1 + (tip speed / speed_scale)^2)
    # the uprightness's share that is exp(-(tilt / upright_deg)^2), sharp where 1 - tilt / pi is flat
    upright_bonus: float = 0.5
    # ars443 steps per control step (experiments/studies/balance_substeps.py)
    n_substeps: int = struct.field(pytree_node=False, default=4)
    integrator: str = struct.field(pytree_node=False, default="ars443")
    episode_steps: int = struct.field(pytree_node=False, default=200)  # 10 s
