"""float32 simulation (``simulate(..., dtype=jnp.float32)``): the whole program runs in
float32, its throws match float64 ones far inside the 1 mm budget of the basketball task, the
tasks' ``sim_dtype="float32"`` keeps their float64 states, and other dtypes are refused.
(The coefficient functions' accuracy in each precision: test_lie.py.)"""

import gvsjax as gv  # noqa: I001  (first: it configures JAX)
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

THETA_F = math.radians(210.0)  # a Python float: a numpy float64 would make the law float64
ARM = gv.paper_arm(tip_force=5.886)


def _release(T, delta, dtype):
    traj = gv.simulate(ARM, delta * T, n_steps=40, save_every=40, integrator="ars443", check_stability=False,
                       base_angle=lambda t: THETA_F * (t / T) ** 2, dtype=dtype)
    return traj.tip[-1], traj.q[-1]


def _float64_arrays(jaxpr) -> set:
    """(primitive, shape) of every strongly typed or non-scalar float64 value in a jaxpr, nested
    ones included. Weakly typed float64 scalars are Python-number parameters of the robot: they
    take the dtype of the arrays they meet."""
    found = set()
    for eqn in jaxpr.eqns:
        for v in eqn.outvars:
            aval = v.aval
            if getattr(aval, "dtype", None) in (jnp.float64, jnp.complex128) and (
                    not aval.weak_type or aval.shape):
                if eqn.primitive.name not in ("pjit", "jit", "scan", "while", "cond"):
                    found.add((eqn.primitive.name, aval.shape))
        for p in eqn.params.values():
            for sub in p if isinstance(p, (list, tuple)) else [p]:
                inner = getattr(sub, "jaxpr", sub)
                if hasattr(inner, "eqns"):
                    found |= _float64_arrays(inner)
    return found


def test_float32_throws_compute_in_float32_and_match_float64():
    """A batch of 64 throws (T in [0.5, 3] s, delta in [0.85, 1]): no float64 array anywhere in the
    float32 program, and its release positions within 0.05 mm of float64's at the same 40 steps
    (measured: max 4.2e-6 m, median 5.5e-7 m; the task's budget against a converged run is 1 mm)."""
    T = jnp.linspace(0.5, 3.0, 64)
    d = jnp.linspace(0.85, 1.0, 64)[::-1]
    args32 = (T.astype(jnp.float32), d.astype(jnp.float32))
    f32 = jax.jit(jax.vmap(lambda T, d: _release(T, d, jnp.float32))).trace(*args32)  # traced once
    assert _float64_arrays(f32.jaxpr.jaxpr) == set()
    tip32, q32 = f32.lower().compile()(*args32)
    tip64, q64 = jax.jit(jax.vmap(lambda T, d: _release(T, d, jnp.float64)))(T, d)
    assert tip32.dtype == q32.dtype == jnp.float32 and tip64.dtype == jnp.float64
    gap = np.max(np.linalg.norm(np.asarray(tip32, float) - np.asarray(tip64), axis=-1))
    assert gap < 5e-5, gap


@pytest.mark.parametrize("dtype", [jnp.float16, jnp.int32, "complex64", 64])
def test_unsupported_dtype_is_named(dtype):
    with pytest.raises(ValueError, match="dtype"):
        gv.simulate(ARM, 0.1, n_steps=2, dtype=dtype)


@pytest.mark.slow
@pytest.mark.extended
def test_basketball_with_a_float32_simulator_keeps_float64_states_and_the_outcome():
    """``sim_dtype="float32"`` (what ``gvsjax.train sim_dtype=float32`` trains on): the env's
    outputs and carried state keep their float64 dtypes (PPO's scans carry them), and the
    outcome is float64's to within fp32's share of the 1 mm budget."""
    from gvsjax.tasks import make

    key = jax.random.PRNGKey(0)
    keys = jax.random.split(key, 8)
    env = make("basketball")
    p64 = env.default_params()
    p32 = p64.replace(sim_dtype="float32")
    actions = jax.random.uniform(key, (8, 2), minval=-1.0, maxval=1.0)
    obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, p64)
    outs = [jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))(keys, state, actions, p) for p in (p64, p32)]
    for a, b in zip(jax.tree_util.tree_leaves(outs[0]), jax.tree_util.tree_leaves(outs[1])):
        assert a.dtype == b.dtype
    rewards = [np.asarray(o[2]) for o in outs]
    assert np.max(np.abs(rewards[0] - rewards[1])) < 2e-4  # exp(-2.2 cost), cost within 5e-5 m


@pytest.mark.slow
@pytest.mark.extended
def test_pickplace_with_a_float32_simulator_keeps_float64_states_and_the_outcome():
    from gvsjax.tasks import make
    from gvsjax.tasks import pickplace as pp

    keys = jax.random.split(jax.random.PRNGKey(0), 6)
    env = make("pickplace")
    P = pp.make_params(n_pairs=6, n_test=2, seed=3)
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))
    ends = []
    for p in (P, P.replace(sim_dtype="float32")):
        _, state = jax.vmap(env.reset_to, in_axes=(0, None))(jnp.stack([P.pick, P.place], 1), p)
        _, s1, _, _, info1 = step(keys, state, P.pick_action, p)
        _, s2, _, _, info2 = step(keys, s1, P.place_action, p)
        assert s1.q.dtype == s2.qd.dtype == jnp.float64
        ends.append((info1["distance"], info2["distance"]))
    # the table rows are exact in float64 (1e-9 m); float32 ends both steps within 0.05 mm
    assert np.max(np.asarray(ends[0])) < 1e-9 and np.max(np.asarray(ends[1])) < 5e-5
