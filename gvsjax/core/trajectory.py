"""The result of a simulation: saved states along time."""

from __future__ import annotations

import jax
from flax import struct


@struct.dataclass
class Trajectory:
    """Saved states of a simulation (SI units).

    t (m,), q (m, n), qd (m, n), tip (m, 3) world tip position, tip_velocity
    (m, 3), joint_torque (m, n_prescribed): the effort the prescribed joints
    exert (by inverse dynamics), N m for revolute joints; tendon_force
    (m, n_tendons), joint_force (m, n_actuated) and wrench (m, n_wrenches, 6):
    the inputs applied (zeros where none is given). ``m = n_steps / save_every + 1``.
    contact_force (m, n_c, 3): world force (N) the obstacles exert at each contact sample
    (``gvsjax.core.contact.sites`` lists them; n_c = 0 without ``Robot.contact``); contact_gap
    (m, n_c): each sample's smallest gap (m, negative when penetrating); in_contact (m,):
    whether any sample penetrates. finite (m,): whether every coordinate and velocity is
    finite (False once a run has diverged, e.g. a step too large for a stiff contact).
    """

    t: jax.Array
    q: jax.Array
    qd: jax.Array
    tip: jax.Array
    tip_velocity: jax.Array
    joint_torque: jax.Array
    tendon_force: jax.Array
    joint_force: jax.Array
    wrench: jax.Array
    contact_force: jax.Array
    contact_gap: jax.Array
    in_contact: jax.Array
    finite: jax.Array
