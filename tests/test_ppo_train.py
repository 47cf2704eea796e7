"""PPO training end to end on the test-only contextual bandit (tests/bandit_env.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from bandit_env import BanditEnv

from gvsjax.ppo import (
    PPOConfig,
    collect,
    finetune_start,
    init,
    make_network,
    make_train,
    make_update,
    num_updates,
    policy_action,
)

# Small, fast settings: 128 samples per update, large learning rates.
FAST = PPOConfig(
    num_envs=32,
    num_steps=4,
    num_minibatches=4,
    update_epochs=4,
    learning_rate=3e-3,
    clip_eps=0.2,
    ent_coef=0.0,
    shared_hidden=(32, 16),
    actor_hidden=(32, 16),
    critic_hidden=(32, 16),
    finetune_fraction=0.0,
)


def deterministic_cost(config, env, params, n=1024):
    """Mean ``info["cost"]`` of the clipped-mean policy over ``n`` fresh episodes' first steps."""
    env_params = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(123), n)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, env_params)
    action = policy_action(params, make_network(config, env.action_size).apply, obs)
    assert float(jnp.max(jnp.abs(action))) <= 1.0
    _, _, _, _, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, state, action, env_params)
    return float(jnp.mean(info["cost"]))


@pytest.mark.parametrize("network, std_mode", [("shared", "learned"), ("separate", "network")])
def test_network_output_shapes(network, std_mode):
    config = FAST.replace(network=network, std_mode=std_mode)
    net = make_network(config, 2)
    params = jax.jit(net.init)(jax.random.PRNGKey(0), jnp.zeros(5))
    mean, log_std, value = net.apply(params, jnp.ones((3, 4, 5)))
    assert mean.shape == (3, 4, 2) and log_std.shape == (3, 4, 2) and value.shape == (3, 4)
    assert mean.dtype == jnp.float32
    np.testing.assert_allclose(log_std, config.init_log_std, atol=0.2)
    assert float(jnp.max(jnp.abs(mean))) < 0.2  # 0.01-scaled mean head


def test_bandit_reward_rises_with_two_phases():
    env = BanditEnv()
    # 150 updates of 128 one-step episodes; the last 20% in phase 2.
    config = FAST.replace(
        total_episodes=150 * 128,
        finetune_fraction=0.2,
        finetune_learning_rate=3e-4,
        finetune_clip_eps=0.05,
    )
    n = num_updates(config, env.episode_length)
    assert n == 150 and finetune_start(config, env.episode_length) == 120
    state, metrics = make_train(config, env, env.default_params())(jax.random.PRNGKey(0))

    reward = np.asarray(metrics["episode_reward"])
    assert reward.shape == (n,)
    # Zero-mean policy with std e^-0.5: reward ~0.13. A learned linear map gets ~0.85.
    assert reward[-10:].mean() > reward[:5].mean() + 0.2
    assert np.asarray(metrics["episode_cost"])[-10:].mean() < 0.2
    # The zero-action policy's mean cost is E|M t| ~ 0.46; 0.1 requires the
    # map t -> M t to be learned to within ~20% (seeds 0-3 reach < 0.01).
    assert deterministic_cost(config, env, state.params) < 0.1

    # Phase schedule is traced: lr and clip switch at update 120, one compile.
    lr, clip = np.asarray(metrics["learning_rate"]), np.asarray(metrics["clip_eps"])
    np.testing.assert_allclose(lr[:120], 3e-3, rtol=1e-6)
    np.testing.assert_allclose(lr[120:], 3e-4, rtol=1e-6)
    np.testing.assert_allclose(clip[:120], 0.2, rtol=1e-6)
    np.testing.assert_allclose(clip[120:], 0.05, rtol=1e-6)
    np.testing.assert_array_equal(metrics["update"], np.arange(n))
    assert int(state.update) == n and int(state.episodes) == n * 128
    for key in ("loss", "policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction"):
        assert np.all(np.isfinite(metrics[key])), key


@pytest.fixture(scope="module")
def two_step_run():
    """2-step bandit, separate actor/critic with state-dependent std, 10% diverging steps."""
    env = BanditEnv(episode_length=2, invalid_prob=0.1)
    # num_steps=3 makes episodes straddle rollouts (bootstrapping from last_value).
    config = FAST.replace(
        network="separate", std_mode="network", num_steps=3, num_minibatches=3,
        total_episodes=150 * 48,
    )
    assert num_updates(config, 2) == 150
    state, metrics = make_train(config, env, env.default_params())(jax.random.PRNGKey(1))
    return config, state, jax.tree.map(np.asarray, metrics)


def test_two_step_episodes_with_separate_network(two_step_run):
    config, state, metrics = two_step_run
    # every finished episode is counted once: completed validly or cut by divergence
    ended = metrics["episodes_completed"].sum() + metrics["invalid_steps"].sum()
    assert int(state.episodes) == ended
    assert int(state.episodes) > 150 * 3 * 32 // 2  # early ends make episodes shorter
    reward = metrics["episode_reward"]  # sum of two per-step rewards, in (0, 2]
    assert reward[-10:].mean() > reward[:5].mean() + 0.4
    # zero-action cost is ~0.46; seeds 0-3 reach 0.04-0.14 with the std head
    assert deterministic_cost(config, BanditEnv(episode_length=2), state.params) < 0.2


def test_invalid_samples_are_excluded_from_training(two_step_run):
    # Diverged steps have NaN reward and cost; unmasked, a single NaN would
    # poison every parameter at the first update.
    config, state, metrics = two_step_run
    assert metrics["invalid_steps"].sum() > 0.05 * 150 * 3 * 32
    assert all(np.all(np.isfinite(x)) for x in jax.tree.leaves(state.params))
    for key in ("loss", "value_loss", "grad_norm", "approx_kl", "episode_reward", "episode_cost"):
        assert np.all(np.isfinite(metrics[key])), key


SMALL = FAST.replace(num_envs=8, num_steps=2, num_minibatches=2, total_episodes=112)


@pytest.fixture(scope="module")
def small_runs():
    """``vmap(make_train)`` over seeds (0, 1, 0); one compile shared by two tests."""
    env = BanditEnv()
    train = make_train(SMALL, env, env.default_params())
    keys = jnp.stack([jax.random.PRNGKey(0), jax.random.PRNGKey(1), jax.random.PRNGKey(0)])
    batched = jax.jit(jax.vmap(train))
    return batched, keys, batched(keys)


def test_make_train_vmaps_over_seeds_and_is_deterministic(small_runs):
    batched, keys, (state, metrics) = small_runs
    assert num_updates(SMALL, 1) == 7 and metrics["loss"].shape == (3, 7)

    # different seeds, different runs
    leaves = jax.tree.leaves(state.params)
    assert all(not np.allclose(x[0], x[1]) for x in leaves if x[0].size > 1)
    assert not np.allclose(metrics["episode_reward"][0], metrics["episode_reward"][1])
    # same seed, bit-identical runs: within one call and across calls
    for x in jax.tree.leaves((state, metrics)):
        np.testing.assert_array_equal(x[0], x[2])
    state_again, metrics_again = batched(keys)
    jax.tree.map(np.testing.assert_array_equal, (state_again, metrics_again), (state, metrics))


def test_make_update_chunks_match_make_train_and_stop_at_budget(small_runs):
    env = BanditEnv()
    n = num_updates(SMALL, 1)
    run = make_update(SMALL, env, env.default_params(), updates_per_call=3)
    state = jax.jit(lambda key: init(SMALL, env, env.default_params(), key))(jax.random.PRNGKey(0))
    chunks = []
    for _ in range(3):  # ceil(7 / 3); the last two scan iterations are skipped
        state, metrics = run(state)
        chunks.append(metrics)
    assert int(state.update) == n
    last = chunks[-1]
    np.testing.assert_array_equal(last["update"], [6, -1, -1])
    assert np.isfinite(last["loss"][0]) and np.all(np.isnan(last["loss"][1:]))

    # same trajectory as make_train with the same key (vmapped: equal up to
    # float reassociation)
    _, _, (full_state, full) = small_runs
    jax.tree.map(
        lambda a, b: np.testing.assert_allclose(a, b[0], rtol=1e-4, atol=1e-6),
        state.params, full_state.params,
    )
    stacked = np.concatenate([c["loss"] for c in chunks])[:n]
    np.testing.assert_allclose(stacked, full["loss"][0], rtol=1e-4, atol=1e-6)


def test_collect_marks_invalid_steps_terminal_with_zero_reward():
    env = BanditEnv(episode_length=2, invalid_prob=0.3)
    config = FAST.replace(num_envs=16, num_steps=6, num_minibatches=1)
    state = init(config, env, env.default_params(), jax.random.PRNGKey(0))
    _, traj = jax.jit(lambda s: collect(config, env, env.default_params(), s))(state)
    invalid = ~np.asarray(traj.valid)
    assert invalid.any() and (~invalid).any()
    assert np.all(np.asarray(traj.done)[invalid])
    assert np.all(np.asarray(traj.reward)[invalid] == 0.0)
    assert np.all(np.isfinite(traj.reward)) and np.all(np.isfinite(traj.obs))


def test_target_kl_stops_the_remaining_epochs():
    env = BanditEnv()
    env_params = env.default_params()
    state = init(FAST, env, env_params, jax.random.PRNGKey(0))

    def one(config):
        _, metrics = make_update(config, env, env_params)(state)
        return jax.tree.map(lambda x: np.asarray(x)[0], metrics)

    free = one(FAST)  # target_kl = inf: every epoch runs
    assert int(free["epochs_run"]) == FAST.update_epochs
    # a bound below the first epoch's own KL (> 0 once the first step moved the policy)
    tight = one(FAST.replace(target_kl=1e-12))
    assert int(tight["epochs_run"]) == 1
    assert float(tight["approx_kl"]) < float(free["approx_kl"])
    with pytest.raises(ValueError, match="target_kl"):
        FAST.replace(target_kl=0.0)


def test_policy_action_names_a_wrong_obs_width_and_a_missing_key():
    net = make_network(FAST, 2)
    params = net.init(jax.random.PRNGKey(0), jnp.zeros(5))
    assert policy_action(params, net.apply, jnp.zeros((3, 5))).shape == (3, 2)
    with pytest.raises(AssertionError, match=r"obs must be \(\.\.\., obs_size=5\)"):
        policy_action(params, net.apply, jnp.zeros((3, 4)))
    with pytest.raises(ValueError, match="key=None is invalid"):
        policy_action(params, net.apply, jnp.zeros(5), deterministic=False)


def _antithetic_batch(config, value_error):
    """A single-step bandit rollout as a Batch with advantage r - (V + value_error(obs))."""
    from gvsjax.ppo import Batch

    env = BanditEnv()
    state = init(config, env, env.default_params(), jax.random.PRNGKey(3))
    _, traj = jax.jit(lambda s: collect(config, env, env.default_params(), s))(state)
    flat = lambda x: x.reshape((-1,) + x.shape[2:])
    obs = flat(traj.obs)
    value = flat(traj.value) + value_error(obs)
    return state.params, Batch(obs=obs, action=flat(traj.action), log_prob=flat(traj.log_prob),
                               value=value, advantage=flat(traj.reward) - value,
                               target=flat(traj.reward), weight=jnp.ones(obs.shape[0]))


def test_antithetic_pairs_share_targets_mirror_noise_and_stay_in_one_minibatch():
    from gvsjax.ppo.train import _shuffle

    config = FAST.replace(antithetic=True, num_envs=16, num_steps=3, num_minibatches=4)
    env = BanditEnv()
    state = init(config, env, env.default_params(), jax.random.PRNGKey(0))
    _, traj = jax.jit(lambda s: collect(config, env, env.default_params(), s))(state)
    obs, action = np.asarray(traj.obs), np.asarray(traj.action)
    mean = np.asarray(make_network(config, 2).apply(state.params, traj.obs)[0])
    np.testing.assert_array_equal(obs[:, :8], obs[:, 8:])  # same targets, every step (auto-reset)
    assert len(np.unique(obs[:, :8].reshape(-1, 2), axis=0)) == 24  # but distinct pairs
    np.testing.assert_allclose(action[:, :8] - mean[:, :8], -(action[:, 8:] - mean[:, 8:]), atol=1e-6)
    # the shuffle moves pairs as units: flat index t*16 + i pairs with t*16 + i + 8
    index = jnp.arange(3 * 16)
    minibatches = np.asarray(_shuffle(config, jax.random.PRNGKey(1), index))
    assert minibatches.shape == (4, 12) and sorted(minibatches.ravel()) == list(range(48))
    for mb in minibatches:
        partner = np.where(mb % 16 < 8, mb + 8, mb - 8)
        assert set(partner) == set(mb)
    with pytest.raises(ValueError, match="num_envs=15"):
        FAST.replace(antithetic=True, num_envs=15, num_minibatches=1)
    with pytest.raises(ValueError, match="num_minibatches=4"):  # 4 divides 12 envs, not 6 pairs
        FAST.replace(antithetic=True, num_envs=12, num_steps=1, num_minibatches=4)


@pytest.mark.parametrize("antithetic", [True, False])
def test_antithetic_policy_gradient_ignores_the_critics_error(antithetic):
    # a state-dependent critic error e(s) shifts both advantages of a pair equally; with
    # mirrored noise its contribution to the mean's gradient cancels exactly (first epoch,
    # ratio 1, no normalisation), so only the log-std gradient may change
    from gvsjax.ppo import ppo_loss

    config = FAST.replace(antithetic=antithetic, num_envs=64, num_steps=1, num_minibatches=1)
    apply_fn = make_network(config, 2).apply

    def grads(value_error):
        params, batch = _antithetic_batch(config, value_error)
        return params, jax.grad(lambda p: ppo_loss(p, apply_fn, batch, 0.2, 0.0, 0.0, False)[0])(params)

    params, clean = grads(lambda o: 0.0)
    _, noisy = grads(lambda o: 0.3 * jnp.sin(3.0 * o[:, 0]) + 0.2 * o[:, 1])
    changed = jax.tree.map(lambda a, b: float(jnp.max(jnp.abs(a - b)) / (jnp.max(jnp.abs(a)) + 1e-12)),
                           clean, noisy)
    flat = {"/".join(str(k.key) for k in path): v
            for path, v in jax.tree_util.tree_flatten_with_path(changed)[0]}
    mean_and_trunk = {k: v for k, v in flat.items() if "log_std" not in k}
    assert mean_and_trunk and flat.keys() - mean_and_trunk.keys()  # both kinds present
    if antithetic:
        assert max(mean_and_trunk.values()) < 1e-4, mean_and_trunk
    else:
        assert max(mean_and_trunk.values()) > 0.05, mean_and_trunk


def test_adaptive_kl_lowers_the_rate_after_a_large_step_and_raises_it_after_a_small_one():
    from gvsjax.ppo.train import adapt_learning_rate

    np.testing.assert_allclose(adapt_learning_rate(jnp.float32(1e-3), 0.1, 0.01), 1e-3 / 1.5, rtol=1e-6)
    np.testing.assert_allclose(adapt_learning_rate(jnp.float32(1e-3), 0.001, 0.01), 1.5e-3, rtol=1e-6)
    np.testing.assert_allclose(adapt_learning_rate(jnp.float32(1e-3), 0.015, 0.01), 1e-3, rtol=1e-6)
    env = BanditEnv()
    env_params = env.default_params()
    config = FAST.replace(adaptive_kl=1e-9, total_episodes=32 * 4 * 3)  # every update's KL is above
    state = init(config, env, env_params, jax.random.PRNGKey(0))
    state, metrics = make_update(config, env, env_params, updates_per_call=3)(state)
    used = np.asarray(metrics["learning_rate"])
    np.testing.assert_allclose(used, FAST.learning_rate / 1.5 ** np.arange(3), rtol=1e-6)
    assert np.all(np.asarray(metrics["approx_kl"]) > 2e-9)
    # the rate never exceeds the phase's (annealed) rate, however small the KL
    config = FAST.replace(adaptive_kl=1e3, anneal_lr=True, total_episodes=32 * 4 * 3)
    state = init(config, env, env_params, jax.random.PRNGKey(0))
    _, metrics = make_update(config, env, env_params, updates_per_call=3)(state)
    np.testing.assert_allclose(np.asarray(metrics["learning_rate"]), FAST.learning_rate * (1 - np.arange(3) / 3),
                               rtol=1e-6)


@pytest.mark.parametrize("antithetic", [False, True])
def test_stagger_starts_cuts_each_first_episode_once_at_a_random_step(antithetic):
    length = 5
    env = BanditEnv(episode_length=length)
    config = FAST.replace(num_envs=64, num_steps=3 * length, num_minibatches=1, stagger_starts=True,
                          antithetic=antithetic)
    state = init(config, env, env.default_params(), jax.random.PRNGKey(0))
    new, traj = jax.jit(lambda s: collect(config, env, env.default_params(), s))(state)
    done, cut = np.asarray(traj.done), np.asarray(traj.cut)
    first_end = np.argmax(done, axis=0) + 1  # the first episode's length in each env
    assert np.array_equal(first_end, np.asarray(state.cut_at))
    assert set(first_end) == set(range(1, length + 1))  # every length, the full one included
    # the cut is flagged where the first episode ends short; later episodes run their full length
    assert np.array_equal(cut.sum(0), (first_end < length).astype(int))
    for i in range(config.num_envs):
        ends = np.flatnonzero(done[:, i]) + 1
        assert np.all(np.diff(ends) == length)
    # cut episodes do not count as finished ones
    assert int(new.episodes) == int(done.sum() - cut.sum())
    if antithetic:
        np.testing.assert_array_equal(first_end[:32], first_end[32:])
    # without the option no episode is cut
    plain = init(config.replace(stagger_starts=False), env, env.default_params(), jax.random.PRNGKey(0))
    _, traj = jax.jit(lambda s: collect(config.replace(stagger_starts=False), env, env.default_params(), s))(plain)
    assert not np.asarray(traj.cut).any() and np.all(np.flatnonzero(np.asarray(traj.done)[:, 0]) + 1 == [5, 10, 15])


class _ScoredFailures(BanditEnv):
    failure_reward = -10.0  # as the benchmark tasks': a failed step is learned from


def _episodes(rewards, ends):
    """Per env, the episodes of a time-major stream (T, N): (rewards, failed) of each one that ended."""
    out = []
    for n in range(rewards.shape[1]):
        current = []
        for t in range(rewards.shape[0]):
            current.append(rewards[t, n])
            if ends[t, n]:
                out.append((current, current[-1] == -10.0))
                current = []
    return out


def expected_window(rewards, ends, gamma=0.99):
    """The training metrics' means, computed episode by episode from the stream."""
    from gvsjax.utils.episode_returns import discounted_returns

    eps = _episodes(np.asarray(rewards), np.asarray(ends))
    lengths = np.array([len(r) for r, _ in eps])
    padded = np.zeros((len(eps), lengths.max()))
    for i, (r, _) in enumerate(eps):
        padded[i, :len(r)] = r
    out = discounted_returns(padded, lengths, gamma)
    return {"train_discounted_return_average": out["average"].mean(), "train_discounted_return_start":
            out["start"].mean(), "train_return": out["undiscounted"].mean(),
            "train_failed_fraction": np.mean([f for _, f in eps]), "train_window_episodes": len(eps)}


def test_a_scored_failure_is_terminal_learned_from_and_counted_over_its_length():
    env = _ScoredFailures(episode_length=3, invalid_prob=0.2)
    config = FAST.replace(num_envs=16, num_steps=12, num_minibatches=1)
    state = init(config, env, env.default_params(), jax.random.PRNGKey(0))
    state, traj = jax.jit(lambda s: collect(config, env, env.default_params(), s))(state)
    invalid = ~np.asarray(traj.valid)
    assert invalid.any() and (~invalid).any()
    assert np.all(np.asarray(traj.done)[invalid]) and np.all(np.asarray(traj.reward)[invalid] == -10.0)
    assert np.all(np.asarray(traj.learn))  # nothing masked out of the loss
    from gvsjax.utils.episode_returns import window_metrics

    got = jax.tree.map(float, window_metrics(state.window))
    want = expected_window(traj.reward, traj.done)
    assert 0 < want["train_failed_fraction"] < 1 and want["train_window_episodes"] < 500
    for k, v in want.items():
        assert got[k] == pytest.approx(v, rel=1e-5), k
