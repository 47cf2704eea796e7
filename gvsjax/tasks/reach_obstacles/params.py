"""reach_obstacles' parameters: the arm, the obstacle layout, the target's draw, the reward."""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp
from flax import struct

from gvsjax.tasks.arm3d import ArmParams
from gvsjax.tasks.reach_obstacles.layouts import CAGE_TARGET, cage, contact_arm


def _arm() -> ArmParams:
    # contact is explicit in every integrator: 16 steps per 0.1 s keep the bars' stiffness stable
    return ArmParams(robot=contact_arm(), n_substeps=16)


def _cage() -> dict:
    return {k: jnp.asarray(v) for k, v in cage().items()}


@struct.dataclass
class ReachObstaclesParams:
    """Task parameters (SI units; the arm's base at the origin, standing along +z).

    The layout (``start``, ``end``, ``radius``: capsules) and ``target`` are given for
    yaw 0; each episode draws the scene's yaw uniformly in [-yaw_range, yaw_range]
    (0: the fixed layout) and the target uniformly within ``target_jitter`` of its
    place in each coordinate; each capsule moves within ``layout_jitter`` of its place in each
    coordinate (0: the obstacles stay).
    """

    arm: ArmParams = struct.field(default_factory=_arm)
    start: Any = struct.field(default_factory=lambda: _cage()["start"])  # (m, 3) m
    end: Any = struct.field(default_factory=lambda: _cage()["end"])  # (m, 3) m
    radius: Any = struct.field(default_factory=lambda: _cage()["radius"])  # (m,) m
    target: Any = CAGE_TARGET  # (3,) m, at yaw 0
    target_jitter: Any = (0.03, 0.03, 0.03)  # m, per coordinate
    # m, per coordinate: each capsule moves by its own uniform draw within this (random layouts; the
    # policy senses them through its contact samples' gaps)
    layout_jitter: Any = (0.0, 0.0, 0.0)
    yaw_range: float = 0.0  # rad; pi: a scene turned anywhere about the base
    # reward per step: (exp(-k d) + exp(-precision k d)) / 2 - penetration_weight x min(depth / tolerance, 2)
    # the first term pulls from a metre away (0.25 at 70 cm), the second rewards the last centimetres
    # (0.37 at 5 cm, 0.82 at 1 cm)
    k: float = 2.0  # 1/m
    precision: float = 10.0
    tolerance: float = 0.01  # m, the penetration a success allows
    penetration_weight: float = 0.5
    # minus action_rate_weight x mean((a - a_before)^2) over the task's actions: damps a control-rate
    # chatter (a bang-bang limit cycle around the target) and a sudden start (a swing into the bars)
    action_rate_weight: float = 0.0
    # the last step's closeness term counts (1 + final_weight) times: success is judged at the end, and
    # the per-step terms alone pay a fast approach that ends farther off
    final_weight: float = 0.0
    # 0: the policy's actions are the tendon groups' actions. > 0: they are corrections, times this, to
    # the open-loop ramp of the task's reference action (``env.RAMP_S`` rise, turned with the scene),
    # the sum clipped to [-1, 1]: residual policy learning (Silver et al. 2018), started from a
    # baseline that already passes the bars
    residual_scale: float = 0.0
    # with residual_scale > 0, in [0, 1]: how much the corrections rise with the ramp; 1: the applied
    # action is clip(ramp fraction x (reference + residual_scale x action)), so no action rises much
    # faster than the baseline that passes the bars (the policy chooses where the arm goes, the ramp
    # how fast); 0: the corrections apply at once
    residual_rise: float = 0.0
    success_distance: float = 0.05  # m
    episode_steps: int = struct.field(pytree_node=False, default=30)  # control steps (3 s)
