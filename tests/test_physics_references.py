"""The simulator against independent references: closed-form beam frequencies, the classic
elastica, energy balance (conserved without damping, never increasing with it), the tendon's
circular arc and the design notes' independently computed release state."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import jax
import jax.numpy as jnp
import numpy as np
import pytest

EI = 5e6 * np.pi * 0.05**4 / 4  # paper arm bending stiffness, N m^2
RHO_A = 1000 * np.pi * 0.05**2  # kg/m
OMEGA_UNIT = np.sqrt(EI / RHO_A)  # 1/s for L = 1 m


def dominant_frequency(signal: np.ndarray, dt: float, guess: float) -> float:
    """Frequency (rad/s) of the strongest component near ``guess``: the peak of
    the Hann-windowed DTFT, refined by golden-section search (no FFT-bin error)."""
    x = (signal - signal.mean()) * np.hanning(len(signal))
    t = np.arange(len(signal)) * dt

    def power(w):
        return -abs(np.sum(x * np.exp(-1j * w * t)))

    lo, hi = 0.7 * guess, 1.3 * guess
    grid = np.linspace(lo, hi, 400)
    k = int(np.argmin([power(w) for w in grid]))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    g = (np.sqrt(5) - 1) / 2
    for _ in range(80):
        c, d = b - g * (b - a), a + g * (b - a)
        if power(c) < power(d):
            b = d
        else:
            a = c
    return (a + b) / 2


@pytest.mark.parametrize(
    "n_modes, basis, expected, rtol",
    [
        (2, "monomial", 3.532732 * OMEGA_UNIT, 5e-3),  # Rayleigh-Ritz, linear curvature
        pytest.param(4, "legendre", 1.8751041**2 * OMEGA_UNIT, 5e-3,  # Euler-Bernoulli, clamped-free
                     marks=pytest.mark.extended),
    ],
)
def test_free_vibration_first_frequency(n_modes, basis, expected, rtol):
    arm = gv.paper_arm(gravity=0.0, damping=0.0, n_modes=n_modes, basis=basis)
    qd0 = np.zeros(n_modes + 1)
    qd0[1] = 0.01  # small curvature rate: linear regime
    dt, duration = 1e-3, 30.0
    traj = gv.simulate(arm, duration, dt, qd0=qd0, save_every=5)
    omega = dominant_frequency(np.asarray(traj.tip[:, 0]), 5 * dt, expected)
    assert omega == pytest.approx(expected, rel=rtol)


@pytest.mark.parametrize("n_modes", [2, pytest.param(4, marks=pytest.mark.extended)])
def test_large_deflection_cantilever_matches_elastica(n_modes):
    # horizontal cantilever, dead tip load P L^2/EI = 1, gravity off, damped to rest
    arm = gv.paper_arm(gravity=0.0, tip_force=EI, n_modes=n_modes, basis="legendre")
    traj = gv.simulate(arm, 25.0, 5e-3, base_angle=lambda t: jnp.pi / 2, integrator="imex",
                       save_every=5000)
    tip, vel = np.asarray(traj.tip[-1]), np.asarray(traj.tip_velocity[-1])
    assert np.linalg.norm(vel) < 1e-6  # at rest
    drop, reach = -tip[1], tip[0]
    if n_modes >= 4:  # classic elastica (Bisshopp-Drucker): 0.30172 L and 0.94357 L
        assert drop == pytest.approx(0.30172, rel=5e-3)
        assert reach == pytest.approx(1 - 0.05643, rel=5e-3)
    else:  # the 2-mode truncation, independently computed in the design notes
        assert drop == pytest.approx(0.30166, abs=2e-4)
        assert reach == pytest.approx(1 - 0.05649, abs=2e-4)


def test_energy_conserved_without_damping():
    arm = gv.paper_arm(damping=0.0, tip_force=5.886)
    qd0 = np.array([0.0, 1.5, -2.0])
    traj = gv.simulate(arm, 10.0, 2e-3, qd0=qd0, save_every=10)
    e = jax.vmap(lambda q, v: gv.energy(arm, q, v))(traj.q, traj.qd)
    total = np.asarray(e["kinetic"] + e["elastic"] + e["gravity"] + e["loads"])
    scale = float(e["kinetic"][0] + e["elastic"][0]) + 1.0
    assert np.max(np.abs(total - total[0])) / abs(total[0]) < 1e-3
    assert np.max(np.abs(total - total[0])) / scale < 1e-3


def test_energy_never_increases_with_damping():
    arm = gv.paper_arm(tip_force=5.886)
    traj = gv.simulate(arm, 5.0, 2e-3, qd0=np.array([0.0, 3.0, -4.0]), save_every=5)
    e = jax.vmap(lambda q, v: gv.energy(arm, q, v))(traj.q, traj.qd)
    total = np.asarray(e["kinetic"] + e["elastic"] + e["gravity"] + e["loads"])
    assert np.all(np.diff(total) <= 1e-9 * np.abs(total).max())
    assert total[-1] < total[0] - 0.1  # and it does dissipate


def test_tendon_bends_free_arm_into_circular_arc():
    tension, d = 30.0, 0.025
    arm = gv.paper_arm(gravity=0.0, tendon_offset=d)
    traj = gv.simulate(arm, 25.0, 5e-3, tendon_force=tension, integrator="imex", save_every=5000)
    kappa = tension * d / EI
    q = np.asarray(traj.q[-1])
    np.testing.assert_allclose(q[1:], [kappa, 0.0], atol=1e-9)
    # a circular arc from the origin, hanging along -y and bending towards +x
    tip = np.asarray(traj.tip[-1])
    np.testing.assert_allclose(tip[:2], [(1 - np.cos(kappa)) / kappa, -np.sin(kappa) / kappa], atol=1e-9)


def test_reference_release_state_of_fast_throw():
    """Values from the design notes' independent implementation (RK4 at 0.1 ms)."""
    arm = gv.paper_arm(tip_force=5.886)
    theta_f, T = np.deg2rad(210.0), 0.5
    traj = gv.simulate(arm, T, n_steps=500, base_angle=lambda t: theta_f * (t / T) ** 2, save_every=500)
    np.testing.assert_allclose(traj.tip[-1, :2], [0.440682, 0.815432], atol=2e-6)
    np.testing.assert_allclose(traj.tip_velocity[-1, :2], [-13.68403, 7.85183], atol=2e-5)
    np.testing.assert_allclose(traj.q[-1, 1:], [-3.66729, 4.95229], atol=2e-5)
    assert float(traj.joint_torque[0, 0]) == pytest.approx(0.02733 * 2 * theta_f / T**2, rel=1e-3)
