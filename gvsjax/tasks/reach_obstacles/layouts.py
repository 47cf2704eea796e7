"""Obstacle layouts: capsules around a target, as arrays, and the arm that touches them.

A layout is three arrays, ``start`` (m, 3), ``end`` (m, 3) and ``radius`` (m,), of
capsules (``gv.Capsule``: every point within ``radius`` of the segment), given
for a scene whose target lies in the x-z plane. An episode may turn the whole
scene (target and capsules) about the vertical axis through the base by a yaw
angle; the arm is round and its tendons sit at four quarters, so a turned scene
asks for the same skill in another direction.

Two layouts are built in, both with the target to the side of the upright arm,
near the edge of what it can reach at rest:

* ``cage``: twelve bars of radius 3 cm around the target (0.8, 0, 0.35) m:
  eleven edges of a cube of side 0.5 m (open at the top edge of the face
  towards the base, where the arm comes in: with that edge closed, neither the
  direct ways in nor a trained policy got the arm through the face) and a bar
  across the bottom under the target.
  The arm at rest stands clear of it; the equilibrium that reaches the target
  passes through the cube's near face >= 14 cm from every bar, and so does the
  way there when the action is raised slowly; applied at once, the swing
  overshoots into the bars.
* ``posts``: six bars of radius 0.1 m across the x-z plane (circles in that
  plane) under, beyond and above the target (0.8, 0, 0.15) m, for the planar
  task. The quasi-static ways there stay >= 6 cm clear of them; a fast swing
  does not (applied at once, the final action swings the tip ~0.4 m below its
  rest place before it settles).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax.numpy as jnp
import numpy as np

from gvsjax.core.contact import Contact, Penalty
from gvsjax.core.obstacles import Capsule
from gvsjax.core.robots import soft_arm

CAGE_TARGET = (0.8, 0.0, 0.35)  # m
CAGE_HALF = 0.25  # m, half the cube's side
CAGE_RADIUS = 0.03  # m
POSTS_TARGET = (0.8, 0.0, 0.15)  # m
POSTS_XZ = ((0.275, 0.05), (0.5, 0.0), (0.72, -0.07), (0.93, -0.05), (1.03, 0.2), (0.97, 0.47))  # m
POSTS_RADIUS = 0.1  # m
POSTS_HALF_WIDTH = 0.3  # m, half the bars' length along y: the planar arm stays at y = 0

# the rod's contact law: stiff enough that pressing with the full tendon tension sinks ~1 cm into a bar,
# soft enough for 16 ars443 steps per 0.1 s (the contact is explicit; experiments/studies/reach_obstacles_steps.py)
PENALTY = Penalty(stiffness=3e5, damping=1e3)
N_POINTS = 11  # contact samples along the arm, 10 cm apart (straight pieces: 1.25 mm off per 1/m of curvature)
# the law runs on at most 16 (piece, bar) pairs in reach along the arm (Contact.pairs): the task's random
# actions touch more than 8 at once, 16 reproduces them to rounding (docs/contact.md)
PAIRS = 16


def cage(centre=CAGE_TARGET, half: float = CAGE_HALF, radius: float = CAGE_RADIUS) -> dict[str, np.ndarray]:
    """Twelve capsules about ``centre`` (m): eleven edges of the cube of half-side ``half`` (all but
    the top edge of the face towards the base, where the arm comes in) and a bar across the bottom
    face under the centre."""
    c = np.asarray(centre, float)
    starts, ends = [], []
    for a in range(3):  # the four edges along axis a
        b, d = [i for i in range(3) if i != a]
        for sb in (-1, 1):
            for sd in (-1, 1):
                s = c.copy()
                s[b] += sb * half
                s[d] += sd * half
                e = s.copy()
                s[a] -= half
                e[a] += half
                if a == 1 and s[0] < c[0] and s[2] > c[2]:  # the near face's top edge (along y): the way in
                    s, e = c + [0.0, -half, -half], c + [0.0, half, -half]  # becomes a bar under the centre
                starts.append(s)
                ends.append(e)
    return {"start": np.array(starts), "end": np.array(ends), "radius": np.full(12, radius)}


def posts(xz=POSTS_XZ, radius: float = POSTS_RADIUS, half_width: float = POSTS_HALF_WIDTH) -> dict[str, np.ndarray]:
    """Bars along y through the points ``xz`` of the x-z plane (m)."""
    xz = np.asarray(xz, float)
    start = np.stack([xz[:, 0], np.full(len(xz), -half_width), xz[:, 1]], -1)
    end = np.stack([xz[:, 0], np.full(len(xz), half_width), xz[:, 1]], -1)
    return {"start": start, "end": end, "radius": np.full(len(xz), radius)}


def turn(points: Any, yaw: Any) -> Any:
    """Points (..., 3) turned by ``yaw`` (rad) about the vertical axis through the origin."""
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    return jnp.stack([c * x - s * y, s * x + c * y, z], -1)


def capsules(start: Any, end: Any, radius: Any) -> tuple[Capsule, ...]:
    """The layout's arrays as a tuple of ``Capsule`` obstacles (leaves may be traced)."""
    return tuple(Capsule(start=start[i], end=end[i], radius=radius[i]) for i in range(start.shape[0]))


def contact_arm(**overrides: Any):
    """``gv.soft_arm`` with the task's contact law and samples (obstacles are set per episode)."""
    return dataclasses.replace(soft_arm(**overrides), contact=Contact(obstacles=(), rod=PENALTY, n_points=N_POINTS,
                                                                        pairs=PAIRS))
