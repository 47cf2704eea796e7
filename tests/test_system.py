"""Inputs inside the integrator: state feedback evaluated at every stage, and a sampled
controller held between samples (zero-order hold), against closed-form responses."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import expm

I_ZZ, MASS, COM = 0.01, 1.0, 0.5
J = I_ZZ + MASS * COM**2  # inertia about the joint
KP, KD, SET = 4.0, 0.5, 0.3


def link_robot() -> gv.Robot:
    body = gv.RigidLink(mass=MASS, inertia=(0.01, 0.01, I_ZZ), com=(COM, 0.0, 0.0), length=1.0,
                        joint=gv.Joint("revolute", (0.0, 0.0, 1.0)))
    return gv.Robot(links=(body,), gravity=0.0)


def pd(t, q, qd):
    return -KP * (q[0] - SET) - KD * qd[0]


def test_pd_feedback_follows_the_damped_oscillator():
    tr = gv.simulate(link_robot(), 2.0, 1e-3, joint_force=pd)
    wn, z = np.sqrt(KP / J), KD / (2 * np.sqrt(KP * J))
    wd = wn * np.sqrt(1 - z**2)
    t = np.asarray(tr.t)
    ref = SET - SET * np.exp(-z * wn * t) * (np.cos(wd * t) + z * wn / wd * np.sin(wd * t))
    np.testing.assert_allclose(np.asarray(tr.q[:, 0]), ref, atol=1e-9)
    np.testing.assert_allclose(np.asarray(tr.joint_force[:, 0]),
                               -KP * (np.asarray(tr.q[:, 0]) - SET) - KD * np.asarray(tr.qd[:, 0]), atol=1e-12)


@pytest.mark.parametrize("every", [1, 50])
def test_sampled_controller_matches_the_exact_zero_order_hold_discretisation(every):
    """x' = A x + B u with u = -K x + KP SET held over each period h: x_{k+1} = Ad x_k + Bd u_k,
    Ad, Bd from the matrix exponential (the classical ZOH discretisation)."""
    dt = 1e-3
    tr = gv.simulate(link_robot(), 1.0, dt, controller=lambda t, q, qd: {"joint_force": pd(t, q, qd)},
                     control_every=every)
    h = every * dt
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0], [1.0 / J]])
    aug = expm(np.block([[A, B], [np.zeros((1, 3))]]) * h)
    Ad, Bd = aug[:2, :2], aug[:2, 2:]
    x = np.zeros(2)
    states = [x]
    for _ in range(int(round(1.0 / h))):
        u = -KP * (x[0] - SET) - KD * x[1]
        x = Ad @ x + (Bd * u)[:, 0]
        states.append(x)
    states = np.array(states)
    got = np.stack([np.asarray(tr.q[::every, 0]), np.asarray(tr.qd[::every, 0])], 1)
    np.testing.assert_allclose(got, states, atol=1e-10)
    held = np.asarray(tr.joint_force[1:, 0]).reshape(-1, every)
    assert np.all(held == held[:, :1])  # constant over each period


def test_controller_gradient_and_batch():
    def final(kp):
        control = lambda t, q, qd: {"joint_force": -kp * (q[0] - SET) - KD * qd[0]}  # noqa: E731
        return gv.simulate(link_robot(), 0.5, n_steps=500, controller=control, control_every=20).q[-1, 0]

    kps = jnp.array([2.0, 4.0, 8.0])
    np.testing.assert_allclose(jax.jit(jax.vmap(final))(kps), [final(k) for k in kps], atol=1e-12)
    g = jax.grad(final)(4.0)
    fd = (final(4.0 + 1e-4) - final(4.0 - 1e-4)) / 2e-4
    np.testing.assert_allclose(g, fd, rtol=1e-5)


@pytest.mark.extended
def test_tendon_tension_of_the_state_is_recorded_at_each_saved_state():
    """The recorded tension is the law at the saved state (what was applied there)."""
    arm = gv.paper_arm(tendon_offset=0.025, gravity=0.0)
    law = lambda t, q, qd: 10.0 + 5.0 * jnp.tanh(20.0 * q[1])  # noqa: E731
    tr = gv.simulate(arm, 0.4, n_steps=200, tendon_force=law, integrator="ars443")
    np.testing.assert_allclose(np.asarray(tr.tendon_force[:, 0]), 10.0 + 5.0 * np.tanh(20.0 * np.asarray(tr.q[:, 1])),
                               atol=1e-12)
    assert np.ptp(np.asarray(tr.tendon_force[:, 0])) > 0.1


@pytest.mark.parametrize("kwargs, name", [
    (dict(joint_force=jnp.zeros(2)), "joint_force"),
    (dict(joint_force=lambda t, q: 0.0), "joint_force"),
    (dict(controller=lambda t, q, qd: {"tension": 1.0}, control_every=10), "controller"),
    (dict(controller=lambda t, q, qd: {"joint_force": 0.0}, control_every=7), "control_every"),
    (dict(controller=lambda t, q, qd: {"joint_force": 0.0}), "control_every"),
    (dict(controller=lambda t, q, qd: {"joint_force": 0.0}, control_every=10, joint_force=1.0), "joint_force"),
    (dict(control_every=10), "control_every"),
])
def test_bad_inputs_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        gv.simulate(link_robot(), 0.1, 1e-3, **kwargs)


def test_a_prescribed_motion_cannot_depend_on_the_state():
    arm = gv.paper_arm()
    with pytest.raises(ValueError, match="base_angle"):
        gv.simulate(arm, 0.1, 1e-3, base_angle=lambda t, q, qd: 0.0)
    with pytest.raises(ValueError, match="joint_force=.*no actuated joints"):
        gv.simulate(arm, 0.1, 1e-3, joint_force=1.0)  # its only joint is prescribed
