"""Basketball (paper section IV-A): one throw per episode, aimed at a 2-D target.

Physics. The paper's arm (``gv.paper_arm(tip_force=5.886)``) has its revolute
base driven by theta(t) = theta_F (t/T)^2, theta_F = 210 deg. The ball (0.6 kg)
is a constant 5.886 N force along -y on the tip until release at
t_rel = delta T; only [0, t_rel] is simulated (``n_steps`` = 40 steps of the
``ars443`` IMEX integrator, dt = t_rel / n_steps <= 75 ms: every release within
0.5 mm of a converged run; RK4 would need >= 217 steps for stability alone).
The ball then flies ballistically from the tip's release position p0 and
velocity v0 (world x-y, m and m/s):
p(tau) = p0 + v0 tau + (0, -g) tau^2 / 2.

Flight path. tau runs from 0 (release) to the moment the ball reaches the
floor, ``y_floor`` = -1.95 m (the hoop is 3.05 m above the floor and 1.1 m
above the arm's base). Nothing before the release counts.

Action (2,) in [-1, 1], clipped, mapped affinely to T in [0.5, 3] s and delta
in [0.85, 1]. Observation (2,): the target, scaled from the window to [-1, 1].
Cost c (m): the exact closest distance between the flight path and the target
(the stationary points of |p(tau) - target|^2 are the roots of a cubic, solved
in closed form and polished by Newton steps; the path's ends are candidates
too). Reward exp(-k c), k = 2.2 (0.8 at the 10 cm success threshold).
Single-step episodes: ``done`` is always True. A non-finite action (played
as the box centre) or a non-finite throw gives ``info["valid"] = False`` and
reward 0, which PPO masks out of its loss.

Targets (reachable by construction). At construction a table of release
states is simulated on a grid of actions (``n_grid_T`` values of T spaced
uniformly in 1/T, which spreads the fast, far-reaching throws evenly, times
``n_grid_delta`` values of delta), i.e. with the very ``release_state`` the
env steps with. Targets lie in the court in front of the shooter: the window
x in [-8, -1] m, y in [-1.95, 4] m (the arm throws towards -x; the window
holds the three-point shot at (-6.75, 1.1) and leaves out points behind or
beside the arm, which are no basketball shots and where two separate families
of throws cover neighbouring targets, a seam no continuous policy can follow;
the first window, x in [-8, 2], y in [-1.95, 5], gave 97.9% within 10 cm
against 99.8% for this one). Default sampling (``target_sampling="action"``):
a uniformly random grid action and a point uniform in flight time on its
in-window path. ``"area"``: the window is cut into ``cell`` x ``cell``
squares, up to ``per_cell`` path samples are kept in every square some path
crosses, and ``reset`` draws a covered square uniformly (uniform in area over
the workspace, more far targets), one of its samples, and jitters its flight
time along that same path by up to half a sample step. ``"mixed"``: each
draw is ``"action"`` or ``"area"`` with probability 1/2. Either way the target
lies exactly on the flight path of a grid action, hence is reachable (to the
simulator's float precision). ``reset`` is pure JAX table look-up: it never
simulates. ``experiments/basketball_figures.py`` plots the workspace.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

import gvsjax as gv
from gvsjax.tasks.base import bounded, register, sanitize_action

BALL_WEIGHT = 5.886  # N, a 0.6 kg ball under g = 9.81
HOOP = (-6.75, 1.1)  # m, the three-point shot relative to the arm's base
WINDOW = (-8.0, -1.0, -1.95, 4.0)  # m: x_min, x_max, y_min (the floor), y_max
RELEASE_SPEED_BOUND = 100.0  # m/s per component; beyond it the throw counts as diverged


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
    integrator: str = struct.field(pytree_node=False, default="ars443")  # see gvsjax.integrators
    # simulate's dtype: "float32" runs ~2.7x the throws/s of a batch, its releases within 0.05 mm of
    # float64's (issue 4); the flight and the reward stay float64
    sim_dtype: str = struct.field(pytree_node=False, default="float64")
    # "action": a uniform random action, a point uniform in flight time on its in-window path;
    # "area": uniform in area over the cells the paths cover (harder: more far targets);
    # "mixed": either of the two with probability 1/2
    target_sampling: str = struct.field(pytree_node=False, default="action")
    # target tables (see module docstring); shapes: P grid throws, C covered cells, K per cell;
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
    path_log_weight: jax.Array | None = None  # (P,) log probability weight of a path (action-uniform)
    path_flight_jitter: jax.Array | None = None  # (P,) s, spacing of path_flight_tau


@struct.dataclass
class BasketballState:
    target: jax.Array  # (2,) m
    source_action: jax.Array  # (2,) a grid action whose path passes through the target
    step: jax.Array  # int32


# ----------------------------------------------------------------------------- physics


def action_to_physical(action: jax.Array, params: BasketballParams) -> tuple[jax.Array, jax.Array]:
    """(..., 2) action in [-1, 1] (clipped) -> (T s, delta), affinely."""
    a = jnp.clip(action, -1.0, 1.0)
    u = (a + 1.0) / 2.0
    T = params.T_range[0] + u[..., 0] * (params.T_range[1] - params.T_range[0])
    delta = params.delta_range[0] + u[..., 1] * (params.delta_range[1] - params.delta_range[0])
    return T, delta


def physical_to_action(T, delta, params: BasketballParams) -> jax.Array:
    """Inverse of ``action_to_physical``: (T, delta) -> (..., 2) action."""
    uT = (T - params.T_range[0]) / (params.T_range[1] - params.T_range[0])
    ud = (delta - params.delta_range[0]) / (params.delta_range[1] - params.delta_range[0])
    return jnp.stack([2.0 * uT - 1.0, 2.0 * ud - 1.0], axis=-1)


def release_state(params: BasketballParams, T, delta) -> tuple[jax.Array, jax.Array]:
    """Simulate the arm to t_rel = delta T: tip position (2,) m and velocity (2,) m/s."""
    dtype = params.sim_dtype
    T, delta = jnp.asarray(T).astype(dtype), jnp.asarray(delta).astype(dtype)
    law = lambda t: params.theta_final * (t / T) ** 2  # noqa: E731
    traj = gv.simulate(params.arm, delta * T, n_steps=params.n_steps, base_angle=law, save_every=params.n_steps,
                       integrator=params.integrator, check_stability=False, dtype=dtype)
    return traj.tip[-1, :2].astype(float), traj.tip_velocity[-1, :2].astype(float)


def flight_point(p0, v0, tau, g):
    """Ball position (..., 2) after flight time tau (s)."""
    tau = jnp.asarray(tau)[..., None]
    return p0 + v0 * tau + 0.5 * jnp.array([0.0, -g]) * tau**2


def floor_time(p0, v0, g, y_floor):
    """Flight time (s) at which the ball, descending, reaches y = y_floor (0 if never)."""
    disc = v0[..., 1] ** 2 + 2.0 * g * (p0[..., 1] - y_floor)
    return jnp.maximum((v0[..., 1] + jnp.sqrt(jnp.maximum(disc, 0.0))) / g, 0.0)


def _cubic_real_roots(b, c, d):
    """Three candidate real roots of x^3 + b x^2 + c x + d (repeats when only one is real)."""
    p = c - b * b / 3.0
    q = 2.0 * b**3 / 27.0 - b * c / 3.0 + d
    disc = (q / 2.0) ** 2 + (p / 3.0) ** 3
    one = disc > 0.0
    sq = jnp.sqrt(jnp.where(one, disc, 1.0))
    x1 = jnp.cbrt(-q / 2.0 + sq) + jnp.cbrt(-q / 2.0 - sq)
    p_neg = jnp.where(one, -1.0, jnp.minimum(p, -1e-300))
    m = 2.0 * jnp.sqrt(-p_neg / 3.0)
    arg = jnp.clip(3.0 * q / (p_neg * m), -1.0, 1.0)
    phi = jnp.arccos(arg) / 3.0
    xs = jnp.stack([m * jnp.cos(phi - 2.0 * jnp.pi * i / 3.0) for i in range(3)], -1)
    xs = jnp.where(one[..., None], x1[..., None], xs)
    return xs - b[..., None] / 3.0


def closest_approach(p0, v0, target, g, tau_end):
    """Exact closest distance (m) between the path p(tau), 0 <= tau <= tau_end, and target.

    Returns ``(distance, tau*)``. d/dtau |p - target|^2 / 2 is the cubic
    (g^2/2) tau^3 - (3/2) g v0y tau^2 + (|v0|^2 - g dy) tau + d.v0 with
    d = p0 - target; its real roots (closed form, two Newton polishes) and
    the two ends are the candidates. tau* carries no gradient; by the
    envelope theorem the distance's gradient is still exact.
    """
    d = p0 - target
    c3 = 0.5 * g * g
    c2 = -1.5 * g * v0[..., 1]
    c1 = jnp.sum(v0 * v0, -1) - g * d[..., 1]
    c0 = jnp.sum(d * v0, -1)
    roots = _cubic_real_roots(c2 / c3, c1 / c3, c0 / c3)
    for _ in range(2):  # Newton polish: closed-form roots lose digits near double roots
        f = ((c3 * roots + c2[..., None]) * roots + c1[..., None]) * roots + c0[..., None]
        fp = (3.0 * c3 * roots + 2.0 * c2[..., None]) * roots + c1[..., None]
        step = jnp.where(jnp.abs(fp) > 1e-12, f / jnp.where(fp == 0.0, 1.0, fp), 0.0)
        roots = roots - step
    tau_end = jnp.asarray(tau_end)
    cands = jnp.concatenate([jnp.clip(roots, 0.0, tau_end[..., None]),
                             jnp.zeros_like(roots[..., :1]), tau_end[..., None]], -1)
    cands = jax.lax.stop_gradient(cands)
    dist2 = jnp.sum((flight_point(p0[..., None, :], v0[..., None, :], cands, g)
                     - target[..., None, :]) ** 2, -1)
    i = jnp.argmin(dist2, -1)
    best = jnp.take_along_axis(dist2, i[..., None], -1)[..., 0]
    # sqrt(0) has an infinite derivative: guard the exact hit
    dist = jnp.where(best > 0.0, jnp.sqrt(jnp.where(best > 0.0, best, 1.0)), 0.0)
    return dist, jnp.take_along_axis(cands, i[..., None], -1)[..., 0]


def throw_cost(params: BasketballParams, action, target):
    """Cost (m), plus (T, delta, p0, v0) of one throw. Differentiable in ``action``."""
    T, delta = action_to_physical(action, params)
    p0, v0 = release_state(params, T, delta)
    tau_end = floor_time(p0, v0, params.g, params.y_floor)
    cost, _ = closest_approach(p0, v0, target, params.g, tau_end)
    return cost, (T, delta, p0, v0)


# ----------------------------------------------------------------------------- targets


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
        path = jax.random.categorical(k_path, _table(params.path_log_weight))
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
                path_flight_tau=flight_tau, path_log_weight=np.log(np.maximum(weight, 1e-300)),
                path_flight_jitter=np.where(has, h * np.bincount(path, minlength=len(p0))
                                            / per_path, 0.0))


_CACHE: dict[tuple, dict] = {}  # tables of the default arm, per argument set


def make_params(n_grid_T: int = 128, n_grid_delta: int = 32, cell: float = 0.05,
                per_cell: int = 4, sample_ds: float = 0.02, per_path: int = 256,
                **overrides) -> BasketballParams:
    """Params with target tables built (~2 s the first time; cached for the default arm).

    ``overrides`` are fields of ``BasketballParams`` (e.g. ``window``,
    ``T_range``, ``arm``); ``arm`` defaults to ``gv.paper_arm(tip_force=5.886)``.
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
    base = BasketballParams(arm=arm if arm is not None else gv.paper_arm(tip_force=BALL_WEIGHT),
                            **overrides)
    exact = dataclasses.replace(base, sim_dtype="float64")  # the tables' paths: float64 whatever sim_dtype is
    key = (n_grid_T, n_grid_delta, cell, per_cell, sample_ds, per_path,
           tuple(sorted((k, v) for k, v in overrides.items() if k != "sim_dtype")))
    if arm is not None:
        tables = _tables(n_grid_T, n_grid_delta, cell, per_cell, sample_ds, per_path, exact)
    else:
        if key not in _CACHE:
            _CACHE[key] = _tables(n_grid_T, n_grid_delta, cell, per_cell, sample_ds, per_path, exact)
        tables = _CACHE[key]
    arrays: dict[str, Any] = {k: jnp.asarray(v) for k, v in tables.items()}  # the table fields
    return dataclasses.replace(base, **arrays)


# ----------------------------------------------------------------------------- env


# target distribution of training (evaluation: "action", the unbiased workspace draw)
TRAIN_TARGETS = "mixed"


class Basketball:
    """The basketball task (functional env API of ``gvsjax.tasks.base``)."""

    name = "basketball"
    train_target_choices = ("action", "area", "mixed")  # values of ``train_params(targets)``
    obs_size = 2
    action_size = 2
    episode_length = 1

    def default_params(self) -> BasketballParams:
        """The paper's task with its target tables (``make_params()``, cached)."""
        return make_params()

    def train_params(self, targets: str = "") -> BasketballParams:
        """Params training uses: targets drawn by ``targets`` (``TRAIN_TARGETS`` when empty).

        Evaluation keeps ``default_params()`` (action-uniform targets). Training on
        "mixed" gives the sparse top of the court, which the fastest throws reach,
        ~2.6x its share of action-uniform draws (issue 7's note has the measurements).
        """
        if targets and targets not in self.train_target_choices:
            raise ValueError(f"train_targets={targets!r} is invalid for basketball; choose one of "
                             f"{list(self.train_target_choices)} (empty: TRAIN_TARGETS)")
        return make_params(target_sampling=targets or TRAIN_TARGETS)

    def reset(self, key, params: BasketballParams):
        """A new reachable target: ``(obs (2,), state)``; table look-up, no simulation."""
        target, source = sample_target(key, params)
        state = BasketballState(target=target, source_action=source, step=jnp.zeros((), jnp.int32))
        return normalise(target, params), state

    def step(self, key, state: BasketballState, action, params: BasketballParams):
        """Throw with ``action`` (2,): ``(obs, state, reward, done=True, info)``.

        ``info``: ``cost`` (m), the physical ``T`` and ``delta``, ``valid``, ``truncated``.
        """
        action, finite = sanitize_action(action, self.action_size)  # NaN/inf -> 0, flagged invalid
        cost, (T, delta, p0, v0) = throw_cost(params, action, state.target)
        # 100 m/s: ~6x the fastest release of the whole action box (15.8 m/s)
        valid = (finite & jnp.isfinite(cost) & jnp.all(jnp.isfinite(p0))
                 & bounded(v0, RELEASE_SPEED_BOUND))
        reward = jnp.where(valid, jnp.exp(-params.k * jnp.where(valid, cost, 0.0)), 0.0)
        state = dataclasses.replace(state, step=state.step + 1)
        info = {"cost": cost, "T": T, "delta": delta, "valid": valid,
                "truncated": jnp.zeros((), bool)}
        return normalise(state.target, params), state, reward, jnp.ones((), bool), info


register("basketball", Basketball)
