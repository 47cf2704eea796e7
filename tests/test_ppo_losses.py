"""PPO losses (gvsjax.ppo.losses): Gaussian log-probabilities and entropy, GAE, the clipped
surrogate and value losses against hand-computed numbers; invalid samples change nothing."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax.ppo.config import PPOConfig
from gvsjax.ppo.losses import (
    Batch,
    clipped_gaussian_log_prob,
    gae,
    gaussian_entropy,
    gaussian_log_prob,
    ppo_loss,
)
from gvsjax.ppo.networks import make_network

LOG_2PI = math.log(2 * math.pi)


# --- Gaussian ------------------------------------------------------------------


def test_gaussian_log_prob_matches_closed_form():
    mean = np.array([[0.5, -1.0], [0.0, 0.0]])
    log_std = np.array([[math.log(2.0), 0.0], [-1.0, 0.5]])
    action = np.array([[1.5, 0.0], [0.3, -0.2]])
    std = np.exp(log_std)
    expected = np.sum(
        -0.5 * ((action - mean) / std) ** 2 - np.log(std) - 0.5 * LOG_2PI, axis=-1
    )
    # first row by hand: z = (0.5, 1) -> -0.5*(0.25 + 1) - log 2 - log(2 pi)
    assert expected[0] == pytest.approx(-0.625 - math.log(2.0) - LOG_2PI)
    np.testing.assert_allclose(gaussian_log_prob(mean, log_std, action), expected, rtol=1e-6)


def test_clipped_log_prob_is_the_mass_beyond_a_bound_and_the_density_inside():
    phi = lambda x: 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))
    mean = np.array([[0.5, 0.5, 0.5]])
    log_std = np.zeros((1, 3))
    got = [float(clipped_gaussian_log_prob(mean[:, i:i + 1], log_std[:, i:i + 1], np.array([[a]]))[0])
           for i, a in enumerate((1.3, -2.0, 0.2))]
    assert got[0] == pytest.approx(math.log(1.0 - phi(0.5)), rel=1e-6)  # P(a >= 1), mean 0.5, std 1
    assert got[1] == pytest.approx(math.log(phi(-1.5)), rel=1e-6)  # P(a <= -1)
    assert got[2] == pytest.approx(-0.5 * 0.09 - 0.5 * LOG_2PI, rel=1e-6)  # the density inside


def test_clipped_log_prob_gradient_is_unbiased_with_less_variance():
    # d/dmu E[f(clip(a))], a ~ N(mu, sigma): score-function estimates with both log-probs
    # against the derivative of the expectation by quadrature (independent of both)
    mu, sigma = 1.1, 0.2  # a mean beyond the bound: most samples are clipped
    f = lambda x: (x - 0.3) ** 2
    grid = np.linspace(mu - 10 * sigma, mu + 10 * sigma, 200_001)

    def expectation(m):
        pdf = np.exp(-0.5 * ((grid - m) / sigma) ** 2) / (sigma * math.sqrt(2 * math.pi))
        return np.trapezoid(f(np.clip(grid, -1, 1)) * pdf, grid)

    exact = (expectation(mu + 1e-5) - expectation(mu - 1e-5)) / 2e-5
    a = mu + sigma * jax.random.normal(jax.random.PRNGKey(0), (400_000, 1), jnp.float64)
    reward = f(jnp.clip(a[:, 0], -1, 1))
    estimates = {}
    for name, logp in (("gaussian", gaussian_log_prob), ("clipped", clipped_gaussian_log_prob)):
        score = jax.vmap(jax.grad(lambda m, x, logp=logp: logp(m, jnp.log(sigma) * jnp.ones(1), x)))(
            jnp.full((a.shape[0], 1), mu), a)[:, 0]
        estimates[name] = np.asarray(reward * score)
    for name, est in estimates.items():
        err = abs(est.mean() - exact)
        assert err < 4 * est.std() / math.sqrt(len(est)), (name, est.mean(), exact)
    assert estimates["clipped"].std() < 0.75 * estimates["gaussian"].std()  # measured 0.69


def test_gaussian_entropy_matches_closed_form():
    log_std = np.array([[0.0, math.log(3.0)], [-2.0, 1.0]])
    # H = sum_i 0.5 * log(2 pi e sigma_i^2)
    expected = np.sum(0.5 * np.log(2 * math.pi * math.e * np.exp(2 * log_std)), axis=-1)
    np.testing.assert_allclose(gaussian_entropy(log_std), expected, rtol=1e-6)


# --- GAE -----------------------------------------------------------------------


def _gae_loop(rewards, values, dones, last_value, gamma, lam):
    """Textbook backward loop, one environment."""
    advantages = np.zeros(len(rewards))
    next_value, next_adv = last_value, 0.0
    for t in reversed(range(len(rewards))):
        not_done = 1.0 - dones[t]
        delta = rewards[t] + gamma * next_value * not_done - values[t]
        next_adv = delta + gamma * lam * not_done * next_adv
        advantages[t] = next_adv
        next_value = values[t]
    return advantages


def test_gae_three_steps_with_done_in_the_middle():
    rewards = np.array([1.0, 2.0, 3.0])
    values = np.array([0.5, 1.0, 1.5])
    dones = np.array([0.0, 1.0, 0.0])
    gamma, lam, last_value = 0.9, 0.8, 2.0
    # by hand: A2 = 3 + 0.9*2 - 1.5 = 3.3; A1 = 2 - 1 = 1 (episode ends);
    #          A0 = (1 + 0.9*1 - 0.5) + 0.9*0.8*1 = 2.12
    hand = np.array([2.12, 1.0, 3.3])
    np.testing.assert_allclose(_gae_loop(rewards, values, dones, last_value, gamma, lam), hand)

    adv, ret = gae(
        jnp.asarray(rewards)[:, None], jnp.asarray(values)[:, None],
        jnp.asarray(dones, bool)[:, None], jnp.array([last_value]), gamma, lam,
    )
    np.testing.assert_allclose(adv[:, 0], hand, rtol=1e-6)
    np.testing.assert_allclose(ret[:, 0], hand + values, rtol=1e-6)


def test_gae_batched_matches_loop():
    rng = np.random.default_rng(0)
    rewards, values = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    dones = rng.random((5, 3)) < 0.3
    last = rng.normal(size=3)
    adv, _ = gae(rewards, values, dones, last, 0.97, 0.9)
    for n in range(3):
        expected = _gae_loop(rewards[:, n], values[:, n], dones[:, n], last[n], 0.97, 0.9)
        np.testing.assert_allclose(adv[:, n], expected, rtol=1e-5, atol=1e-6)


def test_gae_single_step_episodes_is_reward_minus_value():
    rewards = jnp.array([[0.3, 0.9], [0.1, 0.5]])
    values = jnp.array([[0.2, 0.4], [0.6, 0.5]])
    dones = jnp.ones((2, 2), bool)
    adv, ret = gae(rewards, values, dones, jnp.array([7.0, -7.0]), 0.99, 0.95)
    np.testing.assert_allclose(adv, rewards - values, rtol=1e-6)
    np.testing.assert_allclose(ret, rewards, rtol=1e-6)


# --- clipped surrogate and value loss -----------------------------------------


def _toy_apply(params, obs):
    """mean = obs[:, 0] + m, log_std = 0, value = obs[:, 1] + v (A = 1)."""
    mean = obs[:, :1] + params["m"]
    return mean, jnp.zeros_like(mean), obs[:, 1] + params["v"]


TOY_PARAMS = {"m": jnp.zeros(()), "v": jnp.zeros(())}


def _toy_batch(ratios, advantages, values=None, targets=None, old_values=None, weight=None):
    """Batch whose new/old probability ratios are exactly ``ratios``."""
    b = len(ratios)
    obs = jnp.stack([jnp.zeros(b), jnp.asarray(values if values is not None else np.zeros(b))], 1)
    action = jnp.full((b, 1), 0.3)
    new_log_prob = gaussian_log_prob(obs[:, :1], jnp.zeros((b, 1)), action)
    return Batch(
        obs=obs,
        action=action,
        log_prob=new_log_prob - jnp.log(jnp.asarray(ratios)),
        value=jnp.asarray(old_values if old_values is not None else np.zeros(b)),
        advantage=jnp.asarray(advantages, jnp.float32),
        target=jnp.asarray(targets if targets is not None else np.zeros(b)),
        weight=jnp.asarray(weight if weight is not None else np.ones(b), jnp.float32),
    )


def test_clipped_surrogate_exact_numbers():
    ratios = [1.5, 1.5, 0.5, 0.5, 1.1]
    advantages = [1.0, -1.0, 1.0, -1.0, 2.0]
    # min(r A, clip(r, 0.8, 1.2) A):
    #   r=1.5,A=+1 -> 1.2 (clipped)   r=1.5,A=-1 -> -1.5 (unclipped, pessimistic)
    #   r=0.5,A=+1 -> 0.5             r=0.5,A=-1 -> -0.8 (clipped)   r=1.1,A=2 -> 2.2
    surrogate = np.array([1.2, -1.5, 0.5, -0.8, 2.2])
    loss, m = ppo_loss(
        TOY_PARAMS, _toy_apply, _toy_batch(ratios, advantages), 0.2, 0.0, 0.0, False
    )
    assert float(m["policy_loss"]) == pytest.approx(-surrogate.mean(), rel=1e-5)
    assert float(loss) == pytest.approx(-surrogate.mean(), rel=1e-5)
    assert float(m["clip_fraction"]) == pytest.approx(0.8)
    r = np.array(ratios)
    assert float(m["approx_kl"]) == pytest.approx(np.mean((r - 1) - np.log(r)), rel=1e-4)


def test_clipped_samples_give_no_policy_gradient():
    # both samples sit on the flat (clipped) side of the objective
    grad = jax.jit(jax.grad(lambda p, b: ppo_loss(p, _toy_apply, b, 0.2, 0.0, 0.0, False)[0]))
    grads = grad(TOY_PARAMS, _toy_batch([1.5, 0.5], [1.0, -1.0]))
    assert float(grads["m"]) == 0.0
    # inside the clip range the gradient is -A * d ratio / dm = -A * r * (a - mu)
    grads = grad(TOY_PARAMS, _toy_batch([1.1], [2.0]))
    assert float(grads["m"]) == pytest.approx(-2.0 * 1.1 * 0.3, rel=1e-5)


def test_value_loss_plain_and_clipped():
    kwargs = dict(values=[1.0, 2.0], targets=[0.0, 4.0], old_values=[0.9, 1.0])
    batch = _toy_batch([1.0, 1.0], [0.0, 0.0], **kwargs)
    loss, m = ppo_loss(TOY_PARAMS, _toy_apply, batch, 0.2, 0.5, 0.0, False)
    # 0.5 * mean((1-0)^2, (2-4)^2) = 1.25
    assert float(m["value_loss"]) == pytest.approx(1.25)
    assert float(loss) == pytest.approx(0.5 * 1.25)
    _, m = ppo_loss(TOY_PARAMS, _toy_apply, batch, 0.2, 0.5, 0.0, False, clip_value_loss=True)
    # clipped values: 0.9+0.1 = 1.0 and 1.0+0.2 = 1.2 -> losses 0.5 and 0.5*2.8^2 = 3.92;
    # elementwise max with (0.5, 2.0) -> mean(0.5, 3.92) = 2.21
    assert float(m["value_loss"]) == pytest.approx(2.21, rel=1e-5)


def test_entropy_bonus_enters_total_loss():
    batch = _toy_batch([1.0, 1.0], [0.0, 0.0])
    loss, m = ppo_loss(TOY_PARAMS, _toy_apply, batch, 0.2, 0.0, 0.1, False)
    entropy = 0.5 * (1 + LOG_2PI)  # log_std = 0, one action dim
    assert float(m["entropy"]) == pytest.approx(entropy, rel=1e-6)
    assert float(loss) == pytest.approx(-0.1 * entropy, rel=1e-6)


def test_invalid_sample_changes_nothing():
    config = PPOConfig(shared_hidden=(8,), num_envs=4, num_steps=1, num_minibatches=1)
    net = make_network(config, 2)
    params = jax.jit(net.init)(jax.random.PRNGKey(0), jnp.zeros(3))
    rng = np.random.default_rng(1)
    valid = Batch(
        obs=jnp.asarray(rng.normal(size=(3, 3)), jnp.float32),
        action=jnp.asarray(rng.normal(size=(3, 2)), jnp.float32),
        log_prob=jnp.asarray(rng.normal(size=3) - 2.0, jnp.float32),
        value=jnp.asarray(rng.normal(size=3), jnp.float32),
        advantage=jnp.asarray(rng.normal(size=3), jnp.float32),
        target=jnp.asarray(rng.normal(size=3), jnp.float32),
        weight=jnp.ones(3, jnp.float32),
    )
    # a diverged sample: NaN/inf everywhere, weight 0
    bad = Batch(
        obs=jnp.full((1, 3), jnp.nan), action=jnp.full((1, 2), jnp.inf),
        log_prob=jnp.full(1, jnp.nan), value=jnp.full(1, jnp.nan),
        advantage=jnp.full(1, 1e30), target=jnp.full(1, jnp.nan), weight=jnp.zeros(1),
    )
    mixed = jax.tree.map(lambda a, b: jnp.concatenate([a[:2], b, a[2:]]), valid, bad)

    @jax.jit
    def loss_and_grads(batch):
        fn = lambda p: ppo_loss(p, net.apply, batch, 0.2, 0.5, 0.01, True, True)
        return jax.value_and_grad(fn, has_aux=True)(params)

    (loss_a, m_a), g_a = loss_and_grads(valid)
    (loss_b, m_b), g_b = loss_and_grads(mixed)
    assert np.isfinite(float(loss_b))
    np.testing.assert_allclose(loss_b, loss_a, rtol=1e-6)
    for k in m_a:
        np.testing.assert_allclose(m_b[k], m_a[k], rtol=1e-5, atol=1e-7)
    jax.tree.map(lambda x, y: np.testing.assert_allclose(x, y, rtol=1e-5, atol=1e-7), g_b, g_a)
