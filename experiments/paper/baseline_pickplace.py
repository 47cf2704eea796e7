"""Differentiable-physics baseline for pick and place: the best accuracy the model allows.

    python experiments/paper/baseline_pickplace.py [n_random=16] [out_dir=figures]

For a target pair, the four action numbers a = (theta_F1, T1, theta_F2, T2)
(in [-1, 1]) are optimised through the simulator (both 5 s steps, exactly the
env's ``pp.episode``) by Levenberg-Marquardt on the residual
r(a) = (tip_1 - target_1, tip_2 - target_2) in R^4: J = jacfwd(r) (4 forward
tangents through 2 x 60 ars443 steps, the task's integration), step (J^T J + mu I)^-1 J^T r with mu
adapted, a line search over step fractions (1, 1/2, 1/4, 0) and the box
enforced by clipping. Starts: the geometric guess theta_F = the target's
angle about the joint, with tensions 0, 15 and 30 N and +-0.15 rad on the
angle (9 starts per pair, solved in one batch). The best end per pair wins.

Solves the paper's pair (Table I) and ``n_random`` held-out reachable pairs
(these are reached exactly by some table action, so the solver should get
~0). Writes ``baseline_pickplace.json`` and prints a Table I-style line.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
from gvsjax.tasks import pickplace as pp

FRACTIONS = (1.0, 0.5, 0.25, 0.0)


def starts(targets: np.ndarray) -> np.ndarray:
    """(B, 9, 2, 2) start actions for targets (B, 2, 2)."""
    angle = np.arctan2(targets[..., 0], -targets[..., 1]) / np.pi  # (B, 2)
    out = []
    for da in (-0.15 / np.pi, 0.0, 0.15 / np.pi):
        for tension in (-1.0, 0.0, 1.0):
            a = np.stack([np.clip(angle + da, -1, 1), np.full_like(angle, tension)], -1)
            out.append(a)
    return np.stack(out, 1)


def make_solver(params: pp.PickPlaceParams, n_iters: int = 12):
    """Jitted ``solve(a0 (N, 2, 2), targets (N, 2, 2)) -> (a (N, 2, 2), distances (N, 2))``."""

    def residual(a_flat, target):
        _, tips = pp.episode_distances(params, a_flat.reshape(2, 2), target)
        return (tips - target).reshape(-1)

    def lm_step(carry, _):
        a, mu, target = carry
        r = residual(a, target)
        J = jax.jacfwd(residual)(a, target)
        step = -jnp.linalg.solve(J.T @ J + mu * jnp.eye(4), J.T @ r)
        trials = jnp.stack([jnp.clip(a + f * step, -1.0, 1.0) for f in FRACTIONS])
        cost = jax.vmap(lambda x: jnp.sum(residual(x, target) ** 2))(trials)
        cost = jnp.where(jnp.isfinite(cost), cost, jnp.inf)
        best = jnp.argmin(cost)
        mu = jnp.where(best == 0, mu / 3.0, mu * 4.0)  # full step accepted: trust it more
        return (trials[best], mu, target), None

    def one(a0, target):
        (a, _, _), _ = jax.lax.scan(lm_step, (a0.reshape(-1), 1e-3, target), None, length=n_iters)
        d, _ = pp.episode_distances(params, a.reshape(2, 2), target)
        return a.reshape(2, 2), d

    return jax.jit(jax.vmap(one))


def solve_pairs(params, targets: np.ndarray, n_iters: int = 12) -> dict:
    """Best actions (B, 2, 2), distances (B, 2) m and tips for target pairs (B, 2, 2)."""
    a0 = starts(targets)
    B, S = a0.shape[:2]
    solve = make_solver(params, n_iters)
    t0 = time.perf_counter()
    a, d = solve(jnp.asarray(a0.reshape(B * S, 2, 2)), jnp.asarray(np.repeat(targets, S, 0)))
    a, d = np.asarray(a).reshape(B, S, 2, 2), np.asarray(d).reshape(B, S, 2)
    total = np.where(np.isfinite(d.sum(-1)), d.sum(-1), np.inf)
    best = np.argmin(total, 1)
    a, d = a[np.arange(B), best], d[np.arange(B), best]
    _, tips = jax.jit(jax.vmap(lambda x, t: pp.episode_distances(params, x, t)))(
        jnp.asarray(a), jnp.asarray(targets))
    return {"actions": a, "distances": d, "tips": np.asarray(tips),
            "seconds": time.perf_counter() - t0}


def main(n_random: str = "16", out: str = "figures") -> None:
    if n_random in ("-h", "--help", "help"):
        print(__doc__.strip())
        return
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    params = pp.make_params()
    targets = np.concatenate([np.asarray(pp.PAPER_PAIR)[None],
                              pp.eval_targets(params, int(n_random), seed=5)])
    r = solve_pairs(params, targets)
    theta, tension = (np.asarray(x) for x in pp.action_to_physical(jnp.asarray(r["actions"]), params))
    print(f"solved {len(targets)} pairs x 9 starts in {r['seconds']:.1f} s (incl. compile)")
    print("paper pair (Table I), best the model allows:")
    print("        X_target  Y_target   X_tip    Y_tip   dist_cm  theta_F_deg  T_N")
    for k in range(2):
        t, p = targets[0, k], r["tips"][0, k]
        print(f"step {k + 1}  {t[0]:8.3f} {t[1]:8.3f} {p[0]:8.3f} {p[1]:8.3f} "
              f"{100 * r['distances'][0, k]:8.2f} {np.degrees(theta[0, k]):10.1f} {tension[0, k]:6.1f}")
    dr = r["distances"][1:]
    print(f"{len(dr)} reachable held-out pairs: max distance step 1 {100 * dr[:, 0].max():.3f} cm, "
          f"step 2 {100 * dr[:, 1].max():.3f} cm")
    result = {
        "method": "Levenberg-Marquardt through the simulator, 9 starts, 12 iterations",
        "seconds_incl_compile": r["seconds"],
        "paper_pair": {"targets": targets[0].tolist(), "tips": r["tips"][0].tolist(),
                       "distances_m": r["distances"][0].tolist(),
                       "theta_final_rad": theta[0].tolist(), "tension_N": tension[0].tolist()},
        "random_pairs": {"n": len(dr), "max_distance_m": dr.max(0).tolist(),
                         "median_distance_m": np.median(dr, 0).tolist()},
    }
    (out / "baseline_pickplace.json").write_text(json.dumps(result, indent=2))
    print("wrote", out / "baseline_pickplace.json")


if __name__ == "__main__":
    main(*sys.argv[1:])
