"""track3d's parameters: the arm, the target's motion and region, the reward and observation scales."""

from __future__ import annotations

from typing import Any

from flax import struct

from gvsjax.core.validation import require
from gvsjax.tasks.arm3d import ArmParams

# "reachable": the box's points within reach_radius of a tip the arm holds at rest (the default);
# "box": the whole published box, much of which no held action reaches
TARGET_SETS = ("reachable", "box")


@struct.dataclass
class Track3DParams:
    """Task parameters (SI units; the arm's base at the origin, standing along +z).

    With ``targets="reachable"`` the target starts (at a row of ``starts``) and moves only where
    the arm can hold its tip: within ``reach_radius`` of a row of ``holdable``, a table of the
    arm's static tips (``target.make_params`` builds both); with ``"box"`` anywhere in the box.
    """

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
    targets: str = struct.field(pytree_node=False, default="reachable")  # one of TARGET_SETS
    holdable: Any = None  # (p, 3) m, static tips of the arm near the box (targets="reachable")
    starts: Any = None  # (s, 3) m, uniform box points within reach_radius of holdable: where a target starts
    reach_radius: float = 0.03  # m, how far from a holdable tip a reachable target may lie
    # holdable's rows near each cell of a grid over the box (holdable.cell_rows): the target's step
    # asks only its cell's; None asks every row
    reach_cells: Any = None

    def __post_init__(self) -> None:
        # a static field: its value survives pytree rebuilds, so it is checked whenever params are made
        require(isinstance(self.targets, str) and self.targets in TARGET_SETS, "Track3DParams.targets",
                self.targets, f"one of {list(TARGET_SETS)}")
