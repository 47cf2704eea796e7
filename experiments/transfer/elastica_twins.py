"""PyElastica twins of the four benchmark tasks (follow_target, ik_4d, obstacles_2d, obstacles_3d).

The twin follows Choi & Tong's Elastica environments (arXiv 2511.06667, QuantuMope/dismech-rl), run on
PyElastica 1.0: a ``CosseratRod`` of 20 elements (21 nodes), 1 m, radius 5 cm, E 10 MPa, density 1000,
G = E/3, built along +z with normal +x, node 0 and element 0 clamped (``OneEndFixedBC``), gravity 9.8
along -z, position Verlet at 2e-4 s. Their world is Elastica's with x and y swapped (they read
``position_collection[[1, 0, 2]]``), and so is the twin's observation.

* Damping: their pinned PyElastica 0.2.4 damps with ``straight_rod(nu=10)``; 1.0 removed ``nu``. The
  twin uses ``AnalyticalLinearDamper`` with the constants of ``dismech_damping.damper_settings``:
  translational nu x each node's share of element length, rotational (J_e / dt) ln(1 + nu l_e dt / J_e)
  (0.2.4's explicit torque -nu l_e omega; ``experiments/transfer/dismech_damping.py`` checks both laws decay alike).
* Control (their ``ActionConverter``): the turning angles come from gvsjax's own ``control.apply``
  (clip included). Control point k's angle is spread evenly over the Voronoi nodes of its segment, whose
  bounds are node 1, the midpoints between control nodes, and node 20: nodes {2-4}, {5-8}, {9-12},
  {13-16}, {17-19}, each getting angle / (bound difference) (3, 4, 4, 4 and 4 for the last, so it gets 3/4
  of its angle and node 1 none), divided by the Voronoi length into ``rest_kappa``. Direction 1 enters
  ``rest_kappa[0]``, direction 2 and the twist with a minus sign. Over the control interval the rest
  curvature moves linearly, one increment before each Verlet step.
* Target and reward: gvsjax's ``task.reset`` (the target, the obstacles) and ``task.after`` (the target's
  move, the reward) on an ``EpisodeState`` filled from the rod; the observation is ``task.observe``'s.
* Contact (obstacle tasks): rigid ``ea.Cylinder`` obstacles held by ``FixedConstraint``, against the rod
  through ``RodCylinderContact`` (1.0's name for 0.2.4's rod-cylinder ``ExternalContact``; the same
  kernel) with their constants k = 1.6e5 N/m and nu = 4 N s/m per element, no friction.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
for _p in (HERE, os.path.dirname(os.path.dirname(HERE))):  # this folder (dismech_damping) and the repository's gvsjax
    if _p not in sys.path:
        sys.path.insert(0, _p)

import gvsjax  # noqa: F401  (configures JAX before any computation)
from gvsjax.tasks.curvature import control

N_EL, DT, GRAVITY = 20, 2e-4, 9.8  # elements, s, m/s^2
LENGTH, RADIUS, E, RHO = 1.0, 0.05, 1e7, 1000.0
CONTROL_NODES = (2, 6, 10, 14, 18)
STATE_NODES = tuple(range(2, 21, 2))  # 0.1, 0.2, ..., 1.0 m
SWAP = [1, 0, 2]  # Elastica <-> their (and gvsjax's) world: x and y exchanged
CONTACT_K, CONTACT_NU = 2 * 8e4, 4.0  # their ExternalContact constants, per element
DEPTH_EVERY = 50  # Verlet steps between penetration checks (10 ms)


def node_weights(n_nodes: int = N_EL + 1, ctrl=CONTROL_NODES) -> np.ndarray:
    """(n_nodes - 2, 5): the share of control point k's turning angle at interior node j + 1, as their
    ``ActionConverter`` spreads it (rows past the last interior node are dropped, so the last segment
    gets 3/4)."""
    bounds = [1] + [(a + b) // 2 for a, b in zip(ctrl[:-1], ctrl[1:])] + [n_nodes - 1]
    W = np.zeros((n_nodes - 2, len(ctrl)))
    for k, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
        W[lo:hi, k] = 1.0 / (hi - lo)  # rows index interior node row + 1; slicing past the end drops rows
    return W


def rest_kappa(kappa: np.ndarray, twist: np.ndarray, voronoi: np.ndarray) -> np.ndarray:
    """(3, 19) Elastica rest curvature (1/m) of turning angles kappa (5, directions) and twists (5,)."""
    W = node_weights()
    out = np.zeros((3, N_EL - 1))
    out[0] = W @ kappa[:, 0]
    if kappa.shape[1] > 1:
        out[1] = -(W @ kappa[:, 1])  # their polarity flip for DisMech's second direction
    out[2] = -(W @ twist)  # and for the twist
    return out / voronoi


def _point_capsule_depth(points: np.ndarray, ends: np.ndarray, radius: float) -> float:
    """Deepest penetration (m, <= 0 when clear) of the rod's surface at ``points`` (P, 3) into capsules with
    axes ``ends`` (m, 2, 3) and ``radius``."""
    a, b = ends[:, 0], ends[:, 1]
    d = b - a
    t = np.clip(np.einsum("pmk,mk->pm", points[:, None] - a[None], d) / np.einsum("mk,mk->m", d, d), 0.0, 1.0)
    dist = np.linalg.norm(points[:, None] - (a[None] + t[..., None] * d[None]), axis=-1)
    return float(np.max(radius + RADIUS - dist))


class ElasticaTwin:
    """One environment of a gvsjax benchmark task simulated in PyElastica (their world frame).

    ``reset(key) -> obs``; ``step(key, action) -> (obs, reward, done, info)`` with the same keys as
    gvsjax's ``env.reset`` / ``env.step`` (per-step ``fold_in(key, t)``), so the targets match.
    ``contact``: (k, nu) per element for the obstacle tasks; ``gravity`` m/s^2 along -z.
    """

    def __init__(self, task, params, contact: tuple[float, float] = (CONTACT_K, CONTACT_NU),
                 gravity: float = GRAVITY):
        self.task, self.params, self.contact, self.gravity = task, params, contact, gravity
        self.n_sub = int(round(params.arm.control_dt / DT))
        self._reset = jax.jit(lambda k: task.reset(k, params)[1])
        self._after = jax.jit(lambda k, s: task.after(k, s, params))
        self._observe = jax.jit(lambda s: task.observe(s, params))
        self._apply = jax.jit(lambda k, t, a: control.apply(params.arm, k, t, a))
        self.has_obstacles = hasattr(params, "n_obstacles")
        self.steps_simulated = 0

    # ------------------------------------------------------------------ the simulator

    def _build(self, obstacles: np.ndarray) -> None:
        import elastica as ea
        from dismech_damping import damper_settings

        mixins = (ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping) + (
            (ea.Contact,) if len(obstacles) else ())
        sim = type("TwinSim", mixins, {})()
        rod = ea.CosseratRod.straight_rod(n_elements=N_EL, start=np.zeros(3), direction=np.array([0.0, 0.0, 1.0]),
                                          normal=np.array([1.0, 0.0, 0.0]), base_length=LENGTH, base_radius=RADIUS,
                                          density=RHO, youngs_modulus=E, shear_modulus=E / 3.0)
        sim.append(rod)
        sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
        sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -self.gravity]))
        sim.dampen(rod).using(ea.AnalyticalLinearDamper, time_step=DT, **damper_settings())
        for a, b in obstacles:  # their world -> Elastica's
            a, b = a[SWAP], b[SWAP]
            axis = (b - a) / np.linalg.norm(b - a)
            normal = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
            cyl = ea.Cylinder(start=a, direction=axis, normal=normal / np.linalg.norm(normal),
                              base_length=float(np.linalg.norm(b - a)), base_radius=float(self.params.radius),
                              density=RHO)
            sim.append(cyl)
            sim.constrain(cyl).using(ea.FixedConstraint, constrained_position_idx=(0,), constrained_director_idx=(0,))
            sim.detect_contact_between(rod, cyl).using(ea.RodCylinderContact, k=self.contact[0], nu=self.contact[1])
        sim.finalize()
        self.sim, self.rod, self.stepper, self.time = sim, rod, ea.PositionVerlet(), np.float64(0.0)
        self.obstacles = np.asarray(obstacles, float)

    def _fill(self, state):
        """``state`` with the rod's observed nodes (their world) and tip frame."""
        rod = self.rod
        p = rod.position_collection[SWAP][:, STATE_NODES].T
        v = rod.velocity_collection[SWAP][:, STATE_NODES].T
        d = rod.director_collection[..., -1][:, SWAP]  # rows d1, d2, d3 (their world)
        # gvsjax's tip_R columns (tangent, local y, local z) = (d3, d2, d1): benchmark_frame gives [-d2, -d1, d3]
        R = np.stack([d[2], d[1], d[0]], axis=1)
        return dataclasses.replace(state, node_p=jnp.asarray(p), node_v=jnp.asarray(v), tip_R=jnp.asarray(R))

    def depth(self) -> float:
        """Deepest penetration now (m): the rod's centreline sampled 4 times per element, against capsules."""
        if not len(self.obstacles):
            return 0.0
        x = self.rod.position_collection[SWAP].T
        pts = np.concatenate([x[:-1] + f * (x[1:] - x[:-1]) for f in (0.0, 0.25, 0.5, 0.75)] + [x[-1:]])
        return max(_point_capsule_depth(pts, self.obstacles, float(self.params.radius)), 0.0)

    # ------------------------------------------------------------------ the environment

    def reset(self, key) -> np.ndarray:
        state = self._reset(key)  # gvsjax's target (and obstacles) for this key
        self._build(np.asarray(state.obstacles))
        self.state = self._fill(state)
        return np.asarray(self._observe(self.state))

    def step(self, key, action) -> tuple[np.ndarray, float, bool, dict]:
        s = self.state
        kappa, twist = self._apply(s.kappa, s.twist, jnp.asarray(action, float))
        voronoi = self.rod.rest_voronoi_lengths
        old = rest_kappa(np.asarray(s.kappa), np.asarray(s.twist), voronoi)
        new = rest_kappa(np.asarray(kappa), np.asarray(twist), voronoi)
        deepest, ok = float(s.deepest), True
        for i in range(self.n_sub):
            self.rod.rest_kappa[:] = old + ((i + 1) / self.n_sub) * (new - old)
            self.time = self.stepper.step(self.sim, self.time, DT)
            if (i + 1) % DEPTH_EVERY == 0:
                ok = bool(np.isfinite(self.rod.position_collection[:, -1]).all())
                if not ok:
                    break
                deepest = max(deepest, self.depth())
        self.steps_simulated += i + 1
        ok = ok and bool(np.isfinite(self.rod.position_collection).all())
        moved = dataclasses.replace(s, kappa=kappa, twist=twist, deepest=jnp.asarray(deepest), step=s.step + 1)
        if ok:
            moved = self._fill(moved)
        new_state, reward, info = self._after(key, moved)
        reward = float(reward) if ok else -10.0  # the benchmark's penalty for a failed simulation
        self.state = new_state
        done = bool(int(new_state.step) >= self.task.episode_length) or not ok
        info = {k: float(v) for k, v in info.items()} | {"valid": ok, "deepest": deepest,
                                                         "tip": np.asarray(new_state.node_p[-1]),
                                                         "target": np.asarray(new_state.target)}
        return np.asarray(self._observe(new_state)), reward, done, info


def run_episode(twin: ElasticaTwin, key, policy=None, actions=None) -> dict:
    """One episode from ``reset(key)``: per step reward, distance, orientation, deepest, tip, target, valid
    (each (T, ...)). ``policy``: obs (k,) -> action; or open-loop ``actions`` (T, a)."""
    t0 = time.perf_counter()
    obs = twin.reset(key)
    rec: dict[str, list] = {k: [] for k in ("reward", "distance", "orientation", "deepest", "tip", "target",
                                            "valid")}
    alive = True
    for t in range(twin.task.episode_length):
        a = actions[t] if actions is not None else policy(obs)
        obs, r, done, info = twin.step(jax.random.fold_in(key, t), a)
        alive = alive and info["valid"]
        for k in rec:
            rec[k].append(r if k == "reward" else alive if k == "valid" else info.get(k, 0.0))
        if not alive:  # gvsjax keeps the last valid state; its later steps count as invalid
            for _ in range(t + 1, twin.task.episode_length):
                for k in rec:
                    rec[k].append(rec[k][-1] if k not in ("reward", "valid") else (-10.0 if k == "reward" else False))
            break
    out = {k: np.asarray(v) for k, v in rec.items()}
    out["wall_s"] = time.perf_counter() - t0
    return out


def held_actions(key, n_steps: int, n_actions: int, hold: int) -> np.ndarray:
    """(n_steps, n_actions) open-loop actions: uniform in [-1, 1], each held for ``hold`` steps."""
    n = -(-n_steps // hold)
    a = np.asarray(jax.random.uniform(key, (n, n_actions), minval=-1.0, maxval=1.0))
    return np.repeat(a, hold, axis=0)[:n_steps]


def gvsjax_open_loop(task, params, keys, actions) -> dict:
    """gvsjax's episodes from ``reset(keys[i])`` under open-loop ``actions`` (n, T, a), keys as
    ``record_episodes``': per step (n, T) reward, distance, deepest, tip (n, T, 3), target, valid."""
    def one(key, acts):
        _, state = task.reset(key, params)

        def body(carry, t):
            s, alive = carry
            _, s, r, _, info = task.step(jax.random.fold_in(key, t), s, acts[t], params)
            alive = alive & info["valid"]
            return (s, alive), {"reward": r, "distance": info["distance"], "deepest": s.deepest,
                                "tip": s.node_p[-1], "target": s.target, "valid": alive, "depth": info["depth"]}

        return jax.lax.scan(body, (state, jnp.asarray(True)), jnp.arange(task.episode_length))[1]

    out = jax.jit(jax.vmap(one))(keys, jnp.asarray(actions))
    return {k: np.asarray(v) for k, v in out.items()}


def _rotation(w: np.ndarray) -> np.ndarray:
    """exp([w]x) (3, 3) of a rotation vector w (3,) (Rodrigues)."""
    th = float(np.linalg.norm(w))
    K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if th < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(th) / th * K + (1.0 - np.cos(th)) / th**2 * K @ K


def rest_tips(theta: np.ndarray, h: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """The tip (3,) of the 1 m arm in its rest shape (no load) for turning angles ``theta`` (5, 2), in the
    rod's material convention: (PyElastica's discrete rod, each node turning by its share; gvsjax's
    continuum, a constant curvature share_k theta_k / l_k over each segment, integrated with steps ``h``).
    Their difference is the curvature mapping's alone."""
    from gvsjax.core.curvature_arm import SEGMENT_SHARE, SEGMENTS

    R, x, W, dl = np.eye(3), np.zeros(3), node_weights(), LENGTH / N_EL
    for j in range(N_EL):
        x = x + dl * R[:, 2]
        if j < N_EL - 1:
            R = R @ _rotation(np.append(W[j] @ theta, 0.0))
    discrete = x
    R, x, knots = np.eye(3), np.zeros(3), np.asarray(SEGMENTS) * LENGTH
    for i in range(int(round(LENGTH / h))):
        k = int(np.searchsorted(knots, (i + 0.5) * h)) - 1
        u = np.append(SEGMENT_SHARE[k] * theta[k] / (knots[k + 1] - knots[k]), 0.0) if 0 <= k < 5 else np.zeros(3)
        x = x + h * (R @ _rotation(0.5 * h * u))[:, 2]  # constant curvature: the mid-step tangent
        R = R @ _rotation(h * u)
    return discrete, x
