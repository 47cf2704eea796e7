"""throw3d's parameters: the arm, the action ranges, the court, the target tables."""

from __future__ import annotations

import math
from typing import Any

import jax
from flax import struct

BALL_WEIGHT = 5.886  # N, a 0.6 kg ball under g = 9.81
# m: horizontal distance from the base (min, max), height (floor, top); all azimuths
COURT = (1.0, 8.0, -1.95, 4.0)


@struct.dataclass
class Throw3DParams:
    """Task parameters (SI units). The target tables are built by ``make_params``."""

    arm: Any  # gv.Robot pytree, ``gv.paper_arm_3d``
    theta_final: float = math.radians(210.0)  # rad, the swing at the end of the motion
    T_range: tuple = (0.5, 3.0)  # s, total motion time
    delta_range: tuple = (0.85, 1.0)  # release fraction t_rel / T
    # rad, the yaw psi_R at release: past +-pi so that targets behind are reached from either side
    yaw_range: tuple = (-1.1 * math.pi, 1.1 * math.pi)
    k: float = 2.2  # 1/m, reward exp(-k c)
    g: float = 9.81  # m/s^2, along -z
    court: tuple = COURT  # (rho_min, rho_max, z_min, z_max) m: targets and observation scaling
    n_steps: int = struct.field(pytree_node=False, default=40)  # integrator steps to release
    integrator: str = struct.field(pytree_node=False, default="ars443")
    sim_dtype: str = struct.field(pytree_node=False, default="float64")
    # "action": a uniform random grid action, a point uniform in flight time on its court path;
    # "volume": uniform over the court's covered cells (more far and high targets);
    # "mixed": either with probability 1/2
    target_sampling: str = struct.field(pytree_node=False, default="action")
    # target tables (``targets``): P grid throws, M in-court flight times per throw;
    # None in a bare Throw3DParams(...), whose step works but whose reset needs them
    path_p0: jax.Array | None = None  # (P, 3) m
    path_v0: jax.Array | None = None  # (P, 3) m/s
    path_action: jax.Array | None = None  # (P, 3) in [-1, 1]
    path_tau: jax.Array | None = None  # (P, M) s, in-court flight times
    path_jitter: jax.Array | None = None  # (P,) s, spacing of path_tau
    path_cdf: jax.Array | None = None  # (P,) cumulative draw probability (flat over throws missing the court)
    cell_path: jax.Array | None = None  # (C, K) int32 path index of samples in each covered cell
    cell_tau: jax.Array | None = None  # (C, K) s flight time
    cell_count: jax.Array | None = None  # (C,) int32 samples stored (1..K)
