"""The Lie-group maths (gvsjax.lie): the exponential's coefficient functions of u = theta^2
(sinc, a, b, f3, f4), values and rates, in float64 and float32, against an independent series."""

import gvsjax  # noqa: F401, I001  (first: it configures JAX)
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax import lie


def _series(name: str, n_terms: int = 20) -> list[float]:
    """Taylor coefficients in u = theta^2, derived by hand from the sin/cos series
    (independent of gvsjax's truncated series and closed forms)."""
    f = math.factorial
    if name == "sinc":
        return [(-1) ** k / f(2 * k + 1) for k in range(n_terms)]
    if name == "a":  # (1 - cos t) / t^2
        return [(-1) ** k / f(2 * k + 2) for k in range(n_terms)]
    if name == "b":  # (t - sin t) / t^3
        return [(-1) ** k / f(2 * k + 3) for k in range(n_terms)]
    if name == "f3":  # (2 - 2c - t s) / (2 t^4): t^2m has coefficient (-1)^m (2m - 2) / (2m)!
        return [(-1) ** m * (2 * m - 2) / (2 * f(2 * m)) for m in range(2, n_terms + 2)]
    # f4 = (2 t - 3 s + t c) / (2 t^5): t^(2m+1) has coefficient (-1)^m (2m - 2) / (2m + 1)!
    return [(-1) ** m * (2 * m - 2) / (2 * f(2 * m + 1)) for m in range(2, n_terms + 2)]


# worst relative error allowed: values, and rates (d/du) relative to the largest rate
TOLERANCE = {jnp.float64: (1e-9, 1e-5), jnp.float32: (2e-5, 1e-3)}


@pytest.mark.parametrize("dtype", [jnp.float64, jnp.float32], ids=["float64", "float32"])
@pytest.mark.parametrize("name", ["sinc", "a", "b", "f3", "f4"])
def test_coefficient_functions_are_accurate_in_each_precision(name, dtype):
    """Values and rates from 0 to theta = 3 against a 20-term series in float64. With
    float64's threshold (theta < 0.1) in float32, f4's closed form at theta = 0.1
    is ~2% off (cancellation; numpy float32 gives 1.6%), far beyond the 2e-5 allowed: this is
    what the float32 threshold and extra series term fix."""
    fn = {"sinc": lie._sinc, "a": lie._a, "b": lie._b, "f3": lie._f3, "f4": lie._f4}[name]
    c = _series(name)
    u = np.concatenate([[0.0], np.geomspace(1e-8, 9.0, 400)])
    ref = sum(ck * u**k for k, ck in enumerate(c))
    ref_rate = sum(k * ck * u ** (k - 1) for k, ck in enumerate(c) if k)
    val, rate = jax.vmap(lambda x: jax.jvp(fn, (x,), (jnp.ones_like(x),)))(jnp.asarray(u, dtype))
    assert val.dtype == rate.dtype == dtype
    tol_val, tol_rate = TOLERANCE[dtype]
    assert np.max(np.abs(np.asarray(val, float) - ref) / np.abs(ref)) < tol_val
    assert np.max(np.abs(np.asarray(rate, float) - ref_rate)) / np.max(np.abs(ref_rate)) < tol_rate
