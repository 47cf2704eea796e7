"""The Lie-group maths (gvsjax.core.lie): the exponential's coefficient functions of u = theta^2
(sinc, a, b, f3, f4), values and rates, in float64 and float32, against an independent series."""

import gvsjax  # noqa: F401, I001  (first: it configures JAX)
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gvsjax.core import lie


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


def test_scalar_algebra_gives_what_the_jnp_operators_give():
    """``lie.add/sub/mul/neg`` bind ``lax`` directly where no promotion is involved and fall back to
    the operators elsewhere: for every pair of operand kinds (strong and weak arrays of both floating
    dtypes, a shape-(3,) array, Python numbers, an integer array) the value, dtype, weak type and
    shape equal the ``jnp`` operators', eagerly, under jit and under vmap; and gradients pass."""
    operands = {"f64": jnp.asarray(1.25, jnp.float64), "f32": jnp.asarray(-0.75, jnp.float32),
                "weak": jnp.asarray(0.5), "vec": jnp.asarray([1.5, -2.0, 0.25]), "vec32": jnp.ones(3, jnp.float32),
                "float": 2.5, "int": 3, "ints": jnp.asarray(2, jnp.int32)}
    assert operands["weak"].weak_type and not operands["f64"].weak_type
    pairs = [(x, y) for x in operands for y in operands if not (x in ("float", "int") and y in ("float", "int"))]
    ops = {lie.add: jnp.add, lie.sub: jnp.subtract, lie.mul: jnp.multiply}

    def check(got, want, label):
        got, want = jnp.asarray(got), jnp.asarray(want)
        assert (got.dtype, got.shape, got.weak_type) == (want.dtype, want.shape, want.weak_type), label
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want), err_msg=str(label))

    for x, y in pairs:
        for op, ref in ops.items():
            check(op(operands[x], operands[y]), ref(operands[x], operands[y]), (op.__name__, x, y))

    @jax.jit  # the arrays traced (their weak types kept), the Python numbers as they are
    def traced(arrays):
        v = {**arrays, "float": 2.5, "int": 3}
        return {f"{op.__name__}|{x}|{y}": (op(v[x], v[y]), ref(v[x], v[y]))
                for x, y in pairs for op, ref in ops.items()}

    for label, (got, want) in traced({k: v for k, v in operands.items() if k not in ("float", "int")}).items():
        check(got, want, ("jit", label))
    for x in ("f64", "f32", "weak", "vec", "ints"):
        check(lie.neg(operands[x]), -operands[x], ("neg", x))
    # under vmap: a batched shape-() operand against an unbatched one of the other's dtype
    batch = jnp.asarray([0.5, 1.0, 2.0])
    for op, ref in ops.items():
        check(jax.vmap(op, (0, None))(batch, operands["f64"]), ref(batch, operands["f64"]), ("vmap", op.__name__))
        check(jax.vmap(op, (None, 0))(2.0, batch), ref(2.0, batch), ("vmap float", op.__name__))
    # gradients: d/dx of x * (x - 2) + (-x) at x = 1.5 is 2 x - 3
    grad = jax.grad(lambda x: lie.add(lie.mul(x, lie.sub(x, 2.0)), lie.neg(x)))(jnp.asarray(1.5))
    assert float(grad) == 0.0
