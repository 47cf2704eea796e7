"""Drawing the upright 3D arm of the closed-loop tasks (``gvsjax.tasks.arm3d``) on 3D axes."""

from __future__ import annotations

import jax
import numpy as np

from gvsjax.core.kinematics import backbone
from gvsjax.core.model import Robot

LIMITS = ((-0.9, 0.9), (-0.9, 0.9), (-0.3, 1.1))  # m, the drawn volume: the arm's reach about its base


def setup_axes(ax) -> None:
    """Fixed limits, labels and aspect, so frames of an animation do not rescale."""
    ax.set_xlim(*LIMITS[0])
    ax.set_ylim(*LIMITS[1])
    ax.set_zlim(*LIMITS[2])
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_box_aspect(tuple(hi - lo for lo, hi in LIMITS))


def draw_arm(ax, points: np.ndarray, color: str = "tab:blue", label: str | None = None) -> None:
    """The backbone ``points`` (k, 3) and its shadow on the floor z = 0."""
    ax.plot(*points.T, color=color, lw=4, label=label)
    ax.plot(*points[:, :2].T, np.zeros(len(points)), color="0.7", lw=2)


def backbones(robot: Robot, q: np.ndarray) -> np.ndarray:
    """(T, k, 3) backbone points of the coordinates q (T, n)."""
    return np.asarray(jax.jit(jax.vmap(lambda x: backbone(robot, x)))(q))
