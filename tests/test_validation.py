"""Bad input fails early with a ValueError that names the parameter."""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import math

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

bad_positive = st.one_of(st.floats(max_value=0.0), st.just(math.nan), st.just(math.inf))


@settings(max_examples=25, deadline=None)
@given(name=st.sampled_from(["length", "radius", "youngs_modulus", "density"]), value=bad_positive)
def test_paper_arm_rejects_nonpositive_sizes_and_materials(name, value):
    with pytest.raises(ValueError, match=name):
        gv.paper_arm(**{name: value})


@settings(max_examples=25, deadline=None)
@given(name=st.sampled_from(["damping", "gravity", "tip_mass"]),
       value=st.one_of(st.floats(max_value=-1e-12), st.just(math.nan)))
def test_paper_arm_rejects_negative_or_nan(name, value):
    with pytest.raises(ValueError, match=name):
        gv.paper_arm(**{name: value})


@settings(max_examples=20, deadline=None)
@given(value=st.one_of(st.integers(max_value=0), st.floats(allow_nan=True), st.just(True)))
def test_paper_arm_rejects_bad_mode_counts(value):
    with pytest.raises(ValueError, match="n_modes"):
        gv.paper_arm(n_modes=value)


def test_paper_arm_unknown_key_lists_valid_ones():
    with pytest.raises(ValueError, match="youngs_modulus"):
        gv.paper_arm(young=1.0)


def test_tendon_must_run_inside_the_rod():
    with pytest.raises(ValueError, match="offset"):
        gv.paper_arm(tendon_offset=0.2)


ARM = gv.paper_arm()


@settings(max_examples=20, deadline=None)
@given(dt=st.one_of(st.floats(max_value=0.0), st.just(math.nan), st.just(-math.inf)))
def test_simulate_rejects_bad_steps(dt):
    with pytest.raises(ValueError, match="dt"):
        gv.simulate(ARM, 1.0, dt)


def test_simulate_rejects_step_beyond_stability():
    with pytest.raises(ValueError, match=r"dt=0\.05.*stability"):
        gv.simulate(ARM, 1.0, 0.05)
    # the implicit scheme has no such limit
    traj = gv.simulate(ARM, 1.0, 0.05, integrator="imex")
    assert np.all(np.isfinite(traj.q))


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(duration=-1.0, dt=1e-3), "duration"),
        (dict(duration=1.0, dt=3e-3), "dt"),  # does not divide the duration
        (dict(duration=1.0, dt=1e-3, q0=np.zeros(2)), "q0"),
        (dict(duration=1.0, dt=1e-3, qd0=[0.0, math.nan, 0.0]), "qd0"),
        (dict(duration=1.0, dt=1e-3, integrator="rk45"), "integrator"),
        (dict(duration=1.0, dt=1e-3, save_every=7), "save_every"),
        (dict(duration=1.0, dt=1e-3, base_angle=1.0), "base_angle"),
        (dict(duration=1.0, dt=1e-3, tendon_force=5.0), "tendon_force"),  # arm has no tendon
    ],
)
def test_simulate_argument_errors(kwargs, name):
    with pytest.raises(ValueError, match=name):
        gv.simulate(ARM, **kwargs)


@settings(max_examples=15, deadline=None)
@given(tension=st.one_of(st.floats(max_value=-1e-9), st.just(math.nan)))
def test_negative_tendon_tension_is_rejected(tension):
    arm = gv.paper_arm(tendon_offset=0.025)
    with pytest.raises(ValueError, match="tendon_force"):
        gv.simulate(arm, 0.1, 1e-3, tendon_force=tension)


def test_traced_inputs_skip_concrete_checks_but_run():
    import jax

    def tip(E):
        arm = gv.paper_arm(youngs_modulus=E)
        return gv.simulate(arm, 0.2, n_steps=50, base_angle=lambda t: t, save_every=50).tip[-1]

    out = jax.vmap(tip)(jnp.array([4e6, 5e6]))
    assert out.shape == (2, 3) and np.all(np.isfinite(out))
