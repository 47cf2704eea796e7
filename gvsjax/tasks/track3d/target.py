"""The moving target: constant speed, random direction changes, kept in the box or its reachable part.

In the box (``targets="box"``) the target starts uniformly and reflects off the walls.
The reachable part (``"reachable"``) is the box's points within ``reach_radius`` of a
row of ``holdable``, the tips of the arm's equilibria under sampled held actions. There
the target starts at a uniform draw from ``starts``, box points drawn uniformly and kept
when inside the part (rejection done once, when the params are made, so that a reset
costs no distance query), and follows the box's law; a step that would leave the part
turns it instead, to the first of ``BOUNCE_CANDIDATES`` uniformly random directions whose
step stays in (a diffuse bounce off a boundary that has no simple normal); when none
does, it stays and reverses. The draws have a fixed size, so they jit and vmap.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core.validation import concrete, require
from gvsjax.tasks import arm3d, holdable
from gvsjax.tasks.track3d.params import TARGET_SETS, Track3DParams
from gvsjax.tasks.track3d.tables import TABLE_SEED, default_tips, holdable_tips

BOUNCE_CANDIDATES = 8  # directions tried at the part's boundary, the current one first
STARTS = 16384  # accepted start points in the params


def random_direction(key: jax.Array) -> jax.Array:
    """A unit 3-vector uniform on the sphere."""
    v = jax.random.normal(key, (3,))
    return v / jnp.linalg.norm(v)


def check(params: Track3DParams) -> None:
    """A ValueError naming the parameter when the target set cannot be drawn from (before tracing)."""
    require(params.targets in TARGET_SETS, "Track3DParams.targets", params.targets, f"one of {list(TARGET_SETS)}")
    if params.targets != "reachable":
        return
    for name in ("holdable", "starts"):
        value = getattr(params, name)
        if value is None:
            raise ValueError(f"Track3DParams.{name} is None but targets='reachable' needs it; build the params "
                             "with gvsjax.tasks.track3d.make_params(...) or use targets='box'")
        shape = np.shape(value)
        require(len(shape) == 2 and shape[1] == 3 and shape[0] >= 1, f"Track3DParams.{name}", f"shape {shape}",
                "shape (p, 3), p >= 1")
    r = params.reach_radius
    if concrete(r):
        require(np.ndim(r) == 0 and bool(np.isfinite(r) and r > 0), "Track3DParams.reach_radius", r,
                "a finite number > 0 (m)")
    cells = params.reach_cells
    if cells is not None and concrete((r, cells.radius, cells.low, cells.high, params.holdable)):
        built = (float(cells.radius) == float(r) and cells.table_size == np.shape(params.holdable)[0]
                 and np.array_equal(np.asarray(cells.low), np.asarray(params.box_low, float))
                 and np.array_equal(np.asarray(cells.high), np.asarray(params.box_high, float)))
        require(built, "Track3DParams.reach_cells", f"built for reach_radius={float(cells.radius)}, "
                f"{cells.table_size} holdable rows", "cells of this holdable, box and reach_radius "
                "(holdable.cell_rows), or None")


def inside(point: jax.Array, params: Track3DParams) -> jax.Array:
    """() bool: ``point`` (3,) is a place the target may be (in the box; reachable: also within
    ``reach_radius`` of a holdable tip)."""
    low, high = jnp.asarray(params.box_low), jnp.asarray(params.box_high)
    ok = jnp.all((point >= low) & (point <= high))
    if params.targets == "reachable" and params.reach_cells is not None:
        ok = ok & holdable.within_cells(point, jnp.asarray(params.holdable), params.reach_cells)
    elif params.targets == "reachable":
        ok = ok & (holdable.distance_to(point, jnp.asarray(params.holdable)) <= params.reach_radius)
    return ok


def start(key: jax.Array, params: Track3DParams) -> tuple[jax.Array, jax.Array]:
    """(position uniform in the target set, velocity of ``speed`` in a uniform direction)."""
    check(params)
    k_pos, k_dir = jax.random.split(key)
    velocity = params.speed * random_direction(k_dir)
    if params.targets == "box":
        low, high = jnp.asarray(params.box_low), jnp.asarray(params.box_high)
        return jax.random.uniform(k_pos, (3,), minval=low, maxval=high), velocity
    starts = jnp.asarray(params.starts)
    return starts[jax.random.randint(k_pos, (), 0, starts.shape[0])], velocity


def _reflect(position, velocity, params: Track3DParams):
    """One step of ``velocity``, reflected off the box's walls (each wall flips its component)."""
    low, high = jnp.asarray(params.box_low), jnp.asarray(params.box_high)
    p = position + velocity * params.arm.control_dt
    below, above = p < low, p > high
    p = jnp.where(below, 2 * low - p, jnp.where(above, 2 * high - p, p))
    return jnp.clip(p, low, high), jnp.where(below | above, -velocity, velocity)


def move(key: jax.Array, position: jax.Array, velocity: jax.Array, params: Track3DParams):
    """One control step: maybe turn (probability ``turn_probability``), then move ``velocity * control_dt``,
    reflecting off the walls (each wall flips its velocity component) and, for the reachable set,
    bouncing off its boundary (module docstring). Returns (position, velocity)."""
    check(params)
    k_turn, k_dir = jax.random.split(key)
    turn = jax.random.uniform(k_turn) < params.turn_probability
    velocity = jnp.where(turn, params.speed * random_direction(k_dir), velocity)
    if params.targets == "box":
        return _reflect(position, velocity, params)
    keys = jax.random.split(jax.random.fold_in(k_dir, 1), BOUNCE_CANDIDATES - 1)
    tries = jnp.concatenate([velocity[None], params.speed * jax.vmap(random_direction)(keys)])
    p, v = jax.vmap(_reflect, in_axes=(None, 0, None))(position, tries, params)
    ok = jax.vmap(inside, in_axes=(0, None))(p, params)
    first = jnp.argmax(ok)
    return jnp.where(jnp.any(ok), p[first], position), jnp.where(jnp.any(ok), v[first], -velocity)


def box_distance(points: Any, params: Track3DParams) -> np.ndarray:
    """(m,) the distance (m) of each of ``points`` (m, 3) from the box (0 inside)."""
    low, high = np.asarray(params.box_low), np.asarray(params.box_high)
    p = np.asarray(points)
    return np.linalg.norm(p - np.clip(p, low, high), axis=-1)


def start_points(params: Track3DParams, n: int = STARTS, seed: int = TABLE_SEED) -> np.ndarray:
    """(n, 3) m: uniform box points inside the reachable part of ``params`` (its ``holdable``
    table and ``reach_radius``), by rejection."""
    rng = np.random.default_rng(seed)
    kept: list[np.ndarray] = []
    while sum(len(k) for k in kept) < n:
        points = rng.uniform(params.box_low, params.box_high, (4 * n, 3))
        d = holdable.nearest(points, params.holdable)[0]
        kept.append(points[d <= params.reach_radius])
    return np.concatenate(kept)[:n]


def make_params(actuation: str = "tendon", targets: str = "reachable", **overrides: Any) -> Track3DParams:
    """Track3DParams of the default arm under ``actuation`` with ``targets`` (one of ``TARGET_SETS``);
    for "reachable" the table of holdable tips within ``reach_radius`` of the box and the start
    points (the default arms' tables are shipped, ``tables.default_tips``; another ``arm``'s is
    computed, ~1 min). ``overrides``: other fields (an ``arm`` sets the actuation)."""
    require(targets in TARGET_SETS, "targets", targets, f"one of {list(TARGET_SETS)}")
    allowed = set(Track3DParams.__dataclass_fields__) - {"targets", "holdable", "starts", "reach_cells"}
    unknown = sorted(set(overrides) - allowed)
    if unknown:
        raise ValueError(f"unknown track3d parameter(s) {unknown}; valid: {sorted(allowed)}")
    params = Track3DParams(**{"arm": arm3d.ArmParams(actuation=actuation), **overrides}, targets="box")
    arm3d.check(params.arm)
    if targets == "box":
        return params
    tips = holdable_tips(params.arm) if "arm" in overrides else default_tips(actuation)
    near = tips[box_distance(tips, params) <= params.reach_radius]
    params = dataclasses.replace(params, targets="reachable", holdable=jnp.asarray(near))
    params = dataclasses.replace(params, starts=jnp.asarray(start_points(params)))
    params = dataclasses.replace(params, reach_cells=holdable.cell_rows(near, params.box_low, params.box_high,
                                                                        params.reach_radius))
    check(params)
    return params
