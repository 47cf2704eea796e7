"""The benchmark's rewards, its moving target and the tip's orientation error.

All as in Choi & Tong (arXiv 2511.06667): d is the tip-to-target distance (m), o the
orientation distance 1 - <q_tip, q_target>^2 of unit quaternions, which for
rotation matrices is (3 - trace(R_tip^T R_target)) / 4 = sin^2(angle / 2).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def reach_reward(d: jax.Array) -> jax.Array:
    """-d^2, plus 0.5 for 5 cm < d < 10 cm, plus 2.0 for d < 5 cm (follow and both obstacle tasks)."""
    return -d**2 + jnp.where((d > 0.05) & (d < 0.1), 0.5, 0.0) + jnp.where(d < 0.05, 2.0, 0.0)


def pose_reward(d: jax.Array, o: jax.Array) -> jax.Array:
    """The 4D IK reward: -d^2 - 0.5 o^2 plus the distance and orientation bonuses."""
    mid = jnp.where(o > 0.1, 1.0, 1.5) - 0.5 * o
    near = jnp.where(o > 0.1, 4.0, jnp.where(o < 0.05, 6.0, 4.5)) - 2.0 * o
    bonus = jnp.where(d < 0.05, near, jnp.where(d < 0.1, jnp.where(d > 0.05, mid, 0.0), 0.0))
    return -d**2 - 0.5 * o**2 + bonus


def orientation_distance(R_tip: jax.Array, R_target: jax.Array) -> jax.Array:
    """1 - <q_tip, q_target>^2 in [0, 1] from the two rotation matrices (3, 3)."""
    return jnp.clip((3.0 - jnp.trace(R_tip.T @ R_target)) / 4.0, 0.0, 1.0)


def benchmark_frame(R_tip: jax.Array) -> jax.Array:
    """The benchmark's tip frame [m1, m2, t] from gvsjax's section frame (columns: tangent, local
    y, local z): m1 = -y_local, m2 = -z_local, t = tangent. At rest it is a yaw of pi about z."""
    return jnp.stack([-R_tip[:, 1], -R_tip[:, 2], R_tip[:, 0]], axis=1)


def quaternion(R: jax.Array) -> jax.Array:
    """The unit quaternion (x, y, z, w), scalar last, of the rotation matrix ``R`` (3, 3), with the sign
    SciPy's ``Rotation.from_matrix(R).as_quat()`` gives it (the benchmark's observation): the largest of
    |x|, |y|, |z|, |w| is positive, found by comparing R's diagonal entries and its trace."""
    tr = jnp.trace(R)
    choice = jnp.argmax(jnp.stack([R[0, 0], R[1, 1], R[2, 2], tr]))  # the first of equal ones, as NumPy's
    rows = []
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        q: list[jax.Array] = [tr] * 4  # every slot is set below
        q[i], q[j], q[k] = 1.0 - tr + 2.0 * R[i, i], R[j, i] + R[i, j], R[k, i] + R[i, k]
        q[3] = R[k, j] - R[j, k]
        rows.append(jnp.stack(q))
    rows.append(jnp.stack([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1], 1.0 + tr]))
    quat = jnp.stack(rows)[choice]
    return quat / jnp.linalg.norm(quat)


def yaw_quaternion(yaw: jax.Array) -> jax.Array:
    """(x, y, z, w) of the rotation by ``yaw`` about world z: (0, 0, sin(yaw/2), cos(yaw/2)), as SciPy's
    ``from_euler("xyz", (0, 0, yaw))`` gives it (w > 0 for |yaw| < pi)."""
    z = jnp.zeros_like(yaw)
    return jnp.stack([z, z, jnp.sin(0.5 * yaw), jnp.cos(0.5 * yaw)])


def yaw_frame(yaw: jax.Array) -> jax.Array:
    """The rotation by ``yaw`` about world z (roll = pitch = 0)."""
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    z, one = jnp.zeros_like(yaw), jnp.ones_like(yaw)
    return jnp.stack([jnp.stack([c, -s, z]), jnp.stack([s, c, z]), jnp.stack([z, z, one])])


def target_direction(key: jax.Array, speed, dims: int = 3) -> jax.Array:
    """The benchmark's heading: a, b uniform in [0, 2 pi), speed x (cos a sin b, sin a sin b, cos b)
    (not uniform on the sphere, as published); in 2D, speed x (cos a sin b, cos b) in (x, z)."""
    a, b = jax.random.uniform(key, (2,), maxval=2 * jnp.pi)
    v = jnp.stack([jnp.cos(a) * jnp.sin(b), jnp.sin(a) * jnp.sin(b), jnp.cos(b)])
    return speed * (v if dims == 3 else v[jnp.array([0, 2])])


def move_target(key: jax.Array, position, velocity, low, high, speed, turn_probability, dt):
    """One control step of the moving target: flip each velocity component whose coordinate is outside
    [low, high]; if none flipped, take a new heading with ``turn_probability``; then move by v dt."""
    k_turn, k_dir = jax.random.split(key)
    outside = (position < low) | (position > high)
    velocity = jnp.where(outside, -velocity, velocity)
    turn = ~jnp.any(outside) & (jax.random.uniform(k_turn) < turn_probability)
    velocity = jnp.where(turn, target_direction(k_dir, speed, position.shape[0]), velocity)
    return position + velocity * dt, velocity


__all__ = ["reach_reward", "pose_reward", "orientation_distance", "benchmark_frame", "quaternion", "yaw_quaternion",
           "yaw_frame", "target_direction", "move_target"]
