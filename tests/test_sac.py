"""gvsjax.sac: its pieces against closed forms, learning a bandit, the command line, resume."""

from __future__ import annotations

import csv
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from bandit_env import MATRIX, BanditEnv

from gvsjax import sac, train
from gvsjax.ppo import checkpoint
from gvsjax.sac import replay
from gvsjax.tasks import base


def test_config_names_the_parameter_and_its_range():
    for bad, match in ((dict(batch_size=0), "batch_size=0.*>= 1"), (dict(gamma=1.0), "gamma=1.0.*< 1"),
                       (dict(tau=0.0), "tau=0.0"), (dict(hidden=()), r"hidden=\(\).*positive integers"),
                       (dict(batch_size=64, buffer_size=32), "batch_size=64.*buffer_size=32"),
                       (dict(min_log_std=3.0), "min_log_std=3.0.*max_log_std"),
                       (dict(learning_rate=float("nan")), "learning_rate=nan"), (dict(layer_norm=1), "layer_norm=1")):
        with pytest.raises(ValueError, match=match):
            sac.SACConfig(**bad)
    with pytest.raises(ValueError, match="unknown SACConfig key"):
        sac.SACConfig().replace(num_minibatches=2)


def test_squashed_log_prob_is_the_change_of_variables():
    """log pi(a) = log N(u) - sum log(1 - tanh(u)^2), by the naive formula where it is accurate,
    and finite where the naive one is not (|u| large: tanh rounds to 1)."""
    key = jax.random.PRNGKey(0)
    mean = jnp.array([[0.3, -1.2, 0.0], [25.0, -30.0, 0.1]])
    log_std = jnp.array([[-0.5, 0.2, -1.0], [-3.0, -3.0, 0.0]])
    action, log_prob = sac.squashed_sample(mean, log_std, key)
    eps = jax.random.normal(key, mean.shape, mean.dtype)
    u = mean + jnp.exp(log_std) * eps
    naive = jnp.sum(-0.5 * eps**2 - log_std - 0.5 * math.log(2 * math.pi) - jnp.log1p(-jnp.tanh(u) ** 2), -1)
    np.testing.assert_allclose(log_prob[0], naive[0], rtol=1e-10)
    np.testing.assert_allclose(action, jnp.tanh(u))
    assert np.isfinite(log_prob[1]) and not np.isfinite(naive[1])
    # the mass of a [-1, 1] box: the density integrates to 1 (one dimension, by quadrature)
    a = np.linspace(-1 + 1e-9, 1 - 1e-9, 400_001)
    m, s = 0.4, 0.7
    u = np.arctanh(a)
    pdf = np.exp(-0.5 * ((u - m) / s) ** 2) / (s * math.sqrt(2 * math.pi)) / (1 - a**2)
    assert abs(np.trapezoid(pdf, a) - 1.0) < 1e-4


def test_replay_wraps_around_and_samples_only_what_it_holds():
    buf = replay.empty(5, 1, 1)
    batch = lambda v: replay.Transitions(*(jnp.full((3, k), v) if k else jnp.full((3,), v)  # noqa: E731
                                           for k in (1, 1, 0, 0, 1, 0)))
    buf = replay.add(buf, batch(1.0))
    assert int(buf.count) == 3 and int(buf.position) == 3
    assert set(np.asarray(replay.sample(buf, jax.random.PRNGKey(0), 200).reward)) == {1.0}
    buf = replay.add(buf, batch(2.0))  # 2 fill the end, 1 overwrites the oldest
    assert int(buf.count) == 5 and int(buf.position) == 1
    np.testing.assert_array_equal(buf.data.reward, [2.0, 1.0, 1.0, 2.0, 2.0])


class _Clock(BanditEnv):
    """The bandit with 3 steps per episode; ``time_limit`` as given."""

    def __init__(self, time_limit: bool):
        super().__init__(episode_length=3)
        self.time_limit = time_limit


@pytest.mark.parametrize("time_limit", [True, False])
def test_a_time_limit_is_bootstrapped_a_termination_is_not(time_limit):
    env = _Clock(time_limit)
    config = sac.SACConfig(num_envs=4, buffer_size=64, batch_size=8, hidden=(8,), learning_starts=10_000)
    state = sac.init(config, env, env.default_params(), jax.random.PRNGKey(1))
    for _ in range(3):
        state, _ = sac.iteration(config, env, env.default_params(), state)
    discount = np.asarray(state.buffer.data.discount[:12]).reshape(3, 4)
    np.testing.assert_array_equal(discount[:2], 1.0)
    np.testing.assert_array_equal(discount[2], 1.0 if time_limit else 0.0)
    # the stored next observation of the last step is that step's own (step index 3), not the reset's
    np.testing.assert_array_equal(np.asarray(state.buffer.data.next_obs[8:12, 2]), 3.0)
    np.testing.assert_array_equal(np.asarray(state.last_obs[:, 2]), 0.0)
    assert int(state.episodes) == 4


def test_td_target_is_the_closed_form():
    """r + gamma d min(Q1', Q2') at a' = pi(s'): with the critics' last layer zeroed to constants."""
    config = sac.SACConfig(hidden=(4,), layer_norm=False)
    critic = sac.make_critic(config)
    params = critic.init(jax.random.PRNGKey(0), jnp.zeros(2), jnp.zeros(1))
    p = params["params"]
    for i, c in enumerate((3.0, -1.5)):  # Q1 = 3, Q2 = -1.5 everywhere
        p[f"Dense_{i}"] = {"kernel": jnp.zeros_like(p[f"Dense_{i}"]["kernel"]),
                           "bias": jnp.full_like(p[f"Dense_{i}"]["bias"], c)}
    actor = sac.make_actor(config, 1)
    actor_params = actor.init(jax.random.PRNGKey(1), jnp.zeros(2))
    batch = replay.Transitions(obs=jnp.zeros((3, 2)), action=jnp.zeros((3, 1)), reward=jnp.array([1.0, 2.0, 0.5]),
                               discount=jnp.array([1.0, 0.0, 1.0]), next_obs=jnp.ones((3, 2)),
                               valid=jnp.array([1.0, 1.0, 0.0]))
    y = sac.td_target(actor.apply, critic.apply, actor_params, {"params": p}, jnp.asarray(0.2), batch,
                      jax.random.PRNGKey(2), 0.9, False)
    np.testing.assert_allclose(y, [1.0 - 0.9 * 1.5, 2.0, -0.9 * 1.5], rtol=1e-6)  # invalid: reward 0


def _policy_cost(config, state, env):
    targets = jax.random.uniform(jax.random.PRNGKey(7), (512, 2), minval=-1.0, maxval=1.0)
    action = sac.policy_action(state.params["actor"], sac.make_actor(config, 2).apply, targets)
    return float(jnp.mean(jnp.linalg.norm(action - targets @ jnp.asarray(MATRIX).T, axis=-1)))


def test_sac_learns_the_bandit_under_jit_and_its_losses_stay_finite_with_diverged_steps():
    """The bandit's optimum is a = M t; the initial policy misses it by ~0.5, the trained one by
    ~0.02 (seeds 0-2). Diverged steps (NaN reward) are stored but weigh nothing."""
    env = BanditEnv(invalid_prob=0.05)
    params = env.default_params()
    config = sac.SACConfig(num_envs=32, total_episodes=32 * 250, batch_size=128, buffer_size=20_000,
                           hidden=(64, 64), learning_starts=256, updates_per_iteration=2,
                           init_log_alpha=-3.0)  # rewards are <= 1: start with a temperature of that scale
    state = sac.init(config, env, params, jax.random.PRNGKey(0))
    before = _policy_cost(config, state, env)
    run = sac.make_update(config, env, params, updates_per_call=50)
    calls = []
    for _ in range(6):  # the sixth call is past the budget: skipped
        state, metrics = run(state)
        calls.append(jax.tree.map(np.asarray, metrics))
    metrics = {k: np.concatenate([c[k] for c in calls]) for k in calls[0]}
    ran = metrics["update"] >= 0
    assert int(state.update) == 250 and int(state.gradient_steps) == 2 * (250 - 7) and ran.sum() == 250
    for k in ("critic_loss", "actor_loss", "q", "alpha"):
        assert np.all(np.isfinite(metrics[k][ran])), k
    assert metrics["invalid_steps"][ran].sum() > 100  # ~5% of 8000 steps diverged
    after = _policy_cost(config, state, env)
    assert before > 0.3 and after < 0.05, (before, after)


@pytest.fixture
def bandit(monkeypatch):
    monkeypatch.setitem(base._REGISTRY, "bandit", BanditEnv)


SAC_RUN = ["task=bandit", "algo=sac", "num_envs=16", "batch_size=32", "buffer_size=4096", "hidden=16,16",
           "learning_starts=64", "progress=false", "eval_targets=0", "updates_per_call=8", "checkpoint_every=0"]


def _rows(path):
    with open(path) as f:
        return [{k: v for k, v in r.items() if k != "wall_s"} for r in csv.DictReader(f)]


def test_cli_trains_sac_resumes_bit_identically_and_loads_its_policy(bandit, tmp_path):
    whole, part = tmp_path / "whole", tmp_path / "part"
    assert train.main(SAC_RUN + [f"out={whole}", "total_episodes=640"]) == 0
    assert train.main(SAC_RUN + [f"out={part}", "total_episodes=320"]) == 0
    # resume: algo comes from the run folder; a SAC key is accepted, the fixed ones are not
    assert train.main(["task=bandit", f"out={part}", "resume=true", "total_episodes=640", "progress=false",
                       "eval_targets=0", "updates_per_call=8"]) == 0
    assert _rows(part / "metrics.csv") == _rows(whole / "metrics.csv")
    config, env, env_params, actor = checkpoint.load_policy(part)
    assert isinstance(config, sac.SACConfig) and config.hidden == (16, 16)
    policy = jax.jit(checkpoint.make_policy(config, env.action_size, actor))
    action = policy(jnp.zeros((5, env.obs_size)))
    assert action.shape == (5, 2) and bool(jnp.all(jnp.abs(action) <= 1.0))
    with pytest.raises(ValueError, match="hidden=.*cannot change on resume"):
        train.train(*train.parse_args(["task=bandit", f"out={part}", "resume=true", "hidden=8"]))
    # the evaluation (deterministic) is written beside the training's last 500 episodes (sampled actions)
    from gvsjax import evaluate

    summary = evaluate.evaluate_run(part, part, n_episodes=16, seed=3)
    last = _rows(part / "metrics.csv")[-1]
    assert "deterministic" in summary["what"] and "sampled" in summary["training"]["what"]
    assert int(float(last["train_window_episodes"])) == 500 and summary["training"]["at_episode"] == 640
    assert summary["training"]["discounted_return_start"] == pytest.approx(float(last["train_discounted_return_start"]))
    assert (part / "learning_curve.png").exists()


@pytest.mark.parametrize("args, words", [
    (["algo=sac", "num_minibatches=2"], ["num_minibatches", "ppo keys", "algo=sac"]),
    (["batch_size=64"], ["batch_size", "sac keys", "algo=ppo"]),
    (["algo=sac", "preset=paper"], ["preset='paper' is invalid with algo=sac"]),
    (["algo=dqn"], ["algo='dqn' is invalid", "ppo, sac"]),
    (["algo=sac", "tau=2"], ["tau=2.0 is invalid", "0 < tau <= 1"]),
])
def test_cli_errors_name_the_key(bandit, capsys, args, words):
    assert train.main(["task=bandit", *args, "progress=false"]) == 2
    err = capsys.readouterr().err
    assert all(w in err for w in words), err


def test_a_scored_failure_is_stored_terminal_and_learned_from_and_counted_over_its_length():
    """With a ``failure_reward`` (the benchmark tasks' -10) a diverged step is a terminal transition
    with that reward that weighs in the losses, and the logged returns count its episode."""
    from test_ppo_train import _ScoredFailures, expected_window

    env = _ScoredFailures(episode_length=3, invalid_prob=0.2)
    config = sac.SACConfig(num_envs=8, buffer_size=256, batch_size=8, hidden=(8,), learning_starts=10_000)
    state = sac.init(config, env, env.default_params(), jax.random.PRNGKey(1))
    step = jax.jit(lambda s: sac.iteration(config, env, env.default_params(), s))
    for _ in range(20):
        state, metrics = step(state)
    data = jax.tree.map(lambda x: np.asarray(x[:160]).reshape((20, 8) + x.shape[1:]), state.buffer.data)
    failed = data.reward == -10.0
    assert failed.any()
    assert np.all(data.discount[failed] == 0.0) and np.all(data.valid == 1.0)
    want = expected_window(data.reward, data.discount == 0.0)
    for k, v in want.items():
        assert float(metrics[k]) == pytest.approx(v, rel=1e-5), k
