"""The PyElastica twins of the benchmark tasks (experiments/transfer/elastica_twins.py): the curvature mapping
against the closed-form shape of the discrete rod, and the observation against gvsjax's."""

import gvsjax  # noqa: F401, I001  (first: it configures JAX)
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

from gvsjax.core.curvature_arm import SEGMENT_SHARE
from gvsjax.tasks import make

pytest.importorskip("elastica", reason="PyElastica is in the bench extra (pip install -e '.[bench]')")
sys.path.insert(0, str(Path(__file__).parents[1] / "experiments" / "transfer"))
import elastica_twins as et  # noqa: E402  (a moved script must fail here, not skip)


def test_node_weights_are_the_benchmark_segments():
    W = et.node_weights()
    assert W.shape == (19, 5)
    np.testing.assert_allclose(W.sum(0), SEGMENT_SHARE)  # the last segment gets 3/4, as theirs
    assert W[0].sum() == 0.0  # node 1 carries no curvature
    assert [int(np.flatnonzero(W[:, k])[0]) + 1 for k in range(5)] == [2, 5, 9, 13, 17]


@pytest.fixture(scope="module")
def twin():
    """One ik_4d twin without gravity (its jitted target, reward and observation compile once)."""
    task = make("ik_4d")
    return et.ElasticaTwin(task, task.default_params(), gravity=0.0)


def test_observation_at_reset_is_gvsjax_observation(twin):
    """The same key gives the same target and, the arm straight at rest, gvsjax's observation (ik_4d's
    holds the tip frame, whose convention the twin converts)."""
    key = jax.random.PRNGKey(7)
    obs = twin.reset(key)
    assert obs.shape == (twin.task.obs_size,)
    ref = twin.task.observe(twin._reset(key), twin.params)  # gvsjax's reset state, observed by gvsjax
    np.testing.assert_allclose(obs, np.asarray(ref), atol=1e-12)


def test_static_bend_without_gravity_is_the_closed_form_polyline(twin):
    """Turning angles held without gravity: the rod settles into its rest shape, element j turned from
    vertical by the sum of the nodes' angles up to j, towards -x (direction 1)."""
    key = jax.random.PRNGKey(0)
    twin.reset(key)
    action = np.zeros(15)
    action[:10:2] = [1.0, 0.6, 1.0, -0.4, 0.8]  # direction 1 of each point; no twist
    for t in range(6):  # kappa = 0.3 x action in direction 1
        twin.step(jax.random.fold_in(key, t), action)
    for t in range(6, 21):  # held for 1.5 s: mode 1 decays at 3.8 /s
        twin.step(jax.random.fold_in(key, t), np.zeros(15))
    kappa = 0.3 * action[:10:2]
    np.testing.assert_allclose(np.asarray(twin.state.kappa)[:, 0], kappa, atol=1e-12)
    phi = np.concatenate([[0.0], np.cumsum(et.node_weights() @ kappa)])  # element angles from vertical
    x = np.concatenate([[0.0], np.cumsum(-0.05 * np.sin(phi))])
    z = np.concatenate([[0.0], np.cumsum(0.05 * np.cos(phi))])
    pos = twin.rod.position_collection[et.SWAP].T
    np.testing.assert_allclose(pos[:, 0], x, atol=1e-3)
    np.testing.assert_allclose(pos[:, 2], z, atol=1e-3)
    np.testing.assert_allclose(pos[:, 1], 0.0, atol=1e-9)
