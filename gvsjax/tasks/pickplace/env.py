"""Pick and place (paper section IV-B): two 5 s steps, each aimed at a 2-D target.

Action (2,) in [-1, 1], clipped: theta_F = pi a_0 (rad) and the tension
T = 30 (a_1 + 1) / 2 N (a tendon pulls only); ``motion`` simulates the step.
Observation (9,): theta / pi, q1 / q_scale, q2 / q_scale, qd / qd_scale (3),
the current step's target (2), the step indicator (0 pick, 1 place). The
target is seen in polar form about the joint (``target_obs="polar"``,
default): its angle from the hanging direction / pi (the same measure as
theta / pi) and (|target| - 0.99 m) / 1 cm, with |target| clipped to the
table's radius band; ``"cartesian"`` gives (x, y) / 1 m instead. Polar,
because the angle the joint needs is nearly the target's angle, and its
range [-pi, pi] has a seam at the upright arm that in (x, y) the policy must
learn itself (it settled the seam on the wrong side for targets within ~50
deg of upright). Reward per step exp(-k d), k = 4.46 1/m (0.8 at 5 cm), d the
tip-to-target distance (m) at the end of the step. The episode ends after
step 2. A non-finite or out-of-bound state gives ``info["valid"] = False``,
``done`` and reward 0.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.robots import paper_arm
from gvsjax.tasks.base import (
    Box,
    Controller,
    Environment,
    EvalResult,
    Policy,
    bounded,
    policy_only,
    sanitize_action,
)
from gvsjax.tasks.pickplace import figures
from gvsjax.tasks.pickplace.motion import action_to_physical, reward_of, run_step
from gvsjax.tasks.pickplace.params import PAPER_PAIR, PickPlaceParams
from gvsjax.tasks.pickplace.targets import eval_targets, make_params, sample_targets
from gvsjax.utils import plots

# Divergence bounds on the end-of-step state: |q1|, |q2| <= 20 (= L / r: beyond it the
# curvature can exceed 1 / radius, the inner fibre would have negative length) and
# |qd| <= 100 (rad/s, 1/s); random-action episodes peak at 1.4 and 2.7.
Q_BOUND = 20.0
QD_BOUND = 100.0


@struct.dataclass
class PickPlaceState:
    q: jax.Array  # (3,) theta rad, q1, q2
    qd: jax.Array  # (3,)
    tension: jax.Array  # () N, tendon tension now
    step: jax.Array  # () int32, 0 before the pick, 1 before the place, 2 at the end
    targets: jax.Array  # (2, 2) m, pick and place targets


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


def error_summary(d: np.ndarray) -> dict[str, float]:
    """Statistics of distances (m); a diverged episode counts as infinite."""
    return {"median_m": float(np.median(d)), "p95_m": float(np.percentile(d, 95)),
            "max_m": float(np.max(d)), "mean_m": float(np.mean(d)),
            "within_2cm": float(np.mean(d < 0.02)), "within_5cm": float(np.mean(d < 0.05))}


class PickPlace(Environment):
    """The pick-and-place task."""

    name = "pickplace"
    accepts_controller = False  # an open-loop task: evaluated with a policy
    obs_size = 9
    action_size = 2
    episode_length = 2
    animation_keys = {"action": "0.5,0.6,-0.7,0.2", "fps": 8, "dpi": 80}
    # separate 128-32 ReLU actor and critic, as the paper
    ppo_defaults = dict(
        network="separate", actor_hidden=(128, 32), critic_hidden=(128, 32), activation="relu",
        num_envs=512, num_steps=2, num_minibatches=8, update_epochs=8, gamma=1.0, gae_lambda=1.0,
        learning_rate=1e-3, clip_eps=0.2, ent_coef=0.0, init_log_std=-1.0, anneal_lr=True,
        finetune_fraction=0.0, total_episodes=120_000,
    )

    def default_params(self) -> PickPlaceParams:
        """The paper's task with its target-pair table (``make_params()``)."""
        return make_params()

    def observation_space(self, params=None) -> Box:
        inf = np.inf
        return Box(np.array([-1.0, -inf, -inf, -inf, -inf, -inf, -1.0, -inf, 0.0]),
                   np.array([1.0, inf, inf, inf, inf, inf, 1.0, inf, 1.0]))

    def reset(self, key, params: PickPlaceParams):
        """A new episode on a random training pair (pick, place): ``(obs, state)``."""
        targets, _ = sample_targets(key, params)
        state = _reset_state(targets)
        return observe(state, params), state

    def reset_to(self, targets, params: PickPlaceParams):
        """Reset with given targets (2, 2) m (e.g. the paper's pair)."""
        state = _reset_state(jnp.asarray(targets, dtype=float))
        return observe(state, params), state

    def step(self, key, state: PickPlaceState, action, params: PickPlaceParams):
        """One 5 s motion towards the current target: ``(obs, state, reward, done, info)``."""
        action, finite = sanitize_action(action, self.action_size)
        theta_f, tension = action_to_physical(action, params)
        tr = run_step(params, state.q, state.qd, state.tension, theta_f, tension)
        q, qd, tip = tr.q[-1], tr.qd[-1], tr.tip[-1, :2]
        i = jnp.minimum(state.step, 1)
        d = jnp.sqrt(jnp.sum((tip - state.targets[i]) ** 2))
        valid = (finite & jnp.all(jnp.isfinite(q)) & bounded(q[1:], Q_BOUND)
                 & bounded(qd, QD_BOUND) & jnp.isfinite(d))
        reward = jnp.where(valid, reward_of(jnp.where(valid, d, 0.0), params), 0.0)
        new = dataclasses.replace(state, q=jnp.where(valid, q, 0.0), qd=jnp.where(valid, qd, 0.0),
                                  tension=tension, step=state.step + 1)
        done = (new.step >= self.episode_length) | ~valid
        info = {"distance": d, "theta_final": theta_f, "tension": tension,
                "tip_x": tip[0], "tip_y": tip[1], "valid": valid,
                "truncated": jnp.zeros((), bool)}
        return observe(new, params), new, reward, done, info

    # ------------------------------------------------------------------ evaluation

    def evaluate(self, params: PickPlaceParams, policy: Policy | Controller, n_episodes: int, seed: int) -> EvalResult:
        """The policy on ``n_episodes`` held-out target pairs, and on the paper's pair."""
        policy = policy_only(self, policy)
        targets = eval_targets(params, n_episodes, seed)
        run = jax.jit(lambda t: rollout(params, policy, t))
        acts, tips, d, valid = (np.asarray(x) for x in run(jnp.asarray(targets)))
        d = np.where(valid, d, np.inf)
        metrics = {"n_targets": n_episodes, "targets": "held-out table rows (reachable pairs)",
                   "valid_fraction": float(np.mean(valid)),
                   "step1": error_summary(d[:, 0]), "step2": error_summary(d[:, 1])}
        theta, tension = (np.asarray(x) for x in action_to_physical(jnp.asarray(acts), params))
        rows: dict[str, np.ndarray] = {}
        for k in range(2):
            s = k + 1
            rows.update({f"x{s}_target": targets[:, k, 0], f"y{s}_target": targets[:, k, 1],
                         f"x{s}_tip": tips[:, k, 0], f"y{s}_tip": tips[:, k, 1],
                         f"theta{s}_rad": theta[:, k], f"tension{s}_N": tension[:, k], f"d{s}_m": d[:, k]})
        paper = np.asarray(PAPER_PAIR)
        paper_actions = np.asarray(run(jnp.asarray(paper)[None])[0][0])
        return EvalResult(metrics=metrics, rows=rows,
                          extra={"distance": d, "paper_targets": paper, "paper_actions": paper_actions})

    def summary(self, metrics) -> str:
        return "\n".join(
            f"eval step {k} on {metrics['n_targets']} pairs: median {100 * r['median_m']:.2f} cm, "
            f"p95 {100 * r['p95_m']:.2f} cm, max {100 * r['max_m']:.2f} cm, <2 cm {100 * r['within_2cm']:.1f}%"
            for k, r in ((1, metrics["step1"]), (2, metrics["step2"])))

    def figures(self, params: PickPlaceParams, result: EvalResult, out: Path) -> list[Path]:
        """Error histograms of both steps and the episode on the paper's pair (Fig. 6)."""
        d = result.extra["distance"]
        paths = [plots.error_histogram(d[:, k], out / f"error_histogram_step{k + 1}.png",
                                       title=f"step {k + 1} distance") for k in range(2)]
        paths.append(figures.episode_figure(params, result.extra["paper_actions"], result.extra["paper_targets"],
                                            out / "episode_paper_pair.png"))
        return paths

    # ------------------------------------------------------------------ drawing

    def render(self, params: PickPlaceParams, state: PickPlaceState, last_action) -> np.ndarray:
        """The arm's backbone and both targets."""
        return plots.rgb_image(lambda ax: figures.draw_state(ax, params.arm, state.q, state.targets))

    def animate(self, path: Path, **keys: Any) -> Path:
        """An episode's GIF: key action = "a0,a1,a2,a3" (step 1 then step 2, each in [-1, 1]), fps, dpi."""
        k = {**self.animation_keys, **keys}
        try:
            action = np.reshape([float(x) for x in str(k["action"]).split(",")], (2, 2))
        except ValueError:
            raise ValueError(f"action={k['action']!r} must be 4 comma-separated numbers in [-1, 1]") from None
        params = PickPlaceParams(arm=paper_arm(tendon_offset=0.025))
        return figures.episode_gif(path, params, action, fps=k["fps"], dpi=k["dpi"])


def rollout(params: PickPlaceParams, policy: Policy, targets):
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
