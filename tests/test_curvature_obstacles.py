"""The benchmark's obstacle tasks: the random capsules obey the published sampler's rules, the segment
distance matches a dense search, and obstacles_2d / obstacles_3d run under jit and vmap for several steps
with contact reported."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import gvsjax  # noqa: F401
from gvsjax.tasks import make
from gvsjax.tasks.curvature.layouts import BOX_HIGH, BOX_LOW, GAP, LENGTH, random_capsules, segment_distance


def test_segment_distance_matches_a_dense_search():
    rng = np.random.default_rng(0)
    s = np.linspace(0.0, 1.0, 801)
    for _ in range(10):
        p0, p1, q0, q1 = rng.normal(size=(4, 3))
        a = p0 + s[:, None] * (p1 - p0)
        b = q0 + s[:, None] * (q1 - q0)
        dense = np.min(np.linalg.norm(a[:, None] - b[None], axis=-1))
        got = float(segment_distance(*map(jnp.asarray, (p0, p1, q0, q1))))
        assert got <= dense + 1e-12 and got == pytest.approx(dense, abs=5e-3)


def test_random_capsules_follow_the_rules():
    ends = np.asarray(jax.jit(jax.vmap(random_capsules))(jax.random.split(jax.random.PRNGKey(3), 50)))
    assert ends.shape == (50, 8, 2, 3)
    np.testing.assert_allclose(np.linalg.norm(ends[:, :, 1] - ends[:, :, 0], axis=-1), LENGTH, rtol=1e-12)
    assert np.all(ends >= BOX_LOW - 1e-12) and np.all(ends <= BOX_HIGH + 1e-12)
    for layout in ends[:10]:
        for i in range(8):
            for j in range(i):
                assert float(segment_distance(*map(jnp.asarray, (*layout[i], *layout[j])))) >= GAP
    assert len({tuple(np.round(e[0, 0], 6)) for e in ends}) == 50  # every episode its own layout


# obstacles_3d's own compile runs in the extended tier: the default run covers its parts, the 3D arm
# (test_curvature_tasks), the capsules' sampler (above) and the obstacle task's step (obstacles_2d)
@pytest.mark.parametrize("name", ["obstacles_2d", pytest.param("obstacles_3d", marks=pytest.mark.extended)])
def test_obstacle_task_runs_under_jit_and_vmap(name):
    env = make(name)
    params = env.default_params()
    keys = jax.random.split(jax.random.PRNGKey(0), 2)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    assert obs.shape == (2, env.obs_size)
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    actions = jnp.stack([jnp.full(env.action_size, -1.0), jnp.zeros(env.action_size)])  # -1: towards +x
    for _ in range(3):
        obs, state, reward, done, info = step(keys, state, actions, params)
    assert bool(jnp.all(info["valid"])) and bool(jnp.all(jnp.isfinite(obs)))
    np.testing.assert_allclose(np.asarray(state.kappa[0]), -0.75)  # three steps of 0.25
    tip = np.asarray(state.node_p[:, -1])
    assert tip[0, 0] > 0.1 and abs(tip[1, 0]) < 1e-9  # bent towards the obstacles; the idle arm stays up
    if env.planar:
        np.testing.assert_allclose(tip[:, 1], 0.0, atol=1e-12)
        # curled hard towards the posts at (0.2, 0.12) and (0.4, 0.37), the arm touches them
        assert float(state.deepest[0]) > 0.0
