"""Basketball's parameters: the arm, the action ranges, the court, the target tables."""

from __future__ import annotations

import math
from typing import Any

import jax
from flax import struct

BALL_WEIGHT = 5.886  # N, a 0.6 kg ball under g = 9.81
HOOP = (-6.75, 1.1)  # m, the three-point shot relative to the arm's base
WINDOW = (-8.0, -1.0, -1.95, 4.0)  # m: x_min, x_max, y_min (the floor), y_max


@struct.dataclass
class BasketballParams:
    """Task parameters (SI units). The target tables are built by ``make_params``."""

    arm: Any  # gv.Robot pytree
    theta_final: float = math.radians(210.0)  # rad
    T_range: tuple = (0.5, 3.0)  # s, total motion time
    delta_range: tuple = (0.85, 1.0)  # release fraction t_rel / T
    k: float = 2.2  # 1/m, reward exp(-k c)
    g: float = 9.81  # m/s^2, along -y
    y_floor: float = WINDOW[2]  # m, the flight ends here
    window: tuple = WINDOW  # m, (x_min, x_max, y_min, y_max): targets and obs scaling
    n_steps: int = struct.field(pytree_node=False, default=40)  # integrator steps to release
    integrator: str = struct.field(pytree_node=False, default="ars443")  # see gvsjax.core.integrators
    # simulate's dtype: "float32" gives ~2.7x the throws/s of a batch, releases within 0.05 mm of
    # float64's; the flight and the reward stay float64
    sim_dtype: str = struct.field(pytree_node=False, default="float64")
    # "action": a uniform random action, a point uniform in flight time on its in-window path;
    # "area": uniform in area over the cells the paths cover (harder: more far targets);
    # "mixed": either of the two with probability 1/2
    target_sampling: str = struct.field(pytree_node=False, default="action")
    # target tables (see ``targets``); shapes: P grid throws, C covered cells, K per cell;
    # None in a bare BasketballParams(...), whose step works but whose reset needs them
    path_p0: jax.Array | None = None  # (P, 2) m
    path_v0: jax.Array | None = None  # (P, 2) m/s
    path_action: jax.Array | None = None  # (P, 2) in [-1, 1]
    path_tau_end: jax.Array | None = None  # (P,) s, floor time
    path_jitter: jax.Array | None = None  # (P,) s, flight-time jitter width
    cell_path: jax.Array | None = None  # (C, K) int32 path index
    cell_tau: jax.Array | None = None  # (C, K) s flight time
    cell_count: jax.Array | None = None  # (C,) int32 samples stored (1..K)
    path_flight_tau: jax.Array | None = None  # (P, M) s, in-window flight times per path
    path_cdf: jax.Array | None = None  # (P,) cumulative draw probability of the paths (action-uniform)
    path_flight_jitter: jax.Array | None = None  # (P,) s, spacing of path_flight_tau
