"""Parameter identification: fit positive physical parameters to observations by least squares.

``fit_parameters(predict, observed, initial)`` minimises |predict(p) - observed|^2 / 2 over
positive parameters p (e.g. Young's modulus and the material damping of an arm, with
``predict`` a simulated tip trajectory) by Levenberg-Marquardt, with the Jacobian by
forward-mode differentiation (``jax.jacfwd``: one tangent per parameter, so a few
parameters cost a few simulations, whatever the number of observations).

The unknowns are the logs of p / initial: every parameter is then of order one and stays
positive, and a relative error (10% of E, 10% of eta) is one step length for all of them.
The loop is a ``lax.scan`` of fixed length, so the whole fit runs inside ``jit`` (and
``vmap``, e.g. over data sets) with ``predict`` compiled once.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from gvsjax.core.validation import concrete, finite, integer, positive, require


@struct.dataclass
class Fit:
    """The result of ``fit_parameters`` (n = n_iters, k parameters, m observations).

    values: the fitted parameters, a dict like ``initial``. history: the same dict with
    (n + 1,) arrays, the start and the accepted iterate after each step. cost: (n + 1,)
    |r|^2 / 2 along ``history``. rms: the final root-mean-square residual (observed units).
    residual: (m,) the final predict - observed, flattened. jacobian: (m, k) its derivative
    with respect to log p at the fitted values (``jax.jacfwd``). log_std: (k,) the standard errors
    of log p from the final Jacobian, assuming independent residuals of equal variance
    (a lower bound when the model is not exact). correlation: (k, k) their correlation.
    """

    values: dict
    history: dict
    cost: jax.Array
    rms: jax.Array
    residual: jax.Array
    jacobian: jax.Array
    log_std: jax.Array
    correlation: jax.Array


def fit_parameters(predict: Callable[[dict], Any], observed: Any, initial: dict, *, n_iters: int = 8,
                   lam: float = 1e-3) -> Fit:
    """Fit the positive parameters ``initial`` (dict name -> scalar > 0) so that
    ``predict(params)`` (a pytree of arrays, params a dict of the same names) matches
    ``observed`` (the same structure) in the least-squares sense.

    Levenberg-Marquardt in log space, ``n_iters`` steps from p = initial: each step costs one
    prediction with its Jacobian (``jax.jacfwd``) at the trial point; a step that lowers the
    cost is kept and ``lam`` shrinks (x 1/3), otherwise (or if the trial is not finite) it
    grows (x 4) and the iterate stays. Weight or
    scale observations of different units before the call (residuals are summed as given).

    Works under ``jit`` when ``predict`` is jittable; ``n_iters`` must then be static.
    Bad input (a non-positive initial value, a non-finite observation, mismatched shapes)
    raises ValueError naming the parameter.
    """
    require(isinstance(initial, dict) and len(initial) >= 1, "initial", initial,
            "a dict of parameter name -> initial value > 0")
    for name, value in initial.items():
        positive(f"initial[{name!r}]", value, ())
    integer("n_iters", n_iters)
    positive("lam", lam, ())
    leaves = jax.tree_util.tree_leaves(observed)
    require(len(leaves) >= 1, "observed", observed, "arrays of observations")
    for leaf in leaves:
        finite("observed", leaf)
    names = list(initial)
    p0 = jnp.stack([jnp.asarray(initial[k], float) for k in names])
    obs = jnp.concatenate([jnp.ravel(jnp.asarray(o, float)) for o in jax.tree_util.tree_leaves(observed)])

    def params_of(x):
        return {k: p0[i] * jnp.exp(x[i]) for i, k in enumerate(names)}

    def flat(x):
        pred = predict(params_of(x))
        return jnp.concatenate([jnp.ravel(jnp.asarray(p, float)) for p in jax.tree_util.tree_leaves(pred)])

    shape = jax.eval_shape(flat, jnp.zeros(len(names))).shape
    require(shape == obs.shape, "observed", f"{obs.shape[0]} values", f"{shape[0]} values, as predict returns")

    def residual(x):
        r = flat(x) - obs
        return r, r

    jac = jax.jacfwd(residual, has_aux=True)

    def half_sq(r):
        c = 0.5 * jnp.sum(r * r)
        return jnp.where(jnp.isfinite(c), c, jnp.inf)

    n_par = len(names)

    # The first pass only evaluates the start (no step): jac then appears once in the program,
    # which matters because differentiating a simulation is what takes long to compile.
    def body(carry, first):
        x, r, J, c, lam_k = carry
        A, g = J.T @ J, J.T @ r
        # Marquardt's scaling by diag(A); the floor keeps a parameter the data do not see finite
        damped = A + lam_k * jnp.diag(jnp.diag(A)) + 1e-12 * jnp.trace(A) * jnp.eye(n_par)
        dx = -jnp.linalg.solve(damped, g)
        dx = jnp.where(first | ~jnp.all(jnp.isfinite(dx)), 0.0, dx)
        J_t, r_t = jac(x + dx)
        c_t = half_sq(r_t)
        keep = first | (c_t < c)
        pick = lambda new, old: jnp.where(keep, new, old)  # noqa: E731
        carry = (pick(x + dx, x), pick(r_t, r), pick(J_t, J), pick(c_t, c),
                 jnp.where(first, lam_k, jnp.where(keep, lam_k / 3.0, lam_k * 4.0)))
        return carry, (carry[0], carry[3])

    m = obs.shape[0]
    start = (jnp.zeros(n_par), jnp.zeros(m), jnp.zeros((m, n_par)), jnp.asarray(jnp.inf), jnp.asarray(lam, float))
    firsts = jnp.arange(n_iters + 1) == 0
    (x, r, J, _, _), (xs, cost) = jax.lax.scan(body, start, firsts)
    sigma2 = 2.0 * half_sq(r) / max(m - n_par, 1)
    cov = sigma2 * jnp.linalg.pinv(J.T @ J)
    std = jnp.sqrt(jnp.maximum(jnp.diag(cov), 0.0))
    corr = cov / jnp.maximum(jnp.outer(std, std), 1e-300)
    return Fit(values=params_of(x), history={k: p0[i] * jnp.exp(xs[:, i]) for i, k in enumerate(names)},
               cost=cost, rms=jnp.sqrt(2.0 * cost[-1] / m), residual=r, jacobian=J,
               log_std=std, correlation=corr)


def relative_errors(fit: Fit, truth: dict) -> dict[str, float]:
    """(fitted - truth) / truth per parameter named in ``truth`` (concrete values)."""
    require(concrete(fit.values), "fit", "traced values", "a concrete Fit (outside jit)")
    return {k: float(np.asarray(fit.values[k]) / float(v) - 1.0) for k, v in truth.items()}
