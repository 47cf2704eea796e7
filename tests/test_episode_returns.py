"""The discounted returns training logs (gvsjax.utils.episode_returns) on a hand-made stream of episodes
with known answers, under jit; and the same returns of recorded episodes."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax.utils import episode_returns as er

GAMMA = 0.5  # weights (1 - g^l) / (1 - g) of l = 1, 2, 3: 1, 1.5, 1.75; g^(l-1): 1, 0.5, 0.25

# two environments, four steps: (reward, ended, failed, dropped) per env
STREAM = [([1.0, 2.0], [0, 0], [0, 0], [0, 0]),
          ([1.0, -10.0], [0, 1], [0, 1], [0, 0]),  # env 1: B = (2, -10) fails after 2 steps
          ([1.0, 5.0], [1, 0], [0, 0], [0, 1]),  # env 0: A = (1, 1, 1) ends; env 1's next is cut (forgotten)
          ([-10.0, 3.0], [1, 1], [1, 0], [0, 0])]  # env 0: C = (-10) fails at once; env 1: E = (3) ends
# per episode, in the order they end: (average, start, undiscounted, failed)
B = (-13.0 / 2, -3.0, -8.0, 1.0)  # (2 x 1 - 10 x 1.5) / 2: divided by its 2 steps, not the stream's 4
A = (4.25 / 3, 1.75, 3.0, 0.0)
C = (-10.0, -10.0, -10.0, 1.0)
E = (3.0, 3.0, 3.0, 0.0)


@jax.jit
def _run(stream, size):
    run, win = er.running(2), er.window(size.shape[0])

    def one(carry, s):
        r, ended, failed, dropped = s
        return er.track(*carry, r, ended > 0, failed > 0, dropped > 0, GAMMA), None

    (run, win), _ = jax.lax.scan(one, (run, win), stream)
    return run, win, er.window_metrics(win)


def _stream():
    return tuple(jnp.asarray([s[i] for s in STREAM], jnp.float32) for i in range(4))


@pytest.mark.parametrize("size, held", [(5, (B, A, C, E)), (3, (A, C, E))])
def test_the_window_holds_the_last_episodes_each_over_its_own_length(size, held):
    run, win, m = _run(_stream(), jnp.zeros(size))
    want = np.mean(np.array(held), axis=0)
    got = [m["train_discounted_return_average"], m["train_discounted_return_start"], m["train_return"],
           m["train_failed_fraction"]]
    np.testing.assert_allclose(np.asarray(got), want, rtol=1e-6)
    assert int(m["train_window_episodes"]) == len(held)
    assert np.all(np.asarray(run.steps) == 0) and np.all(np.asarray(run.average) == 0)  # both envs restarted


def test_more_episodes_than_the_window_at_once_keep_the_last():
    run, win = er.running(3), er.window(2)
    r = jnp.array([1.0, 2.0, 3.0])
    ended = jnp.ones(3, bool)
    run, win = jax.jit(er.track, static_argnums=6)(run, win, r, ended, ~ended, ~ended, GAMMA)
    m = er.window_metrics(win)
    assert float(m["train_return"]) == pytest.approx(2.5) and int(m["train_window_episodes"]) == 2


def test_an_empty_window_reports_nan():
    m = er.window_metrics(er.window(4))
    assert np.isnan(float(m["train_discounted_return_average"])) and int(m["train_window_episodes"]) == 0


def test_recorded_episodes_count_their_first_length_steps():
    rewards = np.array([[1.0, 1.0, 1.0], [2.0, -10.0, np.nan], [-10.0, np.nan, np.nan]])
    out = er.discounted_returns(rewards, np.array([3, 2, 1]), GAMMA)
    np.testing.assert_allclose(out["average"], [A[0], B[0], C[0]], rtol=1e-12)
    np.testing.assert_allclose(out["start"], [A[1], B[1], C[1]], rtol=1e-12)
    np.testing.assert_allclose(out["undiscounted"], [A[2], B[2], C[2]], rtol=1e-12)
