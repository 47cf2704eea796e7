"""Robot descriptions (gvsjax.core.model, gvsjax.core.robots): ``paper_arm``, ``rod_3d`` and ``tendon_arm`` reject bad
parameters with a ValueError naming the parameter, before anything is traced or compiled; the
two strain bases describe the same arm."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import math

import numpy as np
import pytest
from helpers import FAST, nan_inf, not_a_number, not_positive, raises_naming
from hypothesis import example, given
from hypothesis import strategies as st

negative = st.one_of(st.floats(max_value=-1e-12, allow_nan=False), st.integers(max_value=-1),
                     st.just(math.nan), st.just(math.inf), not_a_number)
not_finite = st.one_of(nan_inf, not_a_number)
bad_count = st.one_of(st.integers(max_value=0), st.floats(allow_nan=True), st.booleans(),
                      st.text(max_size=3), st.none())


def named(table):
    """(name, bad value) pairs: a parameter of ``table``, then a value from its strategy."""
    return st.sampled_from(sorted(table)).flatmap(lambda name: st.tuples(st.just(name), table[name]))


ARM_BAD = {
    **{k: not_positive for k in ("length", "radius", "youngs_modulus", "density")},
    **{k: negative for k in ("damping", "gravity", "tip_mass")},
    "tip_force": not_finite,
    "n_modes": bad_count,
    "n_gauss": bad_count,
    "basis": st.one_of(st.text(max_size=8).filter(lambda s: s not in ("monomial", "legendre")),
                       st.integers(), st.none()),
    "poisson": st.one_of(st.floats(min_value=0.5, exclude_min=True, allow_nan=False),
                         st.floats(max_value=-1.0, allow_nan=False), st.just(math.nan), not_a_number),
    "tendon_offset": st.one_of(st.floats(min_value=0.0501, allow_nan=False, allow_infinity=False),
                               st.floats(max_value=-0.0501, allow_nan=False, allow_infinity=False),
                               nan_inf, not_a_number.filter(lambda v: v is not None)),
}


@FAST
@given(case=named(ARM_BAD))
@example(case=("length", 0.0))
@example(case=("radius", math.nan))
@example(case=("youngs_modulus", math.inf))
@example(case=("density", -1.0))
@example(case=("damping", -1e-12))
@example(case=("tip_mass", math.nan))
@example(case=("n_modes", True))
@example(case=("n_modes", 0))
@example(case=("tendon_offset", 0.2))  # outside the 5 cm rod
def test_paper_arm_overrides_invalid(case):
    name, value = case
    raises_naming(name, gv.paper_arm, **{name: value})


@FAST
@given(key=st.text("abcdefghijklmnopqrstuvwxyz_", min_size=1, max_size=12).filter(
    lambda k: k not in gv.PAPER_ARM))
@example(key="young")
def test_paper_arm_unknown_override_lists_the_valid_keys(key):
    # a closure, so that generated keys such as "fn" or "exc" reach paper_arm, not the helper
    message = raises_naming(key, lambda: gv.paper_arm(**{key: 1.0}))
    assert "youngs_modulus" in message


ROD_BAD = {
    **{k: not_positive for k in ("length", "radius", "youngs_modulus", "density")},
    **{k: negative for k in ("damping", "gravity")},
    "order": st.one_of(st.integers(max_value=-1), st.floats(), st.booleans(),
                       st.lists(st.integers(-1, 3), max_size=5),  # not six entries
                       st.just((-1,) * 6), st.just((0, 1, 2, 3, 4, -2))),
    "n_gauss": st.one_of(st.integers(max_value=1), st.floats(), st.booleans(), st.none()),
    "basis": st.text(max_size=8).filter(lambda s: s not in ("monomial", "legendre")),
}


@FAST
@given(case=named(ROD_BAD))
def test_rod_3d_invalid(case):
    name, value = case
    raises_naming(name, gv.rod_3d, **{name: value})


TENDON_ARM_BAD = {
    **{k: not_positive for k in ("length", "radius", "taper", "youngs_modulus", "density", "hub_mass",
                                 "hub_length")},
    **{k: negative for k in ("damping", "gravity", "hub_damping", "tip_mass")},
    "hub_inertia": st.one_of(not_positive.map(lambda v: (v, 1e-3, 1e-3)), st.just((1e-3, 1e-3))),
    "helix_turns": not_finite,
    "bending_order": st.one_of(st.integers(max_value=-1), st.floats(), st.booleans(), st.none()),
    "n_gauss": st.one_of(st.integers(max_value=1), st.floats(), st.booleans(), st.none()),  # order 1 needs 2
    "tendon_offset": st.one_of(not_positive, st.floats(min_value=0.025, allow_nan=False)),  # radius 0.025
}


@FAST
@given(case=named(TENDON_ARM_BAD))
@example(case=("tendon_offset", 0.03))  # outside the 25 mm section
@example(case=("n_gauss", 1))
@example(case=("hub_inertia", (True, 1e-3, 1e-3)))  # a flag in a vector is not the number 1
def test_tendon_arm_invalid(case):
    name, value = case
    raises_naming(name, gv.tendon_arm, **{name: value})


def test_tendon_arm_unknown_override_lists_the_valid_keys():
    assert "helix_turns" in raises_naming("bogus", lambda: gv.tendon_arm(bogus=1.0))


def test_tendon_arm_numbers_trace_under_jit_vmap_and_grad():
    """Its physical numbers are leaves: the soft link's stiffness is E times a fixed matrix, so
    d tr(K) / dE = tr(K) / E, batched over E and compiled."""
    import jax
    import jax.numpy as jnp

    from gvsjax.core import dynamics

    def trace_K(E):
        arm = gv.tendon_arm(youngs_modulus=E)
        return jnp.trace(dynamics.full_matrix(dynamics.stiffness_and_damping(arm)[0], arm.n_dofs))

    E = jnp.array([0.5e6, 1e6, 2e6])
    values = jax.jit(jax.vmap(trace_K))(E)
    slopes = jax.jit(jax.vmap(jax.grad(trace_K)))(E)
    np.testing.assert_allclose(slopes, values / E, rtol=1e-12)
    np.testing.assert_allclose(values, values[1] * E / 1e6, rtol=1e-12)


@pytest.mark.extended
def test_monomial_and_legendre_give_the_same_arm():
    """Same span, same quadrature: the two bases are one model in other coordinates."""
    theta_f, T = np.deg2rad(210.0), 0.8

    def tips(basis):
        arm = gv.paper_arm(tip_force=5.886, n_modes=3, basis=basis)
        return gv.simulate(arm, T, n_steps=1000, base_angle=lambda t: theta_f * (t / T) ** 2,
                           save_every=100).tip

    np.testing.assert_allclose(tips("monomial"), tips("legendre"), atol=1e-9)
