"""Discounted episode returns as ALF logs them, the metric of the soft-arm benchmark's published curves.

For an episode of L rewards r_1 .. r_L (L its actual length: a failed simulation ends it early):

* ``average``: (1/L) sum_l r_l (1 - gamma^l) / (1 - gamma), the discounted return-to-go averaged over
  the episode's start steps (ALF's ``AverageDiscountedReturnMetric``);
* ``start``: sum_l gamma^(l-1) r_l, from the first step (ALF's ``EpisodicStartAverageDiscountedReturnMetric``);
* ``undiscounted``: sum_l r_l (ALF's ``AverageReturnMetric``).

ALF averages each over its last ``max(10, number of environments)`` finished training episodes (500 in
the benchmark), whose actions were sampled from the policy. The learners keep the same window
(``Running``, ``Window``, ``track``); ``discounted_returns`` scores recorded episodes at once.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

WINDOW = 500  # finished training episodes the logged means cover (ALF's buffer at 500 environments)


def discounted_returns(rewards, lengths, gamma: float) -> dict[str, np.ndarray]:
    """The three returns of episodes whose rewards are ``rewards`` (n, T), each counted over its first
    ``lengths`` (n,) steps (later entries are ignored, whatever they hold). Per episode (n,)."""
    r = np.asarray(rewards, float)
    t = np.arange(r.shape[1])
    length = np.asarray(lengths)
    r = np.where(t[None, :] < length[:, None], r, 0.0)
    to_go = (1.0 - gamma ** (t + 1)) / (1.0 - gamma)
    return {"average": (r @ to_go) / np.maximum(length, 1), "start": r @ gamma**t, "undiscounted": r.sum(1)}


@struct.dataclass
class Running:
    """The returns so far of each running episode, (N,) per environment."""

    steps: jax.Array  # int32, rewards received so far
    average: jax.Array  # sum_l r_l (1 - gamma^l) / (1 - gamma) so far (not yet divided by L)
    start: jax.Array  # sum_l gamma^(l-1) r_l so far
    undiscounted: jax.Array


@struct.dataclass
class Window:
    """The last ``WINDOW`` finished episodes' returns (a ring; ``count`` slots hold data)."""

    average: jax.Array  # (W,) float32
    start: jax.Array
    undiscounted: jax.Array
    failed: jax.Array  # (W,) float32, 1 where a failed simulation ended the episode
    position: jax.Array  # int32, the next slot
    count: jax.Array  # int32


def running(n: int) -> Running:
    """No episode under way in ``n`` environments."""
    z = jnp.zeros((n,), jnp.float32)
    return Running(jnp.zeros((n,), jnp.int32), z, z, z)


def window(size: int = WINDOW) -> Window:
    """An empty window of ``size`` episodes."""
    z = jnp.zeros((size,), jnp.float32)
    return Window(z, z, z, z, jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32))


def track(run: Running, win: Window, reward: jax.Array, ended: jax.Array, failed: jax.Array, dropped: jax.Array,
          gamma: float) -> tuple[Running, Window]:
    """One step of every environment: add ``reward`` (N,) to the running returns; episodes with ``ended``
    (N,) go into the window (``failed`` marks those a failed simulation ended), those with ``dropped`` (cut
    short by the learner, not by the task) are forgotten. Both restart at zero. Jittable."""
    steps = run.steps + 1
    l = steps.astype(jnp.float32)
    r = reward.astype(jnp.float32)
    new = Running(steps, run.average + r * (1.0 - gamma**l) / (1.0 - gamma), run.start + r * gamma ** (l - 1.0),
                  run.undiscounted + r)
    win = _push(win, ended, {"average": new.average / l, "start": new.start, "undiscounted": new.undiscounted,
                             "failed": failed.astype(jnp.float32)})
    gone = ended | dropped
    return jax.tree.map(lambda x: jnp.where(gone, jnp.zeros_like(x), x), new), win


def _push(win: Window, ended: jax.Array, values: dict) -> Window:
    """``values`` of the ended episodes appended in environment order; past ``W`` the oldest go first."""
    size = win.average.shape[0]
    n_new = jnp.sum(ended, dtype=jnp.int32)
    rank = jnp.cumsum(ended, dtype=jnp.int32) - 1
    keep = ended & (rank >= n_new - size)  # more than W at once: their last W
    index = jnp.where(keep, (win.position + rank) % size, size)  # size: out of range, dropped
    put = {k: getattr(win, k).at[index].set(v, mode="drop") for k, v in values.items()}
    return Window(**put, position=(win.position + n_new) % size, count=jnp.minimum(win.count + n_new, size))


def window_metrics(win: Window) -> dict[str, jax.Array]:
    """The window's means (NaN before the first episode ends) and its episode count, as training logs them:
    ``train_discounted_return_average``, ``train_discounted_return_start``, ``train_return``,
    ``train_failed_fraction``, ``train_window_episodes``."""
    held = jnp.arange(win.average.shape[0]) < win.count
    mean = lambda x: jnp.where(win.count > 0, jnp.sum(jnp.where(held, x, 0.0)) / jnp.maximum(win.count, 1),  # noqa: E731
                               jnp.nan)
    return {"train_discounted_return_average": mean(win.average), "train_discounted_return_start": mean(win.start),
            "train_return": mean(win.undiscounted), "train_failed_fraction": mean(win.failed),
            "train_window_episodes": win.count}


TRAIN_KEYS = ("train_discounted_return_average", "train_discounted_return_start", "train_return",
              "train_failed_fraction")
"""The float metrics of ``window_metrics`` (NaN until an episode has ended)."""
