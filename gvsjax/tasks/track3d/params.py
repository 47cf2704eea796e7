"""track3d's parameters: the arm, the target's motion, the reward and observation scales."""

from __future__ import annotations

from flax import struct

from gvsjax.tasks.arm3d import ArmParams


@struct.dataclass
class Track3DParams:
    """Task parameters (SI units; the arm's base at the origin, standing along +z)."""

    arm: ArmParams = struct.field(default_factory=ArmParams)
    box_low: tuple = (-0.6, -0.6, 0.3)  # m, the target stays in this box
    box_high: tuple = (0.6, 0.6, 0.9)  # m
    speed: float = 0.5  # m/s, the target's constant speed
    turn_probability: float = 0.025  # per control step: a new random direction
    k: float = 5.0  # 1/m, reward exp(-k d) per step (0.78 at 5 cm, 0.61 at 10 cm, 0.08 at 50 cm)
    # minus action_rate_weight x mean((a - a_before)^2): a price on switching tensions from one control
    # step to the next, which whips the arm; the policy observes its last action, so the term is a
    # function of what it sees. 0.1 smooths the actions ~25x at the same tracking accuracy
    action_rate_weight: float = 0.1
    episode_steps: int = struct.field(pytree_node=False, default=100)  # control steps (10 s)
