"""Pick and place (paper section IV-B): two 5 s steps, each aimed at a 2-D target.

Physics. The paper's arm with one tendon at 2.5 cm from the midline
(``gv.paper_arm(tendon_offset=0.025)``, q = (theta, q1, q2)), gravity on, no
ball. In each step of ``step_time`` = 5 s (``n_steps`` = 60 ``ars443`` steps: both
steps' end tips within 0.2 mm of 5000 RK4 steps; RK4 needs ~360 for stability) the base
angle moves from its current value theta_0 to the commanded theta_F on the
cycloidal profile of gvs-notes 9.6,

    theta(t) = theta_0 + (theta_F - theta_0) s(t / T_s),
    s(u) = u - sin(2 pi u) / (2 pi),

whose velocity (theta_F - theta_0)(1 - cos 2 pi u) / T_s is a sinusoid,
accelerating in the first half and decelerating in the second, with zero
velocity and acceleration at both ends. The tendon tension follows the same
smooth ramp s(u) from its value at the start of the step (0 N in step 1) to
the commanded one, so neither control jumps at a step boundary. Step 2
starts from step 1's end state (q, qd and the tension).

Action (2,) in [-1, 1], clipped: theta_F = pi a_0 (rad) and the tension
T = 30 (a_1 + 1) / 2 N (a tendon pulls only). Observation (9,):
theta / pi, q1 / q_scale, q2 / q_scale, qd / qd_scale (3), the current
step's target (2), the step indicator (0 pick, 1 place). The target is
normalised in polar form about the joint (``target_obs="polar"``, default):
its angle from the hanging direction / pi (the same measure as theta / pi,
in [-1, 1]) and (|target| - 0.99 m) / 1 cm, with |target| clipped to the
table's radius band (so a target off the band, like the paper's, is seen as
its projection onto the band's edge); ``"cartesian"`` gives
(x, y) / 1 m instead. Why polar: the angle the joint needs is nearly the
target's angle, and its range [-pi, pi] has a seam at the upright arm; in
(x, y) the policy must learn that jump itself, and in training it settled
the seam on the wrong side for targets within ~50 deg of upright (measured:
p95 error ~0.7-1.6 m after 40k episodes, against ~1.3 cm median).
Reward per step exp(-k d), k = 4.46 1/m (0.8 at d = 5 cm), d the distance
(m) from the tip to the step's target at the end of the step. The episode
ends after step 2. A non-finite state gives ``info["valid"] = False``,
``done`` and reward 0.

Reachable targets. The tendon moment is at most 30 N x 2.5 cm = 0.75 N m,
about 2 % of the gravity moment of a horizontal arm (38.5 N m, gvs-notes
doubt 6): the arm mostly hangs from its base angle and the tension trims
the tip by ~1-2 cm, mostly *along* the circle (like a small change of the
base angle). The reachable set is therefore a thin band hugging the 1 m
circle: 98.6-100 cm from the joint (the radius dips where the horizontal
arm sags), only 1.2 mm (median; max 1.6 mm) thick at a given angle
(measured on the default table). Targets off the band, such as the paper's
pair (94.9 and 97.8 cm from the joint), cannot be reached exactly: the
differentiable baseline's best is 4.05 and 1.56 cm.
At construction ``make_params`` simulates ``n_pairs`` random episodes
(actions uniform in [-1, 1]^2 for both steps, with the env's own
``run_step``) and stores the end-of-step tips: row i is a target pair
(pick, place) that the stored actions reach exactly (to float precision).
The last ``n_test`` rows are held out: ``split="test"`` (evaluation)
draws only from them, ``"train"`` only from the others. ``reset`` is a pure
table look-up: it never simulates.
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

PAPER_PAIR = ((0.884, -0.344), (-0.675, -0.707))  # m, Table I targets


@struct.dataclass
class PickPlaceParams:
    """Task parameters (SI units). The target tables are built by ``make_params``."""

    arm: Any  # gv.Robot pytree
    step_time: float = 5.0  # s, duration of one step
    angle_max: float = math.pi  # rad, theta_F = angle_max * a_0
    tension_max: float = 30.0  # N, T = tension_max * (a_1 + 1) / 2
    k: float = 4.46  # 1/m, reward exp(-k d)
    q_scale: float = 2.0  # obs: curvature coefficients q1, q2 / q_scale
    qd_scale: float = 1.0  # obs: rates (rad/s and 1/s) / qd_scale
    target_scale: float = 1.0  # m, obs ("cartesian"): target / target_scale
    radius_ref: float = 0.99  # m, obs ("polar"): (|target| - radius_ref) / radius_scale
    radius_scale: float = 0.01  # m
    radius_range: tuple = (0.0, math.inf)  # m, radii clipped to this (make_params: the table's band)
    # "polar": target as (angle from the hanging direction / pi, radial offset), so the
    # +-pi seam of the joint's range is in the input too; "cartesian": (x, y) / target_scale
    target_obs: str = struct.field(pytree_node=False, default="polar")
    n_steps: int = struct.field(pytree_node=False, default=60)  # integrator steps per 5 s step
    integrator: str = struct.field(pytree_node=False, default="ars443")  # see gvsjax.integrators
    sim_dtype: str = struct.field(pytree_node=False, default="float64")  # simulate's dtype (issue 4)
    split: str = struct.field(pytree_node=False, default="train")  # "train", "test" or "all"
    n_test: int = struct.field(pytree_node=False, default=0)  # held-out rows at the table's end
    # target tables, P rows (see module docstring); None in a bare PickPlaceParams(...),
    # whose step works but whose reset needs them
    pick: jax.Array | None = None  # (P, 2) m, tip at the end of step 1
    place: jax.Array | None = None  # (P, 2) m, tip at the end of step 2
    pick_action: jax.Array | None = None  # (P, 2) in [-1, 1]
    place_action: jax.Array | None = None  # (P, 2) in [-1, 1]


# For drawing (GIF, Fig. 6): 500 RK4 steps per 5 s step give smooth frames; the task's 60
# ars443 steps end within 0.2 mm of them.
DRAWING_INTEGRATION = dict(integrator="rk4", n_steps=500)


@struct.dataclass
class PickPlaceState:
    q: jax.Array  # (3,) theta rad, q1, q2
    qd: jax.Array  # (3,)
    tension: jax.Array  # () N, tendon tension now
    step: jax.Array  # () int32, 0 before the pick, 1 before the place, 2 at the end
    targets: jax.Array  # (2, 2) m, pick and place targets


# ----------------------------------------------------------------------------- physics


def action_to_physical(action, params: PickPlaceParams):
    """(..., 2) action in [-1, 1] (clipped) -> (theta_F rad, tension N)."""
    a = jnp.clip(action, -1.0, 1.0)
    return params.angle_max * a[..., 0], params.tension_max * (a[..., 1] + 1.0) / 2.0


def physical_to_action(theta_final, tension, params: PickPlaceParams):
    """Inverse of ``action_to_physical`` (no clipping)."""
    return jnp.stack([theta_final / params.angle_max,
                      2.0 * tension / params.tension_max - 1.0], axis=-1)


def cycloid(u):
    """s(u) = u - sin(2 pi u) / (2 pi): 0 -> 1 with s' = s'' = 0 at u = 0 and 1."""
    return u - jnp.sin(2.0 * jnp.pi * u) / (2.0 * jnp.pi)


def controls(theta0, theta_final, tension0, tension, step_time):
    """The step's laws t -> theta (rad) and t -> tension (N), t in [0, step_time]."""
    angle = lambda t: theta0 + (theta_final - theta0) * cycloid(t / step_time)
    pull = lambda t: tension0 + (tension - tension0) * cycloid(t / step_time)
    return angle, pull


def run_step(params: PickPlaceParams, q, qd, tension0, theta_final, tension, save_every=None):
    """Simulate one step from (q, qd, tension0): the ``gv.Trajectory`` (end state last).

    ``save_every`` defaults to ``n_steps`` (start and end states only).
    """
    dtype = params.sim_dtype
    cast = lambda x: jnp.asarray(x).astype(dtype)  # noqa: E731
    angle, pull = controls(cast(q[0]), cast(theta_final), cast(tension0), cast(tension), params.step_time)
    traj = gv.simulate(params.arm, params.step_time, n_steps=params.n_steps, base_angle=angle,
                       tendon_force=pull, q0=q, qd0=qd, save_every=save_every or params.n_steps,
                       integrator=params.integrator, check_stability=False, dtype=dtype)
    # back to float64: the env's state and tables stay float64 whatever the simulation ran in
    return jax.tree_util.tree_map(lambda x: x.astype(float), traj)


def episode(params: PickPlaceParams, actions, save_every=None):
    """Both steps from rest for actions (2, 2): the two trajectories."""
    theta1, t1 = action_to_physical(actions[0], params)
    theta2, t2 = action_to_physical(actions[1], params)
    zero = jnp.zeros(3)
    tr1 = run_step(params, zero, zero, 0.0, theta1, t1, save_every)
    tr2 = run_step(params, tr1.q[-1], tr1.qd[-1], t1, theta2, t2, save_every)
    return tr1, tr2


def episode_distances(params: PickPlaceParams, actions, targets):
    """(2,) tip-to-target distances (m) of both steps; differentiable in ``actions``."""
    tr1, tr2 = episode(params, actions)
    tips = jnp.stack([tr1.tip[-1, :2], tr2.tip[-1, :2]])
    return jnp.sqrt(jnp.sum((tips - targets) ** 2, -1) + 1e-30), tips


def reward_of(distance, params: PickPlaceParams):
    """Reward exp(-k d) of a tip-to-target distance d (m)."""
    return jnp.exp(-params.k * distance)


# ----------------------------------------------------------------------------- targets


def _tables(base: PickPlaceParams, n_pairs: int, seed: int, batch: int = 1024) -> dict:
    rng = np.random.default_rng(seed)
    acts = rng.uniform(-1.0, 1.0, (n_pairs, 2, 2))
    run = jax.jit(jax.vmap(lambda a: tuple(tr.tip[-1, :2] for tr in episode(base, a))))
    tips = [run(jnp.asarray(acts[i:i + batch])) for i in range(0, n_pairs, batch)]
    pick = np.concatenate([np.asarray(t[0]) for t in tips])
    place = np.concatenate([np.asarray(t[1]) for t in tips])
    if not (np.all(np.isfinite(pick)) and np.all(np.isfinite(place))):
        raise RuntimeError("pickplace: a table episode diverged; check the arm and n_steps")
    return dict(pick=pick, place=place, pick_action=acts[:, 0], place_action=acts[:, 1])


_CACHE: dict[tuple, dict] = {}  # tables of the default arm, per argument set


def make_params(n_pairs: int = 4096, n_test: int = 1024, seed: int = 0,
                **overrides) -> PickPlaceParams:
    """Params with target tables built (seconds the first time; cached for the default arm).

    ``overrides`` are fields of ``PickPlaceParams`` (e.g. ``n_steps``,
    ``split``, ``arm``); ``arm`` defaults to ``gv.paper_arm(tendon_offset=0.025)``.
    """
    unknown = sorted(set(overrides) - set(PickPlaceParams.__dataclass_fields__))
    if unknown:
        raise ValueError(f"unknown pickplace parameter(s) {unknown}; valid: "
                         f"{sorted(PickPlaceParams.__dataclass_fields__)}")
    if not 0 < n_test < n_pairs:
        raise ValueError(f"n_test={n_test} must be in (0, n_pairs={n_pairs})")
    if overrides.get("sim_dtype", "float64") not in ("float64", "float32"):
        raise ValueError(f"sim_dtype={overrides['sim_dtype']!r} is invalid; choose 'float64' or 'float32'")
    arm = overrides.pop("arm", None)
    base = PickPlaceParams(arm=arm if arm is not None else gv.paper_arm(tendon_offset=0.025),
                           n_test=n_test, **overrides)
    table_key = (n_pairs, seed, base.n_steps, base.integrator, base.step_time, base.angle_max, base.tension_max)
    exact = dataclasses.replace(base, sim_dtype="float64")  # the tables' targets: float64 whatever sim_dtype is
    if arm is not None:
        tables = _tables(exact, n_pairs, seed)
    else:
        if table_key not in _CACHE:
            _CACHE[table_key] = _tables(exact, n_pairs, seed)
        tables = _CACHE[table_key]
    radii = np.hypot(*np.concatenate([tables["pick"], tables["place"]]).T)
    band = overrides.get("radius_range", (float(radii.min()), float(radii.max())))
    arrays: dict[str, Any] = {k: jnp.asarray(v) for k, v in tables.items()}  # the table fields
    return dataclasses.replace(base, radius_range=band, **arrays)


def _table(x: jax.Array | None) -> jax.Array:
    if x is None:
        raise ValueError("params has no target tables (a bare PickPlaceParams); build it with "
                         "make_params() or the env's default_params()")
    return x


def row_range(params: PickPlaceParams) -> tuple[int, int]:
    """[lo, hi) rows of the table that ``reset`` draws from."""
    n = _table(params.pick).shape[0]
    return {"train": (0, n - params.n_test), "test": (n - params.n_test, n),
            "all": (0, n)}[params.split]


def sample_targets(key, params: PickPlaceParams):
    """A reachable (pick, place) pair (2, 2) m and its table row."""
    lo, hi = row_range(params)
    row = jax.random.randint(key, (), lo, hi)
    return jnp.stack([_table(params.pick)[row], _table(params.place)[row]]), row


# ----------------------------------------------------------------------------- env


def target_features(target, params: PickPlaceParams):
    """Target (..., 2) m -> its two observation entries (see ``target_obs``)."""
    if params.target_obs == "cartesian":
        return target / params.target_scale
    angle = jnp.arctan2(target[..., 0], -target[..., 1]) / jnp.pi  # 0 hanging, +-1 upright
    # an off-band (unreachable) target is seen as its projection onto the band's edge:
    # the policy never extrapolates in radius (the band is ~1.5 cm wide)
    r = jnp.clip(jnp.sqrt(jnp.sum(target**2, -1)), *params.radius_range)
    radius = (r - params.radius_ref) / params.radius_scale
    return jnp.stack([angle, radius], -1)


def observe(state: PickPlaceState, params: PickPlaceParams):
    """The (9,) observation of ``state`` (see the module docstring)."""
    i = jnp.minimum(state.step, 1)
    q = state.q / jnp.array([jnp.pi, params.q_scale, params.q_scale])
    return jnp.concatenate([q, state.qd / params.qd_scale, target_features(state.targets[i], params),
                            i[None].astype(q.dtype)])


def _reset_state(targets) -> PickPlaceState:
    return PickPlaceState(q=jnp.zeros(3), qd=jnp.zeros(3), tension=jnp.zeros(()),
                          step=jnp.zeros((), jnp.int32), targets=targets)


class PickPlace:
    """The pick-and-place task (functional env API of ``gvsjax.tasks.base``)."""

    name = "pickplace"
    obs_size = 9
    action_size = 2
    episode_length = 2

    def default_params(self) -> PickPlaceParams:
        """The paper's task with its target-pair table (``make_params()``)."""
        return make_params()

    def reset(self, key, params: PickPlaceParams):
        """A new episode on a random training pair (pick, place): ``(obs, state)``."""
        targets, _ = sample_targets(key, params)
        state = _reset_state(targets)
        return observe(state, params), state

    def reset_to(self, targets, params: PickPlaceParams):
        """Reset with given targets (2, 2) m (e.g. the paper's pair)."""
        state = _reset_state(jnp.asarray(targets, dtype=float))
        return observe(state, params), state

    def evaluate(self, config, params: PickPlaceParams, net_params, out, n_targets=1000, seed=1_000_003):
        """Task-specific evaluation hook (see the module-level ``evaluate``)."""
        return evaluate(config, params, net_params, out, n_targets, seed)

    # --- reliability (issue 6): divergence bounds on the end-of-step state. |q1|, |q2| <= 20
    # (= L / r: beyond it the curvature can exceed 1 / radius, the inner fibre would have
    # negative length) and |qd| <= 100 (rad/s, 1/s); 512 random-action episodes peak at
    # 1.4 and 2.7 (measured), so only a blowing-up integration crosses them.
    q_bound = 20.0
    qd_bound = 100.0

    def step(self, key, state: PickPlaceState, action, params: PickPlaceParams):
        """One 5 s motion towards the current target: ``(obs, state, reward, done, info)``."""
        action, finite = sanitize_action(action, self.action_size)  # NaN/inf -> 0, flagged invalid
        theta_f, tension = action_to_physical(action, params)
        tr = run_step(params, state.q, state.qd, state.tension, theta_f, tension)
        q, qd, tip = tr.q[-1], tr.qd[-1], tr.tip[-1, :2]
        i = jnp.minimum(state.step, 1)
        d = jnp.sqrt(jnp.sum((tip - state.targets[i]) ** 2))
        valid = (finite & jnp.all(jnp.isfinite(q)) & bounded(q[1:], self.q_bound)
                 & bounded(qd, self.qd_bound) & jnp.isfinite(d))
        # --- end reliability edit ---
        reward = jnp.where(valid, reward_of(jnp.where(valid, d, 0.0), params), 0.0)
        new = dataclasses.replace(state, q=jnp.where(valid, q, 0.0), qd=jnp.where(valid, qd, 0.0),
                                  tension=tension, step=state.step + 1)
        done = (new.step >= self.episode_length) | ~valid
        info = {"distance": d, "theta_final": theta_f, "tension": tension,
                "tip_x": tip[0], "tip_y": tip[1], "valid": valid,
                "truncated": jnp.zeros((), bool)}
        return observe(new, params), new, reward, done, info


# ----------------------------------------------------------------------------- evaluation


def eval_targets(params: PickPlaceParams, n: int, seed: int) -> np.ndarray:
    """(n, 2, 2) target pairs from the held-out rows (distinct while n <= n_test)."""
    n_rows = _table(params.pick).shape[0]
    lo = n_rows - params.n_test
    rng = np.random.default_rng(seed)
    rows = lo + (rng.permutation(params.n_test)[:n] if n <= params.n_test
                 else rng.integers(0, params.n_test, n))
    return np.stack([np.asarray(_table(params.pick))[rows], np.asarray(_table(params.place))[rows]], 1)


def rollout(params: PickPlaceParams, policy, targets):
    """Episodes for targets (n, 2, 2) with ``policy(obs (n, 9)) -> actions (n, 2)``.

    Returns actions (n, 2, 2), tips (n, 2, 2) m, distances (n, 2) m, valid (n, 2);
    axis 1 is the step. Jittable.
    """
    env = PickPlace()
    keys = jnp.zeros((targets.shape[0], 2), jnp.uint32)  # the env draws no randomness in step
    obs, state = jax.vmap(env.reset_to, in_axes=(0, None))(targets, params)
    out = []
    for _ in range(env.episode_length):
        action = policy(obs)
        obs, state, _, _, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, state, action, params)
        out.append((jnp.clip(action, -1, 1), jnp.stack([info["tip_x"], info["tip_y"]], -1),
                    info["distance"], info["valid"]))
    return tuple(jnp.stack(x, 1) for x in zip(*out))


def error_summary(d: np.ndarray) -> dict[str, float]:
    """Statistics of distances (m); a diverged episode counts as infinite."""
    return {"median_m": float(np.median(d)), "p95_m": float(np.percentile(d, 95)),
            "max_m": float(np.max(d)), "mean_m": float(np.mean(d)),
            "within_2cm": float(np.mean(d < 0.02)), "within_5cm": float(np.mean(d < 0.05))}


def evaluate(config, params: PickPlaceParams, net_params, out, n_targets: int = 1000,
             seed: int = 1_000_003) -> dict:
    """Deterministic policy on ``n_targets`` held-out pairs: eval.json, eval_episodes.csv,
    error_histogram_step1.png, error_histogram_step2.png in ``out``. Returns eval.json's dict."""
    import json
    from pathlib import Path

    from gvsjax import plots
    from gvsjax.ppo import make_network, policy_action

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    apply_fn = make_network(config, 2).apply
    policy = lambda obs: policy_action(net_params, apply_fn, obs.astype(jnp.float32)).astype(float)
    targets = eval_targets(params, n_targets, seed)
    acts, tips, d, valid = (np.asarray(x) for x in jax.jit(
        lambda t: rollout(params, policy, t))(jnp.asarray(targets)))
    d = np.where(valid, d, np.inf)
    result = {"task": "pickplace", "n_targets": n_targets, "seed": seed,
              "targets": "held-out table rows (reachable pairs)",
              "valid_fraction": float(np.mean(valid)),
              "step1": error_summary(d[:, 0]), "step2": error_summary(d[:, 1])}
    (out / "eval.json").write_text(json.dumps(result, indent=2))
    theta, tension = action_to_physical(jnp.asarray(acts), params)
    cols = ["x1_target", "y1_target", "x1_tip", "y1_tip", "theta1_rad", "tension1_N", "d1_m",
            "x2_target", "y2_target", "x2_tip", "y2_tip", "theta2_rad", "tension2_N", "d2_m"]
    rows = np.concatenate([np.concatenate([targets[:, k], tips[:, k], np.asarray(theta)[:, k, None],
                                           np.asarray(tension)[:, k, None], d[:, k, None]], 1)
                           for k in range(2)], 1)
    np.savetxt(out / "eval_episodes.csv", rows, delimiter=",", header=",".join(cols), comments="", fmt="%.6g")
    for k in range(2):
        plots.error_histogram(d[:, k], out / f"error_histogram_step{k + 1}.png")
    return result


def summary(result: dict) -> str:
    """One line per step of an ``evaluate`` result."""
    return "\n".join(
        f"eval step {k} on {result['n_targets']} pairs: median {100 * r['median_m']:.2f} cm, "
        f"p95 {100 * r['p95_m']:.2f} cm, max {100 * r['max_m']:.2f} cm, <2 cm {100 * r['within_2cm']:.1f}%"
        for k, r in ((1, result["step1"]), (2, result["step2"])))


def default_ppo_config():
    """PPOConfig tuned for this task (separate 128-32 ReLU actor and critic, as the paper)."""
    from gvsjax.ppo import PPOConfig

    return PPOConfig(**PPO_DEFAULTS)


# the overrides train.py's TASK_DEFAULTS["pickplace"] should hold (see README)
PPO_DEFAULTS: dict[str, Any] = dict(
    network="separate", actor_hidden=(128, 32), critic_hidden=(128, 32), activation="relu",
    num_envs=512, num_steps=2, num_minibatches=8, update_epochs=8, gamma=1.0, gae_lambda=1.0,
    learning_rate=1e-3, clip_eps=0.2, ent_coef=0.0, init_log_std=-1.0, anneal_lr=True,
    finetune_fraction=0.0, total_episodes=120_000,
)


register("pickplace", PickPlace)
