"""Basketball's targets: reachable by construction, drawn by table look-up.

At construction a table of release states is simulated on a grid of actions
(``n_grid_T`` values of T spaced uniformly in 1/T, which spreads the fast,
far-reaching throws evenly, times ``n_grid_delta`` values of delta), with the
very ``release_state`` the env steps with. Targets lie in the court in front of
the shooter: the window x in [-8, -1] m, y in [-1.95, 4] m (the arm throws
towards -x; the window holds the three-point shot at (-6.75, 1.1) and leaves
out points behind or beside the arm, where two separate families of throws
cover neighbouring targets, a seam no continuous policy can follow).

Sampling (``target_sampling``): ``"action"`` (default) draws a uniformly
random grid action and a point uniform in flight time on its in-window path.
``"area"`` cuts the window into ``cell`` x ``cell`` squares, keeps up to
``per_cell`` path samples in every square some path crosses, and draws a
covered square uniformly (uniform in area over the workspace: more far
targets), one of its samples, jittered along that same path by up to half a
sample step. ``"mixed"`` is either with probability 1/2. Every target lies
exactly on the flight path of a grid action, hence is reachable (to the
simulator's precision). ``reset`` is pure JAX table look-up: it never
simulates.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core.robots import paper_arm
from gvsjax.tasks.base import draw_index
from gvsjax.tasks.basketball.params import BALL_WEIGHT, BasketballParams
from gvsjax.tasks.basketball.throw import flight_point, floor_time, physical_to_action, release_state


def normalise(target, params: BasketballParams):
    """Target (..., 2) m -> observation in [-1, 1] by the window."""
    x0, x1, y0, y1 = params.window
    lo, hi = jnp.array([x0, y0]), jnp.array([x1, y1])
    return 2.0 * (target - lo) / (hi - lo) - 1.0


def denormalise(obs, params: BasketballParams):
    """Inverse of ``normalise``: observation in [-1, 1]^2 -> target (2,) m."""
    x0, x1, y0, y1 = params.window
    lo, hi = jnp.array([x0, y0]), jnp.array([x1, y1])
    return lo + (obs + 1.0) * (hi - lo) / 2.0


def _in_window(p, window):
    x0, x1, y0, y1 = window
    return (p[..., 0] >= x0) & (p[..., 0] <= x1) & (p[..., 1] >= y0) & (p[..., 1] <= y1)


def _table(x: jax.Array | None) -> jax.Array:
    if x is None:
        raise ValueError("params has no target tables (a bare BasketballParams); build it with "
                         "make_params() or the env's default_params()")
    return x


def sample_target(key, params: BasketballParams):
    """A reachable target (2,) m and the grid action whose path passes through it."""
    k_path, k_slot, k_jit = jax.random.split(key, 3)

    def by_area():
        cell = jax.random.randint(k_path, (), 0, _table(params.cell_count).shape[0])
        slot = jax.random.randint(k_slot, (), 0, _table(params.cell_count)[cell])
        path, tau = _table(params.cell_path)[cell, slot], _table(params.cell_tau)[cell, slot]
        return path, tau, _table(params.path_jitter)[path]

    def by_action():
        path = draw_index(k_path, _table(params.path_cdf))
        slot = jax.random.randint(k_slot, (), 0, _table(params.path_flight_tau).shape[1])
        return path, _table(params.path_flight_tau)[path, slot], _table(params.path_flight_jitter)[path]

    if params.target_sampling == "area":
        path, tau, width = by_area()
    elif params.target_sampling == "action":
        path, tau, width = by_action()
    else:  # "mixed": half of each
        area = jax.random.bernoulli(jax.random.fold_in(key, 1))
        path, tau, width = jax.tree.map(lambda a, b: jnp.where(area, a, b), by_area(), by_action())
    p0, v0 = _table(params.path_p0)[path], _table(params.path_v0)[path]
    jittered = jnp.clip(tau + (jax.random.uniform(k_jit) - 0.5) * width,
                        0.0, _table(params.path_tau_end)[path])
    point = flight_point(p0, v0, jittered, params.g)
    inside = _in_window(point, params.window)
    target = jnp.where(inside, point, flight_point(p0, v0, tau, params.g))
    return target, _table(params.path_action)[path]


def _grid_actions(n_T: int, n_delta: int, T_range, delta_range) -> np.ndarray:
    """(n_T * n_delta, 2) physical (T, delta): T uniform in 1/T, delta uniform."""
    inv = np.linspace(1.0 / T_range[0], 1.0 / T_range[1], n_T)
    T = np.clip(1.0 / inv, *T_range)
    delta = np.linspace(delta_range[0], delta_range[1], n_delta)
    TT, DD = np.meshgrid(T, delta, indexing="ij")
    return np.stack([TT.ravel(), DD.ravel()], -1)


def _path_samples(p0, v0, tau_end, window, g, ds):
    """In-window samples of every path, ~ds m apart: (path index, tau, point)."""
    speed = np.maximum(np.hypot(*v0.T), np.hypot(v0[:, 0], v0[:, 1] - g * tau_end))
    h = ds / np.maximum(speed, 1e-3)  # flight-time step per path (|v| is largest at an end)
    n = np.minimum(np.ceil(tau_end / h).astype(int) + 1, 20000)
    path = np.repeat(np.arange(len(p0)), n)
    tau = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) * h[path]
    tau = np.minimum(tau, tau_end[path])
    pts = p0[path] + v0[path] * tau[:, None] + 0.5 * np.array([0.0, -g]) * tau[:, None] ** 2
    keep = np.asarray(_in_window(pts, window))
    return path[keep], tau[keep], pts[keep], h


def _cell_table(path, tau, pts, window, cell, per_cell, seed=0):
    """Up to per_cell random samples in every covered cell: (C, K) path, tau; (C,) count."""
    x0, x1, y0, y1 = window
    ny = int(math.ceil((y1 - y0) / cell))
    ix = np.minimum(((pts[:, 0] - x0) / cell).astype(int), int(math.ceil((x1 - x0) / cell)) - 1)
    iy = np.minimum(((pts[:, 1] - y0) / cell).astype(int), ny - 1)
    cid = ix * ny + iy
    order = np.random.default_rng(seed).permutation(len(cid))
    order = order[np.argsort(cid[order], kind="stable")]
    cells, first, counts = np.unique(cid[order], return_index=True, return_counts=True)
    rank = np.arange(len(order)) - np.repeat(first, counts)
    chosen = order[rank < per_cell]
    slot = rank[rank < per_cell]
    row = np.searchsorted(cells, cid[chosen])
    cell_path = np.repeat(path[order[first]][:, None], per_cell, 1)
    cell_tau = np.repeat(tau[order[first]][:, None], per_cell, 1)
    cell_path[row, slot], cell_tau[row, slot] = path[chosen], tau[chosen]
    return cell_path.astype(np.int32), cell_tau, np.minimum(counts, per_cell).astype(np.int32)


def _flight_table(path, tau, n_paths, per_path):
    """(P, M) flight times spread evenly over each path's in-window samples; (P,) has-any."""
    counts = np.bincount(path, minlength=n_paths)
    first = np.cumsum(counts) - counts
    pick = np.floor((np.arange(per_path) + 0.5) / per_path * np.maximum(counts, 1)[:, None])
    idx = np.minimum(first[:, None] + pick.astype(int), max(len(tau) - 1, 0))
    return np.where(counts[:, None] > 0, tau[idx], 0.0), counts > 0


def _tables(n_grid_T, n_grid_delta, cell, per_cell, sample_ds, per_path, base: BasketballParams):
    phys = _grid_actions(n_grid_T, n_grid_delta, base.T_range, base.delta_range)
    throw = jax.jit(jax.vmap(lambda T, d: release_state(base, T, d)))
    p0, v0 = (np.asarray(x) for x in throw(jnp.asarray(phys[:, 0]), jnp.asarray(phys[:, 1])))
    if not (np.all(np.isfinite(p0)) and np.all(np.isfinite(v0))):
        raise RuntimeError("basketball: a grid throw diverged; check the arm and n_steps")
    tau_end = np.asarray(floor_time(p0, v0, base.g, base.y_floor))
    path, tau, pts, h = _path_samples(p0, v0, tau_end, base.window, base.g, sample_ds)
    cell_path, cell_tau, counts = _cell_table(path, tau, pts, base.window, cell, per_cell)
    flight_tau, has = _flight_table(path, tau, len(p0), per_path)
    # action-uniform draws: grid nodes are uniform in 1/T, so weight each by dT ~ T^2
    weight = np.where(has, phys[:, 0] ** 2, 0.0)
    action = np.asarray(physical_to_action(phys[:, 0], phys[:, 1], base))
    return dict(path_p0=p0, path_v0=v0, path_action=action, path_tau_end=tau_end,
                path_jitter=h, cell_path=cell_path, cell_tau=cell_tau, cell_count=counts,
                path_flight_tau=flight_tau, path_cdf=np.cumsum(weight) / np.sum(weight),
                path_flight_jitter=np.where(has, h * np.bincount(path, minlength=len(p0))
                                            / per_path, 0.0))


_CACHE: dict[tuple, dict] = {}  # tables of the default arm, per argument set
_NOT_IN_TABLES = ("sim_dtype", "target_sampling")  # fields the tables do not depend on


def make_params(n_grid_T: int = 128, n_grid_delta: int = 32, cell: float = 0.05,
                per_cell: int = 4, sample_ds: float = 0.02, per_path: int = 256,
                **overrides) -> BasketballParams:
    """Params with target tables built (~2 s the first time; cached for the default arm).

    ``overrides`` are fields of ``BasketballParams`` (e.g. ``window``,
    ``T_range``, ``arm``); ``arm`` defaults to ``paper_arm(tip_force=5.886)``.
    """
    unknown = sorted(set(overrides) - set(BasketballParams.__dataclass_fields__))
    if unknown:
        raise ValueError(f"unknown basketball parameter(s) {unknown}; valid: "
                         f"{sorted(BasketballParams.__dataclass_fields__)}")
    sampling = overrides.get("target_sampling", "action")
    if sampling not in ("action", "area", "mixed"):
        raise ValueError(f"target_sampling={sampling!r} is invalid; choose 'action', 'area' "
                         "or 'mixed'")
    if overrides.get("sim_dtype", "float64") not in ("float64", "float32"):
        raise ValueError(f"sim_dtype={overrides['sim_dtype']!r} is invalid; choose 'float64' or 'float32'")
    arm = overrides.pop("arm", None)
    base = BasketballParams(arm=arm if arm is not None else paper_arm(tip_force=BALL_WEIGHT),
                            **overrides)
    exact = dataclasses.replace(base, sim_dtype="float64")  # the tables' paths: float64 whatever sim_dtype is
    key = (n_grid_T, n_grid_delta, cell, per_cell, sample_ds, per_path,
           tuple(sorted((k, v) for k, v in overrides.items() if k not in _NOT_IN_TABLES)))
    if arm is not None:
        tables = _tables(n_grid_T, n_grid_delta, cell, per_cell, sample_ds, per_path, exact)
    else:
        if key not in _CACHE:
            _CACHE[key] = _tables(n_grid_T, n_grid_delta, cell, per_cell, sample_ds, per_path, exact)
        tables = _CACHE[key]
    arrays: dict[str, Any] = {k: jnp.asarray(v) for k, v in tables.items()}  # the table fields
    return dataclasses.replace(base, **arrays)
