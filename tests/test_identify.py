"""Parameter identification (gvsjax.core.identify): the solver on a closed-form model; E and eta of
the paper's arm recovered from simulated tip trajectories of another discretisation and the
Jacobian against finite differences (extended tier); bad input. One bending mode:
differentiating a simulation is what takes long to compile, and the fit is the same for any
basis (experiments/transfer/identify_and_correct.py fits the task's 2-mode and a converged Legendre arm)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import gvsjax as gv
from gvsjax.core.identify import fit_parameters, relative_errors

E0, ETA0 = gv.PAPER_ARM["youngs_modulus"], gv.PAPER_ARM["damping"]
SWINGS = jnp.array([0.6, 0.9])  # s: theta = 210 deg (t / T)^2 up to 0.8 T, fast enough to excite bending
TRUTH = {"E": 1.2 * E0, "eta": 0.7 * ETA0}


def tips(p, n_steps):
    """Tip x-y at 10 times along two swings (RK4 within its stability limit)."""
    arm = gv.paper_arm(tip_force=5.886, youngs_modulus=p["E"], damping=p["eta"], n_modes=1)

    def one(T):
        tr = gv.simulate(arm, 0.8 * T, n_steps=n_steps, integrator="rk4", save_every=n_steps // 10,
                         check_stability=False, base_angle=lambda t: np.deg2rad(210.0) * (t / T) ** 2)
        return tr.tip[1:, :2]

    return jax.vmap(one)(SWINGS)


def model(p):
    return tips(p, 120)


@pytest.fixture(scope="module")
def fitted():
    observed = jax.jit(lambda p: tips(p, 960))(TRUTH)  # 8x finer steps: not the fitted program
    fit = jax.jit(lambda o: fit_parameters(model, o, {"E": E0, "eta": ETA0}, n_iters=6))(observed)
    return observed, fit


def test_recovers_a_damped_oscillation_and_its_jacobian_in_closed_form():
    """The solver alone, on a closed-form model x(t) = exp(-c t) cos(w t) (the simulator's fit is
    in the extended tier): from 15-50% off, under jit, it recovers w and c to 1e-8, its costs
    never rise, and its Jacobian in log p is the analytic one."""
    t = jnp.linspace(0.0, 4.0, 40)

    def predict(p):
        return {"x": jnp.exp(-p["c"] * t) * jnp.cos(p["w"] * t)}

    truth = {"w": 3.0, "c": 0.4}
    observed = predict(truth)
    fit = jax.jit(lambda o: fit_parameters(predict, o, {"w": 2.6, "c": 0.6}, n_iters=12))(observed)
    err = relative_errors(fit, truth)
    assert abs(err["w"]) < 1e-8 and abs(err["c"]) < 1e-8, err
    assert np.all(np.diff(np.asarray(fit.cost)) <= 0.0) and float(fit.cost[-1]) < 1e-20
    w, c = float(fit.values["w"]), float(fit.values["c"])
    dx_dlogw = -t * w * np.exp(-c * t) * np.sin(w * t)
    dx_dlogc = -t * c * np.exp(-c * t) * np.cos(w * t)
    np.testing.assert_allclose(np.asarray(fit.jacobian), np.stack([dx_dlogw, dx_dlogc], 1), atol=1e-12)


@pytest.mark.slow
@pytest.mark.extended
def test_recovers_E_and_eta_from_another_discretisation(fitted):
    observed, fit = fitted
    err = relative_errors(fit, TRUTH)
    assert abs(err["E"]) < 1e-3 and abs(err["eta"]) < 1e-2, err
    assert float(fit.rms) < 1e-4  # m: the step error left, against ~cm at the start
    assert float(fit.cost[0]) > 1e4 * float(fit.cost[-1])
    assert np.all(np.diff(np.asarray(fit.cost)) <= 0.0)  # only improving steps are kept
    assert fit.history["E"].shape == (7,) and float(fit.history["E"][0]) == E0


@pytest.mark.slow
@pytest.mark.extended
def test_jacobian_matches_finite_differences(fitted):
    observed, fit = fitted
    run = jax.jit(model)
    h = 1e-4
    for i, name in enumerate(("E", "eta")):
        up = {**fit.values, name: fit.values[name] * np.exp(h)}
        down = {**fit.values, name: fit.values[name] * np.exp(-h)}
        fd = (np.ravel(run(up)) - np.ravel(run(down))) / (2.0 * h)
        np.testing.assert_allclose(fit.jacobian[:, i], fd, rtol=1e-5, atol=1e-6 * np.max(np.abs(fd)))


@pytest.mark.parametrize("initial, observed, n_iters, match", [
    ({"E": -1.0}, np.zeros((2, 10, 2)), 3, r"initial\['E'\]=-1.0 is invalid: expected a finite number > 0"),
    ({"E": E0, "eta": float("nan")}, np.zeros((2, 10, 2)), 3, r"initial\['eta'\]=nan is invalid"),
    ({"E": E0}, np.full((2, 10, 2), np.nan), 3, "observed=.* is invalid: expected a finite number"),
    ({"E": E0}, np.zeros((3, 2)), 3, "observed='6 values' is invalid: expected 40 values"),
    ({"E": E0}, np.zeros((2, 10, 2)), 0, "n_iters=0 is invalid: expected an int >= 1"),
    ({}, np.zeros((2, 10, 2)), 3, "initial={} is invalid"),
])
def test_bad_input_names_the_parameter(initial, observed, n_iters, match):
    def predict(p):
        return tips({"E": p["E"], "eta": p.get("eta", ETA0)}, 120)

    with pytest.raises(ValueError, match=match):
        fit_parameters(predict, observed, initial, n_iters=n_iters)
