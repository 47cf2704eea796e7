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
    robot = arm.robot

    def episode(acts):
        def one(carry, a):
            q, qd, kappa, twist = carry
            new_kappa, new_twist = control.apply(arm, kappa, twist, a)
            tr = control.advance(arm, q, qd, control.rest_values(robot, kappa, twist),
                                 control.rest_values(robot, new_kappa, new_twist))
            return (tr.q[-1], tr.qd[-1], new_kappa, new_twist), tr.tip[-1]

        zero = jnp.zeros(robot.n_dofs)
        return jax.lax.scan(one, (zero, zero, jnp.zeros((5, 2)), jnp.zeros(5)), acts)[1]

    return np.asarray(jax.jit(jax.vmap(episode))(actions))


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
