"""Muscle actuation of the 3D arm tasks (``ArmParams.actuation = "muscle"``, ``track3d_muscle``):
the action map against ``gv.moment_map`` and the closed-form arc of a uniform bending moment,
the env under jit/vmap (one control step's generalized force is B u; a held action comes to
rest on the arc), and bad input refused before anything compiles."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import gvsjax as gv
from gvsjax.tasks import actuation, arm3d, make

E, R = 1e7, 0.05
EI = E * math.pi * R**4 / 4


@pytest.fixture(scope="module")
def env():
    return make("track3d_muscle")


def arc(kappa: float, direction) -> np.ndarray:
    """The tip of a 1 m rod standing along +z bent into one arc of curvature kappa towards ``direction``."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    return np.array([*(d * (1 - math.cos(kappa)) / kappa), math.sin(kappa) / kappa])


def test_muscle_actions_are_the_moment_map_towards_the_tendon_directions():
    robot = gv.soft_arm()
    A = actuation.muscle_map(robot)
    B = gv.moment_map(robot, n_points=6, components=("bend_y", "bend_z"))
    np.testing.assert_array_equal(A, np.concatenate([B[:, 6:], -B[:, :6]], 1))
    assert actuation.muscle_map(gv.soft_arm(youngs_modulus=5e6)) is A  # built once per strain basis
    arm = arm3d.ArmParams(actuation="muscle")
    assert arm3d.n_actions(arm) == 12 and arm3d.n_actions(arm3d.ArmParams()) == 4
    a = jnp.linspace(-1.5, 1.5, 12)  # beyond the box: clipped
    tension, strain_force = arm3d.actuate(a, arm)
    np.testing.assert_allclose(np.asarray(strain_force), A @ (arm.moment_max * np.clip(np.asarray(a), -1, 1)),
                               rtol=1e-14)
    assert tension.shape == (8,) and not np.any(np.asarray(tension))
    tension, strain_force = arm3d.actuate(jnp.array([1.0, -0.5, 0.0, 0.2]), arm3d.ArmParams())
    np.testing.assert_allclose(np.asarray(tension), [2000, 0, 0, 1000, 0, 400, 0, 0])
    assert not np.any(np.asarray(strain_force))


@pytest.mark.parametrize("a_y, a_z", [(0.5, 0.0), (0.0, -1.0), (0.6, 0.6)])
def test_uniform_muscle_action_bends_the_weightless_arm_into_the_closed_form_arc(a_y, a_z):
    """Equal moments at every control point are a uniform moment (the spline sums to one): the
    weightless arm's balance K q = B u is linear and gives the curvature moment_max |a| / EI all along,
    towards the section's (a_y, a_z) direction, world (x, y) at rest, as the tendons pull."""
    robot = gv.soft_arm(gravity=0.0)
    arm = arm3d.ArmParams(robot=robot, actuation="muscle")
    _, strain_force = arm3d.actuate(jnp.concatenate([jnp.full(6, a_y), jnp.full(6, a_z)]), arm)
    K = gv.dynamics.full_matrix(gv.stiffness_and_damping(robot)[0], robot.n_dofs)
    q = jnp.linalg.solve(K, strain_force)
    kappa = arm.moment_max * math.hypot(a_y, a_z) / EI
    R_tip, tip = gv.tip_frame(robot, q)
    np.testing.assert_allclose(np.asarray(tip), arc(kappa, (a_y, a_z)), atol=1e-12)
    assert abs(float(q[0])) < 1e-15  # no torsion


@pytest.mark.extended
def test_muscle_env_under_jit_and_vmap(env):
    P = env.default_params()
    assert P.arm.actuation == "muscle" and env.action_size == 12 and env.obs_size == make("track3d").obs_size + 8
    keys = jax.random.split(jax.random.PRNGKey(1), 3)
    obs, s = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, P)
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    up = jnp.concatenate([jnp.full(6, 0.5), jnp.zeros(6)])
    actions = jnp.stack([up, jnp.zeros(12), jnp.full(12, jnp.nan)])
    obs, s1, reward, done, info = step(keys, s, actions, P)
    assert np.asarray(info["valid"]).tolist() == [True, True, False]
    d = np.asarray(info["distance"])
    np.testing.assert_allclose(np.asarray(reward)[:2], np.exp(-P.k * d[:2]), rtol=1e-12)
    assert float(reward[2]) == 0 and not np.any(np.asarray(s1.tension))
    # one control step: the held generalized force is B u, the env's state that of the arm's own step
    ref = arm3d.advance(P.arm, s.q[0], s.qd[0], jnp.zeros(8),
                        strain_force=actuation.muscle_map(P.arm.robot) @ (P.arm.moment_max * up))
    np.testing.assert_allclose(np.asarray(s1.q[0]), np.asarray(ref.q[-1]), rtol=1e-12, atol=1e-14)
    assert float(s1.tip[0, 0]) > 0.01 and abs(float(s1.tip[0, 1])) < 1e-12  # towards world +x
    # weightless, the action held comes to rest on the arc of curvature moment_max / 2 / EI (the
    # Kelvin-Voigt damping leaves the first mode ~4% damped: 15 s)
    P0 = P.replace(arm=P.arm.replace(robot=gv.soft_arm(gravity=0.0)))
    _, s = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys[:1], P0)
    for _ in range(150):
        _, s, _, _, info = step(keys[:1], s, up[None], P0)
    assert bool(info["valid"][0])
    np.testing.assert_allclose(np.asarray(s.tip[0]), arc(P.arm.moment_max * 0.5 / EI, (1, 0)), atol=1e-3)


def test_bad_actuation_is_refused_before_compiling(env):
    with pytest.raises(ValueError, match=r"ArmParams.actuation='muscles' is invalid: expected one of \['tendon'"):
        arm3d.ArmParams(actuation="muscles")
    for bad in (0.0, -80.0, float("nan"), "80"):
        with pytest.raises(ValueError, match=r"ArmParams.moment_max=.* is invalid: expected a finite number > 0"):
            arm3d.ArmParams(actuation="muscle", moment_max=bad)
    with pytest.raises(ValueError, match="ArmParams.tension_max"):
        arm3d.ArmParams().replace(tension_max=-1.0)
    P = env.train_params("box")  # the default's arm without its target table (a minute to build)
    assert P.arm.actuation == "muscle" and P.targets == "box"
    tendon = P.replace(arm=arm3d.ArmParams())
    with pytest.raises(ValueError, match=r"track3d_muscle takes 12 actions, but ArmParams.actuation='tendon'"):
        env.reset(jax.random.PRNGKey(0), tendon)
    with pytest.raises(ValueError, match=r"track3d takes 4 actions, but ArmParams.actuation='muscle'"):
        make("track3d").reset(jax.random.PRNGKey(0), P)
    _, s = env.reset(jax.random.PRNGKey(0), P)
    with pytest.raises(ValueError, match=r"expected \(12,\)"):
        env.step(jax.random.PRNGKey(0), s, jnp.zeros(4), P)


def test_reach_pose_muscle_needs_a_table_of_muscle_actions():
    """The variant's table is built under muscle actions (12 per pose); a tendon table (4) is refused."""
    from gvsjax.tasks import reach_pose as rp

    env = make("reach_pose_muscle")
    assert env.action_size == 12 and env.obs_size == make("reach_pose").obs_size
    table = dict(position=jnp.zeros((3, 3)), axis=jnp.tile(jnp.array([0.0, 0.0, 1.0]), (3, 1)))
    muscle = arm3d.ArmParams(actuation="muscle")
    with pytest.raises(ValueError, match=r"the target table's actions have shape \(3, 4\); reach_pose_muscle takes 12"):
        env.reset(jax.random.PRNGKey(0), rp.ReachPoseParams(arm=muscle, action=jnp.zeros((3, 4)), **table))
    with pytest.raises(ValueError, match="reach_pose takes 4 actions, but ArmParams.actuation='muscle'"):
        make("reach_pose").reset(jax.random.PRNGKey(0), rp.ReachPoseParams(arm=muscle, action=jnp.zeros((3, 4)),
                                                                           **table))


@pytest.mark.extended
def test_reach_pose_muscle_targets_are_where_held_muscle_actions_settle():
    """The muscle table's poses (Newton's statics under each pose's 12 held moments) are where the
    env's dynamics come to rest (a minutes-long compile of the 3D statics with a strain force)."""
    from gvsjax.tasks import reach_pose as rp

    env = make("reach_pose_muscle")
    P = rp.make_params(4, 7, actuation="muscle")
    assert P.action.shape == (4, 12) and P.arm.actuation == "muscle"
    state = jax.vmap(rp.start, in_axes=(0, None))(jnp.arange(4), P)
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    keys = jax.random.split(jax.random.PRNGKey(0), 4)
    for _ in range(60):
        _, state, _, _, info = step(keys, state, P.action, P)
    assert np.all(np.asarray(info["valid"]))
    assert float(np.max(info["distance"])) < 2e-3 and float(np.max(info["angle_deg"])) < 0.2
