"""The upright 3D soft arm the closed-loop tasks control (``gv.soft_arm``).

A policy acts every ``control_dt`` seconds; in between its input is held
(zero-order hold) while the physics takes ``n_substeps`` ``ars443`` steps.
``ArmParams.actuation`` picks what an action is (``gvsjax.tasks.actuation``):
four tendon numbers in [-1, 1], one per bending direction of each tendon group
(``"tendon"``, tensions up to ``tension_max``), or 12 bending moments at six
control points along the arm (``"muscle"``, up to ``moment_max``). The arm is
observed through its tip (position, velocity) and its strain coordinates and
rates, each scaled to order one.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.model import Robot, SoftLink
from gvsjax.core.robots import soft_arm
from gvsjax.core.simulation import simulate
from gvsjax.tasks import actuation as act

ANGULAR_SCALE = 3.0  # 1/m: torsion and curvature coefficients are observed / this
LINEAR_SCALE = 0.05  # stretch and shear coefficients / this
RATE_FACTOR = 10.0  # rates are observed / (10 1/s x the coordinate's scale)
Q_BOUND = 50.0  # beyond |q| / scale = 50 a state is treated as diverged (curvature > 150 / m)
QD_BOUND = 1e3
# PPO settings of the tasks on this arm (each task adds its number of episodes): separate 256-256 tanh
# actor and critic, one 20-step rollout of 512 envs per update
PPO_DEFAULTS: dict[str, Any] = dict(
    network="separate", actor_hidden=(256, 256), critic_hidden=(256, 256), activation="tanh",
    num_envs=512, num_steps=20, num_minibatches=8, update_epochs=4, gamma=0.98, gae_lambda=0.95,
    learning_rate=3e-4, clip_eps=0.2, ent_coef=0.0, init_log_std=-1.0, anneal_lr=True,
    finetune_fraction=0.0, max_grad_norm=0.5,
)


@struct.dataclass
class ArmParams:
    """The arm, its actuation and the control rate (SI units)."""

    robot: Robot = struct.field(default_factory=soft_arm)
    tension_max: float = 2000.0  # N per tendon: both groups together bend the tip below the tasks' targets
    # N m per control point and direction (muscle actuation): the tendons' static cover of track3d's box;
    # 80 N m, the whole-arm tendon's 2000 N x 4 cm, covers less (experiments/studies/muscle_workspace.py)
    moment_max: float = 90.0
    actuation: str = struct.field(pytree_node=False, default="tendon")  # "tendon" or "muscle"
    control_dt: float = 0.1  # s between actions
    # ars443 steps per control step: 8 keep the tip within 6 mm (95th percentile) of a converged run under
    # actions held for 1 s, 16 within 1 mm (experiments/studies/track3d_substeps.py)
    n_substeps: int = struct.field(pytree_node=False, default=8)
    integrator: str = struct.field(pytree_node=False, default="ars443")
    sim_dtype: str = struct.field(pytree_node=False, default="float64")  # simulate's dtype; the env stays float64

    def __post_init__(self) -> None:
        # the limits are checked when they are numbers (pytrees are also rebuilt from placeholders)
        act.check_actuation(self.actuation, self.tension_max, self.moment_max, strict=False)


def with_sim_dtype(arm: ArmParams, sim_dtype: str) -> ArmParams:
    """``arm`` simulating in ``sim_dtype`` ("float64", "float32" or empty: float64)."""
    if sim_dtype not in ("", "float64", "float32"):
        raise ValueError(f"sim_dtype={sim_dtype!r} is invalid; choose 'float64' or 'float32'")
    return dataclasses.replace(arm, sim_dtype=sim_dtype or "float64")


def n_actions(arm: ArmParams) -> int:
    """The action size of the arm's actuation: two per group of four tendons, or 12 moments."""
    return act.n_actions(arm.robot, arm.actuation)


def check(arm: ArmParams) -> None:
    """The arm is one soft link with groups of four tendons (``gv.soft_arm``) and a valid actuation."""
    robot = arm.robot
    if len(robot.links) != 1 or not isinstance(robot.links[0], SoftLink) or len(robot.tendons) % 4 or not robot.tendons:
        raise ValueError("ArmParams.robot must be a gv.soft_arm(...): one soft link and groups of four tendons")
    act.check_actuation(arm.actuation, arm.tension_max, arm.moment_max)


def check_task(env: Any, arm: ArmParams, episode_steps: int, other_obs: int) -> None:
    """``arm`` is a ``gv.soft_arm`` that fits task ``env``: its action size, its observation of
    ``6 + 2 n_dofs + other_obs`` entries and its episode length."""
    check(arm)
    robot = arm.robot
    n = (env.obs_size - 6 - other_obs) // 2
    other = dataclasses.replace(arm, actuation="muscle" if arm.actuation == "tendon" else "tendon")
    if n_actions(arm) != env.action_size and n_actions(other) == env.action_size:
        raise ValueError(f"{env.name} takes {env.action_size} actions, but ArmParams.actuation={arm.actuation!r} "
                         f"makes {n_actions(arm)}; use the task registered for that actuation")
    if n_actions(arm) != env.action_size or robot.n_dofs != n or episode_steps != env.episode_length:
        raise ValueError(f"{env.name}'s arm has two tendon groups and {n} strain coordinates (got "
                         f"{len(robot.tendons)} tendons, {robot.n_dofs} coordinates) and episode_steps="
                         f"{env.episode_length} (got {episode_steps})")


def tensions(action: jax.Array, arm: ArmParams) -> jax.Array:
    """Tendon actions (..., 2 g) in [-1, 1] (clipped) -> tensions (..., 4 g) N, >= 0."""
    return act.tensions(action, arm.tension_max)


def actuate(action: jax.Array, arm: ArmParams) -> tuple[jax.Array, jax.Array]:
    """One action (n_actions(arm),) -> ``(tendon_force, strain_force)`` under the arm's actuation."""
    return act.actuate(action, arm.robot, arm.actuation, arm.tension_max, arm.moment_max)


def advance(arm: ArmParams, q, qd, tension, save_every: int | None = None, strain_force=None):
    """One control step with ``tension`` (and ``strain_force``, default 0) held: the ``Trajectory``
    (its last state the new one), float64."""
    dtype = arm.sim_dtype
    cast = lambda x: jnp.asarray(x).astype(dtype)  # noqa: E731
    tr = simulate(arm.robot, arm.control_dt, n_steps=arm.n_substeps, tendon_force=cast(tension), q0=cast(q),
                  qd0=cast(qd), save_every=save_every or arm.n_substeps, integrator=arm.integrator,
                  strain_force=None if strain_force is None else cast(strain_force), check_stability=False,
                  dtype=dtype)
    return jax.tree_util.tree_map(lambda x: x.astype(float), tr)


def control_step(arm: ArmParams, q, qd, action, save_every: int | None = None):
    """One control step under ``action`` (the arm's actuation): ``(Trajectory, tendon_force, strain_force)``."""
    tension, strain_force = actuate(action, arm)
    # a tendon arm's program stays the one without a strain force
    held = strain_force if arm.actuation == "muscle" else None
    return advance(arm, q, qd, tension, save_every, held), tension, strain_force


def coordinate_scales(robot: Robot) -> np.ndarray:
    """(n,) the scale each strain coordinate is observed in (angular or linear strain)."""
    link = robot.links[0]
    return np.concatenate([np.full(order + 1, ANGULAR_SCALE if c < 3 else LINEAR_SCALE)
                           for c, order in enumerate(link.basis.orders) if order >= 0])


def arm_features(robot: Robot, q, qd, tip, tip_velocity) -> jax.Array:
    """(6 + 2 n,) the tip's position (m) and velocity (m/s), q and qd, each scaled to ~1."""
    s = jnp.asarray(coordinate_scales(robot))
    return jnp.concatenate([tip, tip_velocity, q / s, qd / (RATE_FACTOR * s)])


def healthy(robot: Robot, q, qd) -> jax.Array:
    """False when the state is non-finite or beyond the divergence bounds."""
    s = jnp.asarray(coordinate_scales(robot))
    return jnp.all(jnp.abs(q / s) <= Q_BOUND) & jnp.all(jnp.abs(qd / s) <= QD_BOUND)


def rest(robot: Robot) -> tuple[jax.Array, jax.Array]:
    """q = qd = 0: straight and unstressed; upright, the arm then settles by its weight
    (an axial sag of rho g L^2 / 2E, 0.5 mm for the default arm)."""
    n = robot.n_dofs
    return jnp.zeros(n), jnp.zeros(n)


__all__: list[Any] = ["PPO_DEFAULTS", "ArmParams", "with_sim_dtype", "n_actions", "check", "check_task", "tensions",
                      "actuate", "advance", "control_step", "coordinate_scales", "arm_features", "healthy", "rest"]
