"""What the 3D arm can hold still: its static equilibria over the action box, and distances to them.

A held action a in [-1, 1]^k (either actuation of ``arm3d``) has a static equilibrium
(``gv.equilibrium``, gravity on); its tip position and the rod's tangent there are a
pose the arm can hold. Sampling the action box gives a table of such poses, and a
target's distance to the nearest one bounds what any policy can keep the tip at once
the arm has settled. Not bounded here: where a moving arm passes on its way.

The box's faces and corners are sampled on purpose: tendon and moment limits are
where the workspace's edge is, and uniform draws in k dimensions rarely sit on one.
"""

from __future__ import annotations

import functools
import itertools
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.kinematics import tip_frame
from gvsjax.core.statics import equilibrium
from gvsjax.core.validation import integer
from gvsjax.tasks import arm3d

LOAD_STEPS = 4  # continuation steps of the statics: the largest actions curl the tip below the base
PIN_PROBABILITIES = (0.0, 0.25, 0.5)  # share of an action's entries set to +-1, one third of the draws each


def sample_actions(key: jax.Array, n: int, k: int) -> np.ndarray:
    """(n, k) actions in [-1, 1]^k: first the box's corners (all 2^k when that is at most n / 8,
    else n / 8 random ones), then draws whose entries are each pinned to a random limit with a
    probability from ``PIN_PROBABILITIES`` (uniform inside otherwise). Every prefix of the
    draws is itself a sample of the same law, so nested prefixes show convergence."""
    integer("n", n)
    integer("k", k)
    k_corner, k_u, k_pin, k_p, k_sign = jax.random.split(key, 5)
    if 2**k <= n // 8:
        corners = np.array(list(itertools.product((-1.0, 1.0), repeat=k)))
    else:
        corners = np.sign(np.asarray(jax.random.uniform(k_corner, (n // 8, k), minval=-1.0, maxval=1.0)))
    m = n - len(corners)
    uniform = jax.random.uniform(k_u, (m, k), minval=-1.0, maxval=1.0)
    p = jnp.asarray(PIN_PROBABILITIES)[jax.random.randint(k_p, (m, 1), 0, len(PIN_PROBABILITIES))]
    pinned = jax.random.uniform(k_pin, (m, k)) < p
    sign = jnp.where(jax.random.bernoulli(k_sign, 0.5, (m, k)), 1.0, -1.0)
    return np.concatenate([corners, np.asarray(jnp.where(pinned, sign, uniform))])


def equilibrium_poses(arm: arm3d.ArmParams, actions: Any, batch: int = 4096) -> dict[str, np.ndarray]:
    """The static equilibria under held ``actions`` (n, k): ``q`` (n, n_dofs), tip ``position``
    (n, 3) m, the rod's unit tangent there ``axis`` (n, 3) and ``converged`` (n,), solved in
    batches of ``batch`` (one compiled program)."""
    arm3d.check(arm)
    actions = np.asarray(actions, float)
    k = arm3d.n_actions(arm)
    if actions.ndim != 2 or actions.shape[1] != k:
        raise ValueError(f"actions has shape {actions.shape}; expected (n, {k}) for ArmParams.actuation="
                         f"{arm.actuation!r}")
    batch = min(batch, len(actions))
    parts = []
    for i in range(0, len(actions), batch):
        chunk = actions[i:i + batch]
        padded = np.concatenate([chunk, np.zeros((batch - len(chunk), k))]) if len(chunk) < batch else chunk
        parts.append({key: np.asarray(v)[:len(chunk)] for key, v in _solve(arm, jnp.asarray(padded)).items()})
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


@jax.jit
@functools.partial(jax.vmap, in_axes=(None, 0))
def _solve(arm: arm3d.ArmParams, action: jax.Array) -> dict[str, jax.Array]:
    tension, strain_force = arm3d.actuate(action, arm)
    eq = equilibrium(arm.robot, tendon_force=tension, strain_force=strain_force, load_scale_steps=LOAD_STEPS)
    R, p = tip_frame(arm.robot, eq.q)
    return {"q": eq.q, "position": p, "axis": R[:, 0], "converged": eq.converged}


CELL = 0.08  # m, the side of the grid's cells: a few tens of candidate rows each on the 3D arm's tables


@struct.dataclass
class Cells:
    """Rows of a table near each cell of a grid over a box (``cell_rows``): ``rows`` (nx, ny, nz, m)
    int32 row indices (-1 pads), and the box [``low``, ``high``] (m), ``radius`` (m) and table
    size they were built for (checked against their params where concrete)."""

    rows: Any
    low: Any
    high: Any
    radius: Any
    table_size: int = struct.field(pytree_node=False, default=0)


def cell_rows(table: Any, low: Any, high: Any, radius: float, cell: float = CELL) -> Cells:
    """A grid over the box [low, high] (m) of about ``cell`` (m) per side and, for each cell, the
    rows of ``table`` (p, 3) within ``radius`` (m) of it: ``within_cells`` then answers "within
    radius of a row?" reading a cell's few rows instead of all p."""
    table, low, high = (np.asarray(x, float) for x in (table, low, high))
    n = np.maximum(np.ceil((high - low) / cell - 1e-9).astype(int), 1)
    size = (high - low) / n
    lists = []
    for idx in itertools.product(*(range(k) for k in n)):
        lo = low + size * np.asarray(idx)
        d = np.linalg.norm(table - np.clip(table, lo, lo + size), axis=-1)  # to the closed cell
        lists.append(np.nonzero(d <= radius)[0])
    m = max(1, max(len(x) for x in lists))
    out = np.full((len(lists), m), -1, np.int32)
    for i, rows in enumerate(lists):
        out[i, :len(rows)] = rows
    return Cells(rows=jnp.asarray(out.reshape(*n, m)), low=jnp.asarray(low), high=jnp.asarray(high),
                 radius=float(radius), table_size=len(table))


def within_cells(point: jax.Array, table: jax.Array, cells: Cells) -> jax.Array:
    """() bool: ``distance_to(point, table) <= cells.radius`` for a ``point`` (3,) in the cells'
    box, read from its cell's rows. Exact: a row within the radius of the point is within it of the
    point's cell. jit/vmap-able."""
    low, high = jnp.asarray(cells.low, point.dtype), jnp.asarray(cells.high, point.dtype)
    n = jnp.asarray(cells.rows.shape[:3])
    i = jnp.clip(jnp.floor((point - low) / ((high - low) / n)).astype(jnp.int32), 0, n - 1)
    cand = cells.rows[i[0], i[1], i[2]]
    d2 = jnp.sum((table[jnp.maximum(cand, 0)] - point) ** 2, axis=-1)
    return jnp.sqrt(jnp.min(jnp.where(cand >= 0, d2, jnp.inf))) <= cells.radius  # as distance_to, to the bit


def distance_to(point: jax.Array, table: jax.Array) -> jax.Array:
    """() the distance (m) from ``point`` (3,) to the nearest row of ``table`` (p, 3); jit/vmap-able."""
    return jnp.sqrt(jnp.min(jnp.sum((table - point) ** 2, axis=-1)))


def nearest(points: Any, table: Any, chunk: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``points`` (m, 3): the distance (m) to the nearest row of ``table`` (p, 3) and
    its index; exact (brute force in ``chunk``-point blocks, so memory stays chunk x p)."""
    points, table = jnp.asarray(points, float), jnp.asarray(table, float)
    m = points.shape[0]
    padded = jnp.concatenate([points, jnp.zeros(((-m) % chunk, 3))]).reshape(-1, chunk, 3)
    d, i = jax.lax.map(lambda block: _nearest_block(block, table), padded)
    return np.asarray(d).reshape(-1)[:m], np.asarray(i).reshape(-1)[:m]


@jax.jit
def _nearest_block(block, table):
    d2 = jnp.sum((block[:, None, :] - table[None]) ** 2, -1)
    i = jnp.argmin(d2, axis=1)
    return jnp.sqrt(jnp.take_along_axis(d2, i[:, None], 1)[:, 0]), i


def pose_reachable(points: Any, axes: Any, table: Any, table_axes: Any, radius: float, max_angle_deg: float,
                   chunk: int = 256) -> np.ndarray:
    """(m,) bool: some row of the table lies within ``radius`` (m) of the point with its tangent
    within ``max_angle_deg`` of the point's axis (both unit vectors); exact, brute force."""
    points, axes = jnp.asarray(points, float), jnp.asarray(axes, float)
    table, table_axes = jnp.asarray(table, float), jnp.asarray(table_axes, float)
    m = points.shape[0]
    pad = (-m) % chunk
    blocks = (jnp.concatenate([x, jnp.zeros((pad, 3))]).reshape(-1, chunk, 3) for x in (points, axes))
    cos_max = float(np.cos(np.radians(max_angle_deg)))

    def block(args):
        p, a = args
        near = jnp.sum((p[:, None, :] - table[None]) ** 2, -1) < radius**2
        aligned = (a @ table_axes.T) > cos_max
        return jnp.any(near & aligned, axis=1)

    return np.asarray(jax.lax.map(block, tuple(blocks))).reshape(-1)[:m]


__all__ = ["LOAD_STEPS", "CELL", "Cells", "sample_actions", "equilibrium_poses", "cell_rows", "within_cells",
           "distance_to", "nearest", "pose_reachable"]
