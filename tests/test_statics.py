"""Equilibrium and inverse statics against independent references: the classic
elastica (and a shooting solution of its ODE, in numpy here), linear beam
theory, the circular arc a straight tendon bends a rod into, and finite
differences.

Compile time dominates: the tests share two robot structures (a bending-only
cantilever, a small tendon arm) so that most calls reuse a compiled program.
"""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import functools
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax.core.statics import equilibrium, inverse_statics

R = 0.05  # m
I_AREA = np.pi * R**4 / 4  # second moment of area, m^4


def cantilever(E, gravity=0.0, P=0.0) -> gv.Robot:
    """A 1 m rod clamped at the origin along +x, bending about z only, with a dead
    tip load P along -y and gravity along -y.

    Basis: bending curvature of Legendre order 3 (4 DoFs), n_gauss = 4 (the
    fewest that integrate its stiffness exactly). The linear self-weight
    curvature w (L - s)^2 / (2 E I) is quadratic, so order >= 2 holds it
    exactly; the elastica's curvature P (x_tip - x(s)) / (E I) is smooth but
    not polynomial: its tip error falls with order (measured at P L^2/EI = 1:
    drop 4.8e-4, 1.6e-4, 7.4e-5 for orders 1, 2, 3), and order 3 is well
    inside 0.5% at half the compile time of order 4.
    """
    rod = gv.rod_3d(youngs_modulus=E, radius=R, order=(-1, -1, 3, -1, -1, -1), n_gauss=4, gravity=gravity)
    return rod.replace(loads=(gv.PointLoad(magnitude=P, link=0, X=1.0, direction=(0.0, -1.0, 0.0)),))


E_ARM = 5e6
D = 0.025  # tendon offset, m


def tendon_arm(P=0.0) -> gv.Robot:
    """The paper arm without gravity: prescribed base angle (held at pi/2, pointing
    along +x), a straight tendon at offset D on the local +y side, a tip load P
    along -y; linear curvature (2 modes), 2 Gauss points (compile time)."""
    return gv.paper_arm(gravity=0.0, youngs_modulus=E_ARM, radius=R, tendon_offset=D, tip_force=P, n_modes=2,
                        n_gauss=2)


HORIZONTAL = np.array([np.pi / 2])


@jax.jit
def tip_of(robot, q):
    return gv.backbone(robot, q)[-1]


@functools.cache
def elastica(alpha: float, n: int = 400) -> tuple[float, float]:
    """(reach, drop) / L of a clamped rod under a dead tip load, alpha = P L^2 / (E I):
    theta' = kappa, kappa' = -alpha cos(theta), theta(0) = 0, kappa(L) = 0, shot on
    kappa(0) in [0, alpha] (RK4, n steps; 12 rounds of a 16-way bracket search)."""

    def shoot(k0):
        y, h = np.stack([0 * k0, k0, 0 * k0, 0 * k0]), 1.0 / n
        rhs = lambda y: np.stack([y[1], -alpha * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])])  # noqa: E731
        for _ in range(n):
            a = rhs(y)
            b = rhs(y + h / 2 * a)
            c = rhs(y + h / 2 * b)
            y = y + h / 6 * (a + 2 * b + 2 * c + rhs(y + h * c))
        return y

    lo, hi = 0.0, alpha
    for _ in range(12):
        k = np.linspace(lo, hi, 17)
        f = shoot(k)[1]
        i = np.nonzero(np.sign(f[:-1]) != np.sign(f[1:]))[0][-1]  # the largest root: the branch without a loop
        lo, hi = k[i], k[i + 1]
    y = shoot(np.array([(lo + hi) / 2]))
    return float(y[2, 0]), float(y[3, 0])


def test_elastica_reference_itself():
    """The numpy shooting solution reproduces the classical (Bisshopp-Drucker) values."""
    reach, drop = elastica(1.0)
    assert reach == pytest.approx(0.94357, abs=1e-5)
    assert drop == pytest.approx(0.30172, abs=1e-5)


def test_large_deflection_cantilever_matches_elastica():
    """P L^2 / (E I) = 1: tip drop 0.30172 L, reach 0.94357 L (measured errors 7e-5, 1e-5).
    Continuation is not needed here: Newton from the straight rod takes 4 steps,
    and 4 load steps end at the same point."""
    E = 5e6
    rod = cantilever(E, P=E * I_AREA)
    res = equilibrium(rod)
    assert bool(res.converged) and float(res.residual_norm) <= 1e-10
    assert int(res.iterations) <= 6
    tip = np.asarray(tip_of(rod, res.q))
    assert -tip[1] == pytest.approx(0.30172, rel=5e-3)
    assert tip[0] == pytest.approx(0.94357, rel=5e-3)
    reach, drop = elastica(1.0)  # and tighter, against the shooting solution
    assert -tip[1] == pytest.approx(drop, rel=5e-4)
    assert tip[0] == pytest.approx(reach, rel=5e-4)
    stepped = equilibrium(rod, load_scale_steps=4)
    assert bool(stepped.converged)
    np.testing.assert_allclose(stepped.q, res.q, atol=1e-9)


def test_continuation_reaches_what_newton_alone_does_not():
    """P L^2 / (E I) = 30 (tip nearly under the load): Newton from the straight rod
    stalls (no step along its direction lowers the residual), while 4 load steps
    converge onto the elastica (shooting reference; measured error 0.1%)."""
    E = 5e6
    rod = cantilever(E, P=30.0 * E * I_AREA)
    plain = equilibrium(rod)
    assert not bool(plain.converged)
    res = equilibrium(rod, load_scale_steps=4)
    assert bool(res.converged)
    reach, drop = elastica(30.0)
    tip = np.asarray(tip_of(rod, res.q))
    assert tip[0] == pytest.approx(reach, rel=5e-3)
    assert -tip[1] == pytest.approx(drop, rel=5e-3)


def test_self_weight_matches_linear_beam_theory():
    """Horizontal cantilever under its own weight: tip deflection w L^4 / (8 E I),
    w = rho A g. E = 1e8 Pa (stiffer than the soft-arm range) keeps the
    deflection at 2% of L, small strain; the measured error, -0.03%, is the size
    of the geometric nonlinearity there (the elastica's ~0.095 alpha^2 at the
    equivalent alpha ~ 0.06)."""
    E, g = 1e8, 9.81
    rod = cantilever(E, gravity=g)
    res = equilibrium(rod)
    assert bool(res.converged)
    w = 1000.0 * np.pi * R**2 * g
    expected = w / (8 * E * I_AREA)
    assert 0.01 < expected < 0.03  # small load indeed
    tip = np.asarray(tip_of(rod, res.q))
    assert -tip[1] == pytest.approx(expected, rel=1e-2)


def arc_tip(tension: float) -> np.ndarray:
    """Tip of the horizontal tendon arm: constant curvature k = T d / (E I), a circular
    arc from the origin along +x bending towards the tendon (+y)."""
    k = tension * D / (E_ARM * I_AREA)
    return np.array([np.sin(k) / k, (1 - np.cos(k)) / k, 0.0])


def test_tendon_bends_into_circular_arc_and_inverse_statics_recovers_tension():
    arm = tendon_arm()
    res = equilibrium(arm, tendon_force=150.0, prescribed=HORIZONTAL)
    assert bool(res.converged)
    tip = np.asarray(tip_of(arm, res.q))
    # far inside 0.5%: exact to rounding, as the linear-curvature basis holds a constant one
    np.testing.assert_allclose(tip, arc_tip(150.0), rtol=0, atol=1e-12)

    # both controls at once (one compiled program): from 20 N and 1.3 rad back to 150 N
    # and the horizontal pi/2 (measured: 4.6e-8 and 2.2e-9 relative, 9 evaluations)
    inv = inverse_statics(arm, arc_tip(150.0), controls=("tension", "prescribed"), tension0=20.0,
                          prescribed0=[1.3])
    assert bool(inv.converged) and float(inv.error) <= 1e-9
    assert float(inv.tension[0]) == pytest.approx(150.0, rel=1e-4)
    assert float(inv.prescribed[0]) == pytest.approx(np.pi / 2, rel=1e-4)


def test_inverse_statics_out_of_reach_ends_at_the_nearest_point():
    """No tension and base angle put the tip 2.06 m out: the least-squares answer is the
    straight arm (zero tension, the bound) pointing at the target."""
    target = np.array([2.0, 0.5, 0.0])
    inv = inverse_statics(tendon_arm(), target, controls=("tension", "prescribed"),
                          tension0=20.0, prescribed0=[1.3])
    assert not bool(inv.converged)
    assert float(inv.tension[0]) >= 0.0
    np.testing.assert_allclose(inv.tip, target / np.linalg.norm(target), atol=1e-5)
    assert float(inv.error) == pytest.approx(np.linalg.norm(target) - 1.0, abs=1e-6)


def drop(P):
    """Tip height of the horizontal tendon arm (30 N in the tendon) under a tip load P."""
    arm = tendon_arm(P)
    return tip_of(arm, equilibrium(arm, tendon_force=30.0, prescribed=HORIZONTAL).q)[1]


def test_jit_vmap_and_grad_over_loads_match_single_calls_and_finite_differences():
    """One compiled program (jit of vmap of value_and_grad) for both checks: the
    batched values equal per-load calls, the gradients central differences."""
    loads = jnp.array([0.0, 5.0, 20.0, 60.0])
    values, grads = jax.jit(jax.vmap(jax.value_and_grad(drop)))(loads)
    single = np.array([float(drop(float(P))) for P in loads])
    np.testing.assert_allclose(values, single, rtol=0, atol=1e-12)
    assert np.all(np.diff(single) < 0)  # heavier loads bend further down
    h = 1e-3
    for P, g in zip(loads, grads):
        fd = (float(drop(float(P) + h)) - float(drop(float(P) - h))) / (2 * h)
        assert np.isfinite(float(g)) and float(g) < 0
        assert float(g) == pytest.approx(fd, rel=1e-5)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(q0=np.zeros(2)), "q0"),
        (dict(tendon_force=-1.0), "tendon_force"),
        (dict(tendon_force=[1.0, 2.0]), "tendon_force"),
        (dict(load_scale_steps=0), "load_scale_steps"),
        (dict(prescribed=[0.1, 0.2]), "prescribed"),
        (dict(tol=0.0), "tol"),
    ],
)
def test_bad_input_names_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=rf"^{name}="):
        equilibrium(tendon_arm(), **kwargs)


def test_inverse_statics_bad_input_names_the_parameter():
    arm = tendon_arm()
    with pytest.raises(ValueError, match=r"^target_tip="):
        inverse_statics(arm, [1.0, 0.0])
    with pytest.raises(ValueError, match=r"^tension0="):
        inverse_statics(arm, [1.0, 0.0, 0.0], tension0=-5.0)
    with pytest.raises(ValueError, match=r"^controls="):
        inverse_statics(gv.rod_3d(), [1.0, 0.0, 0.0], controls="tension")
