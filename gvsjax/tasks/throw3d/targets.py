"""throw3d's targets: reachable by construction, drawn by table look-up.

At construction a grid of actions (T uniform in 1/T, delta and psi_R
uniform) is thrown with the env's own ``release_state`` (in float32: a
table path lies within 0.1 mm of float64's), and every flight is sampled
uniformly in flight time. A sample is on the court when its horizontal
distance from the base is in [rho_min, rho_max], its height in [z_min,
z_max], and its azimuth, unwrapped about the throw's own psi_R, lies in
[-pi, pi]. That last rule keeps a target behind the shooter on the side its
throw turned to: the observed azimuth is cut at +-pi, and a throw that turned
the long way round would put neighbouring targets on two separate families of
throws, a seam no continuous policy can follow. ``reset`` draws a uniformly
random grid action, then a point uniform in flight time on its court samples
(jittered along the same path by up to a sample step); with
``target_sampling="volume"`` a covered cell of the court (``cell`` m cubes) is
drawn uniformly instead, then one of its samples, which gives the far and
high targets (thrown only by the fastest swings) a larger share; "mixed" is
either with probability 1/2. Pure JAX look-up, no simulation.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core.robots import paper_arm_3d
from gvsjax.tasks.ballistics import flight_point, floor_time
from gvsjax.tasks.base import draw_index
from gvsjax.tasks.throw3d.params import BALL_WEIGHT, Throw3DParams
from gvsjax.tasks.throw3d.throw import physical_to_action, release_state


def _wrap(a):
    return (a + jnp.pi) % (2.0 * jnp.pi) - jnp.pi


def on_court(p, psi, court) -> jax.Array:
    """Whether points p (..., 3) m thrown with yaw psi_R (...) rad lie on the court."""
    rho_min, rho_max, z_min, z_max = court
    rho = jnp.hypot(p[..., 0], p[..., 1])
    azimuth = jnp.arctan2(p[..., 1], p[..., 0])
    unwrapped = psi + _wrap(azimuth - psi)
    return ((rho >= rho_min) & (rho <= rho_max) & (p[..., 2] >= z_min) & (p[..., 2] <= z_max)
            & (jnp.abs(unwrapped) <= jnp.pi))


def observe(target, params: Throw3DParams) -> jax.Array:
    """Target (..., 3) m -> (distance, azimuth / pi, height), each scaled to [-1, 1]."""
    rho_min, rho_max, z_min, z_max = params.court
    rho = jnp.hypot(target[..., 0], target[..., 1])
    return jnp.stack([2.0 * (rho - rho_min) / (rho_max - rho_min) - 1.0,
                      jnp.arctan2(target[..., 1], target[..., 0]) / jnp.pi,
                      2.0 * (target[..., 2] - z_min) / (z_max - z_min) - 1.0], -1)


def unobserve(obs, params: Throw3DParams) -> jax.Array:
    """Inverse of ``observe``: observation (..., 3) -> target (..., 3) m."""
    rho_min, rho_max, z_min, z_max = params.court
    rho = rho_min + (obs[..., 0] + 1.0) * (rho_max - rho_min) / 2.0
    phi = obs[..., 1] * jnp.pi
    z = z_min + (obs[..., 2] + 1.0) * (z_max - z_min) / 2.0
    return jnp.stack([rho * jnp.cos(phi), rho * jnp.sin(phi), z], -1)


def _table(x: jax.Array | None) -> jax.Array:
    if x is None:
        raise ValueError("params has no target tables (a bare Throw3DParams); build it with "
                         "make_params() or the env's default_params()")
    return x


def sample_target(key, params: Throw3DParams):
    """A reachable target (3,) m and the grid action (3,) whose path passes through it."""
    k_path, k_slot, k_jit = jax.random.split(key, 3)

    def by_action():
        path = draw_index(k_path, _table(params.path_cdf))
        slot = jax.random.randint(k_slot, (), 0, _table(params.path_tau).shape[1])
        return path, _table(params.path_tau)[path, slot]

    def by_volume():
        cell = jax.random.randint(k_path, (), 0, _table(params.cell_count).shape[0])
        slot = jax.random.randint(k_slot, (), 0, _table(params.cell_count)[cell])
        return _table(params.cell_path)[cell, slot], _table(params.cell_tau)[cell, slot]

    if params.target_sampling == "action":
        path, tau = by_action()
    elif params.target_sampling == "volume":
        path, tau = by_volume()
    else:  # "mixed"
        volume = jax.random.bernoulli(jax.random.fold_in(key, 1))
        path, tau = jax.tree.map(lambda a, b: jnp.where(volume, a, b), by_volume(), by_action())
    p0, v0 = _table(params.path_p0)[path], _table(params.path_v0)[path]
    jittered = flight_point(p0, v0, jnp.maximum(tau + (jax.random.uniform(k_jit) - 0.5)
                                                * _table(params.path_jitter)[path], 0.0), params.g)
    action = _table(params.path_action)[path]
    psi = params.yaw_range[0] + (action[2] + 1.0) / 2.0 * (params.yaw_range[1] - params.yaw_range[0])
    target = jnp.where(on_court(jittered, psi, params.court), jittered, flight_point(p0, v0, tau, params.g))
    return target, action


def grid_actions(n_T: int, n_delta: int, n_yaw: int, params: Throw3DParams) -> np.ndarray:
    """(n_T * n_delta * n_yaw, 3) physical (T, delta, psi_R): T uniform in 1/T, the rest uniform."""
    T = np.clip(1.0 / np.linspace(1.0 / params.T_range[0], 1.0 / params.T_range[1], n_T), *params.T_range)
    (d0, d1), (y0, y1) = params.delta_range, params.yaw_range
    axes = (T, np.linspace(d0, d1, n_delta), np.linspace(y0, y1, n_yaw))
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def _cells(path, tau, pts, cell: float, per_cell: int, seed: int = 0):
    """Up to per_cell random samples in every covered cube: (C, K) path, tau; (C,) count."""
    ijk = np.floor(pts / cell).astype(np.int64)
    ijk -= ijk.min(0)
    dims = ijk.max(0) + 1
    cid = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    order = np.random.default_rng(seed).permutation(len(cid))
    order = order[np.argsort(cid[order], kind="stable")]
    cells, first, counts = np.unique(cid[order], return_index=True, return_counts=True)
    rank = np.arange(len(order)) - np.repeat(first, counts)
    chosen, slot = order[rank < per_cell], rank[rank < per_cell]
    row = np.searchsorted(cells, cid[chosen])
    cell_path = np.repeat(path[order[first]][:, None], per_cell, 1)
    cell_tau = np.repeat(tau[order[first]][:, None], per_cell, 1)
    cell_path[row, slot], cell_tau[row, slot] = path[chosen], tau[chosen]
    return cell_path.astype(np.int32), cell_tau, np.minimum(counts, per_cell).astype(np.int32)


def _tables(n_T, n_delta, n_yaw, n_samples, per_path, cell, per_cell, base: Throw3DParams, chunk: int = 4096):
    phys = grid_actions(n_T, n_delta, n_yaw, base)
    fast = dataclasses.replace(base, sim_dtype="float32")
    throw = jax.jit(jax.vmap(lambda T, d, s: release_state(fast, T, d, s)))
    p0s, v0s = [], []
    chunk = min(chunk, len(phys))  # a small table is not padded to a large chunk
    for i in range(0, len(phys), chunk):  # fixed chunk shape: one compilation
        part = phys[i:i + chunk]
        pad = np.concatenate([part, np.repeat(part[-1:], chunk - len(part), 0)])
        p0, v0 = throw(*(jnp.asarray(pad[:, j]) for j in range(3)))
        p0s.append(np.asarray(p0)[:len(part)])
        v0s.append(np.asarray(v0)[:len(part)])
    p0, v0 = np.concatenate(p0s), np.concatenate(v0s)
    if not (np.all(np.isfinite(p0)) and np.all(np.isfinite(v0))):
        raise RuntimeError("throw3d: a grid throw diverged; check the arm and n_steps")
    tau_end = np.asarray(floor_time(jnp.asarray(p0), jnp.asarray(v0), base.g, base.court[2]))
    u = np.linspace(0.0, 1.0, n_samples)
    tau = tau_end[:, None] * u  # (P, n_samples)
    pts = p0[:, None] + v0[:, None] * tau[..., None] + 0.5 * np.array([0.0, 0.0, -base.g]) * tau[..., None] ** 2
    ok = np.asarray(on_court(jnp.asarray(pts), jnp.asarray(phys[:, 2:3]), base.court))
    count = ok.sum(1)
    # per_path court samples spread evenly over each path's court samples
    order = np.argsort(~ok, axis=1, kind="stable")  # court samples first, in flight order
    pick = np.floor((np.arange(per_path) + 0.5) / per_path * np.maximum(count, 1)[:, None]).astype(int)
    path_tau = np.take_along_axis(tau, np.take_along_axis(order, pick, 1), 1)
    step = tau_end / (n_samples - 1)
    action = np.asarray(physical_to_action(phys[:, 0], phys[:, 1], phys[:, 2], base))
    weight = np.where(count > 0, phys[:, 0] ** 2, 0.0)  # grid uniform in 1/T: weight by dT ~ T^2
    where = np.nonzero(ok)
    cell_path, cell_tau, cell_count = _cells(where[0], tau[where], pts[where], cell, per_cell)
    return dict(path_p0=p0, path_v0=v0, path_action=action, path_tau=path_tau,
                cell_path=cell_path, cell_tau=cell_tau, cell_count=cell_count,
                path_jitter=np.where(count > 0, step * count / per_path, 0.0),
                path_cdf=np.cumsum(weight) / np.sum(weight))


_CACHE: dict[tuple, dict] = {}  # tables of the default arm, per argument set
_NOT_IN_TABLES = ("sim_dtype", "target_sampling")


def make_params(n_T: int = 48, n_delta: int = 12, n_yaw: int = 61, n_samples: int = 512, per_path: int = 64,
                cell: float = 0.25, per_cell: int = 4, **overrides) -> Throw3DParams:
    """Params with target tables built (a few tens of seconds the first time; cached for the default arm).

    ``overrides`` are fields of ``Throw3DParams`` (e.g. ``court``, ``T_range``,
    ``arm``); ``arm`` defaults to ``gv.paper_arm_3d(tip_force=5.886)``.
    """
    unknown = sorted(set(overrides) - set(Throw3DParams.__dataclass_fields__))
    if unknown:
        raise ValueError(f"unknown throw3d parameter(s) {unknown}; valid: "
                         f"{sorted(Throw3DParams.__dataclass_fields__)}")
    for name, value in (("n_T", n_T), ("n_delta", n_delta), ("n_yaw", n_yaw), ("n_samples", n_samples),
                        ("per_path", per_path), ("per_cell", per_cell)):
        if not (isinstance(value, int) and not isinstance(value, bool) and value >= 2):
            raise ValueError(f"{name}={value!r} must be an int >= 2")
    if not (isinstance(cell, (int, float)) and np.isfinite(cell) and cell > 0):
        raise ValueError(f"cell={cell!r} must be a length > 0 (m)")
    if overrides.get("target_sampling", "action") not in ("action", "volume", "mixed"):
        raise ValueError(f"target_sampling={overrides['target_sampling']!r} is invalid; choose 'action', "
                         "'volume' or 'mixed'")
    if overrides.get("sim_dtype", "float64") not in ("float64", "float32"):
        raise ValueError(f"sim_dtype={overrides['sim_dtype']!r} is invalid; choose 'float64' or 'float32'")
    for name in ("T_range", "delta_range", "yaw_range"):
        lo, hi = overrides.get(name, getattr(Throw3DParams, name))
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise ValueError(f"{name}={(lo, hi)!r} must be two finite numbers, low < high")
    arm = overrides.pop("arm", None)
    base = Throw3DParams(arm=arm if arm is not None else paper_arm_3d(tip_force=BALL_WEIGHT), **overrides)
    key = (n_T, n_delta, n_yaw, n_samples, per_path, cell, per_cell,
           tuple(sorted((k, v) for k, v in overrides.items() if k not in _NOT_IN_TABLES)))
    if arm is not None:
        tables = _tables(n_T, n_delta, n_yaw, n_samples, per_path, cell, per_cell, base)
    else:
        if key not in _CACHE:
            _CACHE[key] = _tables(n_T, n_delta, n_yaw, n_samples, per_path, cell, per_cell, base)
        tables = _CACHE[key]
    arrays: dict[str, Any] = {k: jnp.asarray(v) for k, v in tables.items()}
    return dataclasses.replace(base, **arrays)
