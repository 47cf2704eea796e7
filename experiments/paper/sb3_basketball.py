"""Stable-Baselines3 PPO on the unchanged Gymnasium env ``gvsjax/Basketball-v0``.

    pip install torch stable-baselines3      # not gvsjax dependencies (CPU torch is enough)
    python experiments/paper/sb3_basketball.py                        # short demo: 20k throws
    python experiments/paper/sb3_basketball.py --timesteps 400000 --n-envs 16 --seed 1 --out runs/sb3/s1.json

SB3 builds its own vector of single ``gym.make`` envs (``make_vec_env``), so
this is exactly what a Gymnasium user gets; every env step is one jitted
throw. ``--vector`` instead hands SB3 the batched ``GvsjaxVectorEnv``
through a small adapter (``Sb3VecEnv`` below): one jitted call throws for
all ``n_envs`` at once, several times faster with 8 or more envs. The
trained policy is then evaluated like ``Basketball.evaluate``: its deterministic
action on ``n_targets`` held-out targets drawn with the keys
``split(PRNGKey(eval_seed), n_targets)`` (default seed 1_000_003, the
evaluation default, never used for training), the same metrics
(``gvsjax.tasks.basketball.miss_metrics``: success < 10 cm, within 1 cm, median, p95, ...).
Writes a results JSON (``--out``) with the wall times, episodes and metrics,
and ``eval_throws.csv`` beside it.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import gvsjax  # noqa: F401  (XLA flag and x64 before JAX starts)
import gvsjax.gym  # noqa: F401  (registers gvsjax/Basketball-v0)
from gvsjax.evaluate import write_rows
from gvsjax.tasks.basketball import miss_metrics as metrics


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--timesteps", type=int, default=20_000, help="training env steps (= throws)")
    p.add_argument("--seed", type=int, default=0, help="SB3 / env seed")
    p.add_argument("--n-envs", type=int, default=8, help="parallel envs (SB3 DummyVecEnv)")
    p.add_argument("--n-steps", type=int, default=128, help="PPO rollout length per env")
    p.add_argument("--batch-size", type=int, default=256, help="PPO minibatch size")
    p.add_argument("--learning-rate", type=float, default=1e-3, help="Adam learning rate")
    p.add_argument("--log-std-init", type=float, default=-0.5,
                   help="initial log std of the Gaussian policy (SB3's default 0 explores a lot "
                        "of the clipped [-1, 1] box; -0.5 is gvsjax.ppo's default)")
    p.add_argument("--max-seconds", type=float, default=float("inf"),
                   help="stop training after this much wall time (e.g. 10x gvsjax's time to a quality level)")
    p.add_argument("--net", choices=("paper", "sb3"), default="paper",
                   help="paper: the paper's layers 128-32-16 with ReLU (SB3 has no shared trunk, so "
                        "actor and critic get one each); sb3: SB3's default MlpPolicy (64-64 tanh)")
    p.add_argument("--n-targets", type=int, default=1000, help="held-out evaluation targets")
    p.add_argument("--eval-every", type=float, default=0.0,
                   help="also evaluate every this many seconds of training (0: only at the end); the "
                        "evaluations' own time is off the training clock and off --max-seconds")
    p.add_argument("--eval-seed", type=int, default=1_000_003, help="evaluation key seed")
    p.add_argument("--out", default="runs/sb3_basketball/result.json", help="results JSON path")
    p.add_argument("--vector", action="store_true",
                   help="step all envs in one jitted call (GvsjaxVectorEnv) instead of SB3's loop")
    args = p.parse_args(argv)
    for name in ("timesteps", "n_envs", "n_steps", "batch_size", "n_targets"):
        if getattr(args, name) < 1:
            p.error(f"--{name.replace('_', '-')}={getattr(args, name)} must be >= 1")
    if not args.max_seconds > 0:
        p.error(f"--max-seconds={args.max_seconds} must be > 0")
    if args.seed < 0 or args.eval_seed < 0:
        p.error("--seed and --eval-seed must be >= 0")
    return args


def sb3_vector_env(n_envs: int):
    """``gvsjax.gym.GvsjaxVectorEnv`` behind SB3's ``VecEnv`` interface (both autoreset
    on the same step; SB3 wants the terminal observation in each env's info)."""
    from stable_baselines3.common.vec_env import VecEnv

    class Sb3VecEnv(VecEnv):
        def __init__(self, venv):
            self.venv = venv
            super().__init__(venv.num_envs, venv.single_observation_space,
                             venv.single_action_space)
            self.episode_returns = []
            self._returns = np.zeros(venv.num_envs)
            self._lengths = np.zeros(venv.num_envs, int)

        def reset(self):
            seed = self._seeds[0]  # SB3's seed(s) sets s + i for env i, as Gymnasium does
            obs, _ = self.venv.reset(seed=seed)
            self._reset_seeds()
            self._returns[:], self._lengths[:] = 0.0, 0
            return obs

        def step_async(self, actions):
            self._actions = actions

        def step_wait(self):
            obs, reward, terminated, truncated, info = self.venv.step(self._actions)
            done = terminated | truncated
            self._returns += reward
            self._lengths += 1
            infos = [{} for _ in range(self.num_envs)]
            for i in np.flatnonzero(done):  # what SB3's Monitor and PPO read
                infos[i] = {"terminal_observation": info["final_obs"][i],
                            "TimeLimit.truncated": bool(truncated[i] and not terminated[i]),
                            "episode": {"r": float(self._returns[i]), "l": int(self._lengths[i])}}
                self.episode_returns.append(float(self._returns[i]))
            self._returns[done], self._lengths[done] = 0.0, 0
            return obs, reward.astype(np.float32), done, infos

        def close(self):
            self.venv.close()

        def get_attr(self, attr_name, indices=None):
            return [getattr(self.venv, attr_name)] * len(self._get_indices(indices))

        def set_attr(self, attr_name, value, indices=None):
            setattr(self.venv, attr_name, value)

        def env_method(self, method_name, *args, indices=None, **kwargs):
            raise NotImplementedError("the batched env has no per-env methods")

        def env_is_wrapped(self, wrapper_class, indices=None):
            return [False] * len(self._get_indices(indices))

    return Sb3VecEnv(gvsjax.gym.GvsjaxVectorEnv(n_envs, "basketball"))


def evaluate_policy(predict, env, env_params, n_targets: int, seed: int) -> dict[str, np.ndarray]:
    """Targets, T, delta and miss (m) of ``predict(obs) -> action`` on held-out targets.

    Same targets and keys as ``Basketball.evaluate`` (reset and step with
    ``split(PRNGKey(seed), n_targets)``), which needs a jittable policy and SB3's is
    torch; a diverged throw counts as an infinite miss.
    """
    keys = jax.random.split(jax.random.PRNGKey(seed), n_targets)
    obs, state = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, env_params)
    action = jnp.asarray(predict(np.asarray(obs, np.float32)), jnp.float64)
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    _, _, _, _, info = step(keys, state, action, env_params)
    miss = np.where(np.asarray(info["valid"]), np.asarray(info["cost"], float), np.inf)
    return {"target": np.asarray(state.target), "T": np.asarray(info["T"]),
            "delta": np.asarray(info["delta"]), "miss": miss}


def _wall_clock_limit(seconds: float):
    """An SB3 callback that ends ``learn`` once ``seconds`` of wall time have passed."""
    from stable_baselines3.common.callbacks import BaseCallback

    class WallClockLimit(BaseCallback):
        def _on_training_start(self) -> None:
            self.t0 = time.perf_counter()

        def _on_step(self) -> bool:
            return time.perf_counter() - self.t0 < seconds

    return WallClockLimit()


def _periodic_eval(every_s: float, evaluate, curve: list, limit_s: float):
    """An SB3 callback that evaluates the deterministic policy every ``every_s`` seconds of training
    and ends ``learn`` after ``limit_s``; the evaluations' own time is kept off the training clock
    (as in time_to_quality.py)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class PeriodicEval(BaseCallback):
        def _on_training_start(self) -> None:
            self.clock, self.last, self.next = 0.0, time.perf_counter(), every_s

        def _on_step(self) -> bool:
            now = time.perf_counter()
            self.clock += now - self.last
            if self.clock >= self.next:
                m = metrics(evaluate()["miss"])
                curve.append({"train_s": self.clock, "timesteps": int(self.num_timesteps),
                              **{k: float(v) for k, v in m.items()}})
                print(f"{self.clock:7.0f} s  <10cm {m['success_rate_10cm']:.3f}  <1cm {m['within_1cm']:.3f}",
                      flush=True)
                while self.next <= self.clock:  # one evaluation even if a step spanned several periods
                    self.next += every_s
            self.last = time.perf_counter()
            return self.clock < limit_s

    return PeriodicEval()


def main(argv=None) -> dict:
    args = parse_args(argv)
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    t0 = time.perf_counter()
    if args.vector:
        venv = sb3_vector_env(args.n_envs)
        venv.seed(args.seed)
    else:
        venv = make_vec_env("gvsjax/Basketball-v0", n_envs=args.n_envs, seed=args.seed)
    policy_kwargs: dict = {"log_std_init": args.log_std_init}
    if args.net == "paper":
        import torch

        policy_kwargs.update(net_arch=dict(pi=[128, 32, 16], vf=[128, 32, 16]), activation_fn=torch.nn.ReLU)
    model = PPO("MlpPolicy", venv, n_steps=args.n_steps, batch_size=args.batch_size,
                learning_rate=args.learning_rate, seed=args.seed, verbose=0, policy_kwargs=policy_kwargs)
    task = venv.venv if args.vector else venv.envs[0].unwrapped
    evaluate = lambda: evaluate_policy(lambda o: model.predict(o, deterministic=True)[0],  # noqa: E731
                                       task.task, task.env_params, args.n_targets, args.eval_seed)
    curve: list = []
    callbacks = ([_periodic_eval(args.eval_every, evaluate, curve, args.max_seconds)] if args.eval_every > 0
                 else [_wall_clock_limit(args.max_seconds)])
    t1 = time.perf_counter()
    model.learn(total_timesteps=args.timesteps, callback=callbacks)
    t2 = time.perf_counter()
    if args.vector:
        episodes = len(venv.episode_returns)
    else:
        episodes = sum(len(m.get_episode_rewards()) for m in venv.envs)
    r = evaluate_policy(lambda o: model.predict(o, deterministic=True)[0], task.task,
                        task.env_params, args.n_targets, args.eval_seed)
    t3 = time.perf_counter()
    result = {"task": "basketball", "agent": "stable-baselines3 PPO (MlpPolicy)",
              "env": "GvsjaxVectorEnv (one jitted call)" if args.vector else "make_vec_env (DummyVecEnv)",
              "seed": args.eval_seed, "train_seed": args.seed, "timesteps": int(model.num_timesteps),
              "episodes": int(episodes), "n_envs": args.n_envs, "n_steps": args.n_steps,
              "batch_size": args.batch_size, "learning_rate": args.learning_rate,
              "log_std_init": args.log_std_init, "net": args.net, "max_seconds": args.max_seconds,
              "setup_s": t1 - t0, "train_s": t2 - t1, "eval_s": t3 - t2, **metrics(r["miss"]),
              "curve": curve}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    write_rows(out.parent / "eval_throws.csv", {"target_x": r["target"][:, 0], "target_y": r["target"][:, 1],
                                                "T": r["T"], "delta": r["delta"], "miss_m": r["miss"]})
    print(f"trained {result['timesteps']} steps ({episodes} episodes) in {result['train_s']:.1f} s")
    print(task.task.summary(result))
    print(f"wrote {out} and {out.parent / 'eval_throws.csv'}")
    return result


if __name__ == "__main__":
    main()
