"""Static equilibrium and inverse statics of a GVS robot.

``equilibrium`` solves F(q, qd = 0) = 0 for the free DoFs (F: gravity, point
loads, tendons, a given generalized force and the elastic force -K q, from
``dynamics.mass_and_forces``) by Newton's method with a backtracking line search, optionally raising the
loads in ``load_scale_steps`` steps (continuation). Its derivatives come from
the implicit function theorem (a ``custom_jvp`` rule reusing Newton's last
Jacobian), not from unrolling the iterations.

``inverse_statics`` finds tendon tensions (>= 0) and/or prescribed DoF values
that put the equilibrium tip at a target: projected Levenberg-Marquardt on
controls -> equilibrium -> tip.

Both work inside ``jit``, ``vmap`` and ``grad``; bad input raises ValueError
naming the parameter before anything is traced. Compile time, not run time,
is the cost here (seconds per robot structure), so each solver traces the
force once.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_derivatives import SymbolicZero

from gvsjax.core import active_strain, dynamics, lie
from gvsjax.core.inputs import initial
from gvsjax.core.kinematics import backbone
from gvsjax.core.model import Robot
from gvsjax.core.validation import check_robot, concrete, finite, integer, positive, require


class StaticsResult(NamedTuple):
    """q: (n,) equilibrium coordinates; residual_norm: ||F_u|| / (||(K q)_u|| +
    ||F_u + (K q)_u||), the free DoFs' force imbalance relative to the elastic
    and external forces in balance; iterations: Newton steps over all load
    steps; converged: residual_norm <= tol at full load."""

    q: jax.Array
    residual_norm: jax.Array
    iterations: jax.Array
    converged: jax.Array


class InverseStaticsResult(NamedTuple):
    """tension: (n_tendons,) N; prescribed: (n_prescribed,) values of the
    prescribed DoFs; q: (n,) the equilibrium; tip: (3,) its tip (m); error:
    ||tip - target|| (m); iterations: equilibria evaluated; converged: error
    <= tol with a converged equilibrium."""

    tension: jax.Array
    prescribed: jax.Array
    q: jax.Array
    tip: jax.Array
    error: jax.Array
    iterations: jax.Array
    converged: jax.Array


def _forces(robot: Robot, q: jax.Array, tension: jax.Array, s: Any, generalized: jax.Array) -> jax.Array:
    """F(q, qd = 0), shape (n,), with gravity, point loads, tensions and the generalized
    force (``strain_force``) scaled by s."""
    n = robot.n_dofs
    loads = tuple(dataclasses.replace(load, magnitude=s * load.magnitude) for load in robot.loads)
    scaled = dataclasses.replace(robot, gravity=s * robot.gravity, loads=loads)  # point masses weigh via gravity
    # qd as structural zeros: the velocity terms vanish at trace time
    _, F = dynamics.mass_and_forces(scaled, [q[i] for i in range(n)], [0] * n,
                                    [s * tension[k] for k in range(len(robot.tendons))])
    return (jnp.stack([lie.as_array(f) for f in F]) + s * generalized).astype(q.dtype)


def _relative(r: jax.Array, kq: jax.Array) -> jax.Array:
    scale = jnp.linalg.norm(kq) + jnp.linalg.norm(r + kq)
    return jnp.linalg.norm(r) / jnp.where(scale > 0, scale, 1.0)


def _newton(residual: Callable, qu: jax.Array, tol: Any, max_iter: Any) -> tuple:
    """Newton with backtracking on ||r||; residual(qu) -> (r, (K q)_u). Each pass
    evaluates r and its Jacobian at one trial point (one trace of the force).
    Returns (qu, Jacobian at qu, relative residual, accepted steps)."""

    def evaluate(v):
        r, kq = residual(v)
        return r, (r, kq)

    def cond(c):
        *_, alpha, it, rel = c
        return (alpha == 0) | (~(rel <= tol) & (it < max_iter) & (alpha > 2.0**-20))

    def body(c):
        x, r_x, jac_x, du, alpha, it, rel = c
        jac, (r, kq) = jax.jacfwd(evaluate, has_aux=True)(x + alpha * du)
        # Armijo on ||r||: the first pass (alpha = 0, ||r_x|| = inf) accepts, NaN never does
        ok = jnp.linalg.norm(r) <= (1 - 1e-4 * alpha) * jnp.linalg.norm(r_x)
        pick = lambda new, old: jnp.where(ok, new, old)  # noqa: E731
        # a NaN start jumps to the stall limit; a stall (2^-20 of a step fails) ends the loop
        alpha_new = pick(1.0, jnp.where(alpha > 0, 0.5 * alpha, 2.0**-21))
        return (pick(x + alpha * du, x), pick(r, r_x), pick(jac, jac_x), pick(-jnp.linalg.solve(jac, r), du),
                alpha_new, it + (ok & (alpha > 0)), pick(_relative(r, kq), rel))

    m, dt = qu.shape[0], qu.dtype
    init = (qu, jnp.full(m, jnp.inf, dt), jnp.zeros((m, m), dt), jnp.zeros(m, dt), jnp.zeros((), dt),
            jnp.zeros((), int), jnp.full((), jnp.nan, dt))
    x, _, jac, _, _, it, rel = jax.lax.while_loop(cond, body, init)
    return x, jac, rel, it


def _parts(robot: Robot, q_start: jax.Array, qa: jax.Array) -> tuple:
    """Free indices, free -> full coordinates, and the free rows of K."""
    a, u = jnp.asarray(robot.prescribed, dtype=int), jnp.asarray(robot.free, dtype=int)
    K_u = dynamics.full_matrix(dynamics.stiffness_and_damping(robot)[0], robot.n_dofs)[u]
    return u, lambda qu: q_start.at[a].set(qa).at[u].set(qu), K_u


@jax.custom_jvp
def _root(robot: Robot, q_start, tension, qa, generalized, steps, tol, max_iter) -> tuple:
    """(free q, Jacobian of F_u there, relative residual, Newton steps as a float)."""
    u, full, K_u = _parts(robot, q_start, qa)

    def stage(i, c):
        s = (i + 1) / steps
        qu, jac, rel, it = _newton(lambda v: (_forces(robot, full(v), tension, s, generalized)[u], K_u @ full(v)), c[0],
                                   tol, max_iter)
        return qu, jac, rel, c[3] + it

    m, dt = len(robot.free), q_start.dtype
    init = (q_start[u], jnp.zeros((m, m), dt), jnp.full((), jnp.inf, dt), jnp.zeros((), int))
    qu, jac, rel, its = jax.lax.fori_loop(0, steps, stage, init)
    return qu, jac, rel, its.astype(dt)  # float outputs only: plain zero tangents


@functools.partial(_root.defjvp, symbolic_zeros=True)
def _root_jvp(primals: tuple, tangents: tuple) -> tuple:
    """F_u(q_u*, p) = 0 gives dq_u* = -(dF_u/dq_u)^-1 (dF_u/dp) dp, with the Jacobian
    Newton ended on (taken at the returned point). First derivatives only."""
    robot, q_start, tension, qa, generalized = primals[:5]
    out = _root(*primals)
    qu, jac = out[0], out[1]
    leaves, tree = jax.tree_util.tree_flatten((robot, tension, qa, generalized))
    is_zero = lambda t: isinstance(t, SymbolicZero)  # noqa: E731
    d_leaves = jax.tree_util.tree_leaves((tangents[0], tangents[2], tangents[3], tangents[4]), is_leaf=is_zero)
    assert len(d_leaves) == len(leaves)  # one tangent (maybe a symbolic zero) per leaf
    active = [i for i, d in enumerate(d_leaves) if not is_zero(d)]  # differentiate only what varies

    def force(*xs):
        ls = list(leaves)
        for i, x in zip(active, xs):
            ls[i] = x
        robot_, tension_, qa_, generalized_ = jax.tree_util.tree_unflatten(tree, ls)
        u, full, _ = _parts(robot_, q_start, qa_)
        return _forces(robot_, full(qu), tension_, 1.0, generalized_)[u]

    d_qu = jnp.zeros_like(qu)
    if active:
        _, dF = jax.jvp(force, tuple(leaves[i] for i in active), tuple(d_leaves[i] for i in active))
        d_qu = -jnp.linalg.solve(jac, dF)
    return out, (d_qu, jnp.zeros_like(jac), jnp.zeros_like(out[2]), jnp.zeros_like(out[3]))


def _solve(robot: Robot, q_start, tension, qa, generalized, steps, tol, max_iter) -> StaticsResult:
    """The traced solver; ``steps`` may be traced: one program for any number of load steps."""
    qu, _, rel, its = _root(robot, q_start, tension, qa, generalized, steps, tol, max_iter)
    return StaticsResult(_parts(robot, q_start, qa)[1](qu), rel, its.astype(int), rel <= tol)


_solve_jit = jax.jit(_solve)


def _check(robot: Robot, q0: Any, load_scale_steps: Any, tol: Any, max_iter: Any) -> Any:
    check_robot(robot)
    require(len(robot.free) >= 1, "robot.prescribed", robot.prescribed, "to leave at least one free DoF")
    integer("load_scale_steps", load_scale_steps, 1)
    integer("max_iter", max_iter, 1)
    positive("tol", tol, ())
    return jnp.asarray(initial(q0, robot.n_dofs, "q0"), dtype=float)


def _vector(name: str, value: Any, size: int, what: str, nonneg: bool, shapes: tuple) -> jax.Array:
    """value as a (size,) float array; numbers checked when concrete, the shape always."""
    require(not callable(value) and not isinstance(value, (str, bytes, bool)), name, value, what)
    if concrete(value):
        try:
            v = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            require(False, name, value, what)
        require(v.shape in shapes and bool(np.all(np.isfinite(v))) and (not nonneg or bool(np.all(v >= 0))),
                name, value, what)
    else:
        require(jnp.shape(value) in shapes, name, value, what)
    return jnp.broadcast_to(jnp.asarray(value, dtype=float), (size,))


def _tension(robot: Robot, value: Any, name: str) -> jax.Array:
    n_t = len(robot.tendons)
    if value is None:
        return jnp.zeros(n_t)
    require(n_t > 0, name, value, "None: this robot has no tendon")
    return _vector(name, value, n_t, f"a finite tension >= 0 N, or one per tendon (shape ({n_t},))", True,
                   ((), (n_t,)))


def _prescribed(robot: Robot, value: Any, q0: jax.Array, name: str) -> jax.Array:
    n_a = len(robot.prescribed)
    if value is None:
        return q0[np.asarray(robot.prescribed, dtype=int)]
    return _vector(name, value, n_a, f"finite values of the {n_a} prescribed DoFs, shape ({n_a},)", False,
                   ((n_a,),))


def equilibrium(robot: Robot, q0: Any = None, *, tendon_force: Any = None, prescribed: Any = None,
                strain_force: Any = None, rest_strain: Any = None, load_scale_steps: int = 1,
                tol: float = 1e-10, max_iter: int = 50) -> StaticsResult:
    """The static equilibrium F(q, qd = 0) = 0 of the free DoFs.

    q0: (n,) starting guess (default: straight, q = 0). tendon_force: tension(s)
    >= 0 N, one value or one per tendon (default 0). prescribed: (n_prescribed,)
    values at which ``robot.prescribed`` DoFs are held (default: their q0).
    strain_force: (n,) generalized force added to F, as ``simulate``'s (default 0;
    e.g. ``gvsjax.core.muscles.moment_map(robot) @ u``). rest_strain: values at
    ``robot.rest_strains``, as ``simulate``'s (default 0; ``gvsjax.core.active_strain``).
    load_scale_steps: k > 1 solves with gravity, point loads, tensions and strain_force
    scaled by 1/k, 2/k, ..., 1, each Newton solve starting from the last (for
    loads beyond Newton's reach from q0). tol: on the relative residual (see
    ``StaticsResult``); max_iter: Newton steps per load step. A failed solve
    is not an exception: check ``converged``.

    Differentiable (first order, implicit function theorem) in the robot's
    leaves, tendon_force, prescribed, strain_force and rest_strain.
    """
    q0 = _check(robot, q0, load_scale_steps, tol, max_iter)
    tension = _tension(robot, tendon_force, "tendon_force")
    qa = _prescribed(robot, prescribed, q0, "prescribed")
    n = robot.n_dofs
    generalized = jnp.zeros(n) if strain_force is None else _vector(
        "strain_force", strain_force, n, f"finite generalized forces, one per coordinate, shape ({n},)", False,
        ((n,),))
    rest = active_strain.check_value(robot, rest_strain)
    if rest is not None:
        require(not callable(rest), "rest_strain", rest, "values, not a callable (statics has no time)")
        generalized = generalized + active_strain.force_map(robot) @ rest
    return _solve_jit(robot, q0, tension, qa, generalized, load_scale_steps, tol, max_iter)


CONTROLS = ("tension", "prescribed")


def inverse_statics(robot: Robot, target_tip: Any, *, controls: Any = None, tension0: Any = None,
                    prescribed0: Any = None, q0: Any = None, load_scale_steps: int = 1, tol: float = 1e-9,
                    max_iter: int = 50, equilibrium_tol: float = 1e-10,
                    equilibrium_max_iter: int = 50) -> InverseStaticsResult:
    """Tendon tensions and/or prescribed DoF values whose equilibrium tip (the end of the
    robot's last link) is ``target_tip``.

    target_tip: (3,) world position (m). controls: "tension", "prescribed" or
    both as a tuple (default: whatever the robot has); the rest stay at their
    starting values. tension0 (>= 0 N, default 0) and prescribed0 (default:
    q0's values): the starting guess. load_scale_steps: continuation for the
    first equilibrium; later ones start from the previous one. tol: on
    ||tip - target|| (m).

    Levenberg-Marquardt with the Jacobian's columns scaled to unit norm (N and
    rad mix), tensions projected onto >= 0. The damped step is the
    minimum-norm one, so with more controls than reachable directions the
    solution found is one near the guess; a target out of reach ends at a
    least-squares point with converged False.
    """
    q0 = _check(robot, q0, load_scale_steps, equilibrium_tol, equilibrium_max_iter)
    integer("max_iter", max_iter, 1)
    positive("tol", tol, ())
    if concrete(target_tip):
        finite("target_tip", target_tip, (3,))
    else:
        require(jnp.shape(target_tip) == (3,), "target_tip", target_tip, "a (3,) position (m)")
    have = tuple(c for c, n in zip(CONTROLS, (len(robot.tendons), len(robot.prescribed))) if n)
    chosen = have if controls is None else ((controls,) if isinstance(controls, str) else tuple(controls))
    require(len(chosen) >= 1 and set(chosen) <= set(have) and len(set(chosen)) == len(chosen), "controls",
            controls, f"one or more of {have} (what this robot has)")
    tension = _tension(robot, tension0, "tension0")
    qa = _prescribed(robot, prescribed0, q0, "prescribed0")
    return _inverse_jit(robot, jnp.asarray(target_tip, dtype=float), q0, tension, qa, load_scale_steps, tol,
                        max_iter, equilibrium_tol, equilibrium_max_iter, controls=chosen)


def _inverse(robot: Robot, target, q0, tension, qa, steps, tol, max_iter, eq_tol, eq_max_iter, *,
             controls: tuple) -> InverseStaticsResult:
    n_t = len(robot.tendons) if "tension" in controls else 0
    x0 = jnp.concatenate([tension[:n_t], qa if "prescribed" in controls else qa[:0]])
    lower = jnp.concatenate([jnp.zeros(n_t), jnp.full(x0.shape[0] - n_t, -jnp.inf)])

    def unpack(x):
        return (x[:n_t] if n_t else tension), (x[n_t:] if "prescribed" in controls else qa)

    def tip(x, q_start, k):
        T, qa_ = unpack(x)
        res = _solve(robot, q_start, T, qa_, jnp.zeros(robot.n_dofs, q_start.dtype), k, eq_tol, eq_max_iter)
        p = backbone(robot, res.q)[-1]
        return p, (p, res)

    def cond(c):
        *_, err, lam, it, _, _, moving = c
        return (it < max_iter) & ~(err <= tol) & (lam < 1e12) & ((it == 0) | (jnp.isfinite(err) & moving))

    def body(c):
        x, res, e, J, err, lam, it, x_try, k, _ = c
        J_try, (p_try, res_try) = jax.jacfwd(tip, has_aux=True)(x_try, res.q, k)
        err_try = jnp.linalg.norm(p_try - target)
        ok = (err_try < err) & res_try.converged
        pick = lambda new, old: jax.tree_util.tree_map(lambda a, b: jnp.where(ok, a, b), new, old)  # noqa: E731
        x, res, e, J, err = pick((x_try, res_try, p_try - target, J_try, err_try), (x, res, e, J, err))
        lam = jnp.where(ok, lam / 3.0, lam * 4.0)
        # damped least squares in unit-column scaling, dz = -J^T (J J^T + lam I)^-1 e, with
        # tensions held at 0 that would go negative left out (else the projection stalls)
        d = jnp.linalg.norm(J, axis=0)
        d = jnp.where(d > 0, d, 1.0)
        dz = lambda Js: -(Js.T @ jnp.linalg.solve(Js @ Js.T + lam * jnp.eye(3), e))  # noqa: E731
        Js = J * (1.0 - ((x <= lower) & (dz(J / d) < 0))) / d
        step = dz(Js) / d
        moving = jnp.linalg.norm(Js.T @ e) > 1e-6 * err  # first-order optimality: a least-squares point
        return x, res, e, J, err, lam, it + 1, jnp.maximum(x + step, lower), jnp.ones((), int), moving

    res0 = StaticsResult(q0, jnp.asarray(jnp.inf), jnp.zeros((), int), jnp.asarray(False))
    # e starts as NaN: should the first equilibrium fail, the reported tip is NaN, not the target
    init = (x0, res0, jnp.full(3, jnp.nan), jnp.zeros((3, x0.shape[0])), jnp.asarray(jnp.inf), jnp.asarray(1e-2),
            jnp.zeros((), int), x0, jnp.asarray(steps, dtype=int), jnp.asarray(True))
    x, res, e, _, err, _, it, _, _, _ = jax.lax.while_loop(cond, body, init)
    T, qa_out = unpack(x)
    return InverseStaticsResult(T, qa_out, res.q, e + target, err, it, (err <= tol) & res.converged)


_inverse_jit = jax.jit(_inverse, static_argnames=("controls",))

__all__ = ["equilibrium", "inverse_statics", "StaticsResult", "InverseStaticsResult", "CONTROLS"]
