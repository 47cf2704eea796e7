"""The benchmark arm twists freely in 3D, and its default control step (2 implicit steps per 0.1 s) stays
finite and accurate while it twists: under random bending-and-twist actions against 8 steps per 0.1 s.
With ``ars443`` (the mass matrix of the step's start in the implicit part only) the same episodes diverge
within a few control steps."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax.tasks import make
from gvsjax.tasks.curvature import control
from gvsjax.tasks.curvature.control import ArmControl

STEPS = 30  # 3 s
EPISODES = 6


def _tips(arm: ArmControl, actions) -> np.ndarray:
    """(episodes, STEPS, 3) tips under ``actions`` (episodes, STEPS, 15) through the task's control step."""
    return np.asarray(jax.jit(jax.vmap(lambda a: control.open_loop_tips(arm, a)))(actions))


@pytest.fixture(scope="module")
def twisting():
    """The ik_4d arm (its own default control step), episodes of actions held 0.5 s: the first half with
    twist actions, the rest bending only (the follow_target arm's dynamics: torsion without rest twist)."""
    arm = make("ik_4d").default_params().arm
    a = jax.random.uniform(jax.random.PRNGKey(7), (EPISODES, STEPS // 5, 15), minval=-1.0, maxval=1.0)
    actions = jnp.repeat(a, 5, axis=1).at[EPISODES // 2:, :, 10:].set(0.0)
    ref = _tips(dataclasses.replace(arm, n_substeps=8), actions)
    return arm, actions, ref


def test_3d_arm_twists_freely_without_a_twist_input():
    robot = gv.curvature_arm()
    assert robot.n_dofs == 21  # torsion and two bendings per link
    assert control.layout(robot) == (2, False)  # ten bending inputs, no rest twist
    assert gv.curvature_arm(planar=True).n_dofs == 7
    assert gv.curvature_arm(torsion=False).n_dofs == 14


@pytest.mark.parametrize("sim_dtype", ["float32"])
def test_twisting_arm_is_finite_and_accurate_at_two_steps(twisting, sim_dtype):
    arm, actions, ref = twisting
    assert arm.n_substeps == 2
    tips = _tips(dataclasses.replace(arm, sim_dtype=sim_dtype), actions)
    assert np.all(np.isfinite(tips))
    err = np.linalg.norm(tips - ref, axis=-1)
    assert np.median(err) < 1e-3 and err.max() < 1e-2, (np.median(err), err.max())
    assert np.abs(ref[:, -1, :2]).max() > 0.2  # the arm moved far from upright


def test_open_loop_tips_under_jit_vmap_and_grad():
    """The planar arm over two control steps: jit(vmap) equals the eager episodes, and the gradient of the
    last tip's x with respect to the actions agrees with central differences."""
    arm = ArmControl(robot=gv.curvature_arm(planar=True))
    actions = jnp.asarray(np.random.default_rng(3).uniform(-1, 1, (2, 2, 5)))
    batch = jax.jit(jax.vmap(lambda a: control.open_loop_tips(arm, a)))(actions)
    assert batch.shape == (2, 2, 3)
    np.testing.assert_allclose(batch[1], control.open_loop_tips(arm, actions[1]), rtol=1e-12, atol=1e-12)
    assert float(jnp.abs(batch[0, -1] - batch[1, -1]).max()) > 1e-3  # the episodes differ
    f = jax.jit(lambda a: control.open_loop_tips(arm, a)[-1, 0])
    g = jax.jit(jax.grad(lambda a: control.open_loop_tips(arm, a)[-1, 0]))(actions[0])
    h, e = 1e-5, jnp.zeros((2, 5)).at[0, 2].set(1.0)  # a first-step action, clipped nowhere
    fd = (f(actions[0] + h * e) - f(actions[0] - h * e)) / (2 * h)
    np.testing.assert_allclose(g[0, 2], fd, rtol=1e-5)
    assert abs(float(fd)) > 1e-4
