"""Pick and place's parameters: the tendon arm, the action ranges, observation scales, tables."""

from __future__ import annotations

import math
from typing import Any

import jax
from flax import struct

PAPER_PAIR = ((0.884, -0.344), (-0.675, -0.707))  # m, the paper's Table I targets


@struct.dataclass
class PickPlaceParams:
    """Task parameters (SI units). The target tables are built by ``make_params``."""

    arm: Any  # gv.Robot pytree
    step_time: float = 5.0  # s, duration of one step
    angle_max: float = math.pi  # rad, theta_F = angle_max * a_0
    tension_max: float = 30.0  # N, T = tension_max * (a_1 + 1) / 2
    k: float = 4.46  # 1/m, reward exp(-k d)
    q_scale: float = 2.0  # obs: curvature coefficients q1, q2 / q_scale
    qd_scale: float = 1.0  # obs: rates (rad/s and 1/s) / qd_scale
    target_scale: float = 1.0  # m, obs ("cartesian"): target / target_scale
    radius_ref: float = 0.99  # m, obs ("polar"): (|target| - radius_ref) / radius_scale
    radius_scale: float = 0.01  # m
    radius_range: tuple = (0.0, math.inf)  # m, radii clipped to this (make_params: the table's band)
    # "polar": target as (angle from the hanging direction / pi, radial offset), so the
    # +-pi seam of the joint's range is in the input too; "cartesian": (x, y) / target_scale
    target_obs: str = struct.field(pytree_node=False, default="polar")
    n_steps: int = struct.field(pytree_node=False, default=60)  # integrator steps per 5 s step
    integrator: str = struct.field(pytree_node=False, default="ars443")  # see gvsjax.core.integrators
    sim_dtype: str = struct.field(pytree_node=False, default="float64")  # simulate's dtype
    split: str = struct.field(pytree_node=False, default="train")  # "train", "test" or "all"
    n_test: int = struct.field(pytree_node=False, default=0)  # held-out rows at the table's end
    # target tables, P rows (see module docstring); None in a bare PickPlaceParams(...),
    # whose step works but whose reset needs them
    pick: jax.Array | None = None  # (P, 2) m, tip at the end of step 1
    place: jax.Array | None = None  # (P, 2) m, tip at the end of step 2
    pick_action: jax.Array | None = None  # (P, 2) in [-1, 1]
    place_action: jax.Array | None = None  # (P, 2) in [-1, 1]


# For drawing (GIF, Fig. 6): 500 RK4 steps per 5 s step give smooth frames; the task's 60
# ars443 steps end within 0.2 mm of them.
DRAWING_INTEGRATION = dict(integrator="rk4", n_steps=500)
