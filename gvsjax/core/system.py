"""The equations the integrators step: free DoFs, with prescribed DoFs following a
time law and the inputs (tendon tensions, joint forces) following laws of time or
of the state.

``FreeDynamics`` offers the integrator interface (``accel``, ``parts``) on the
free coordinates u; the prescribed ones a follow ``motion(t)``, their velocity
and acceleration by forward-mode autodiff of the law. Because of that, a
prescribed law depends on time only: one depending on the state would make the
prescribed acceleration depend on the unknown one. Inputs may depend on the
state, ``(t, q, qd)`` with the full q and qd, and are evaluated at every stage
of the integrator (continuous feedback).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from gvsjax.core import active_strain, dynamics, lie
from gvsjax.core.model import Robot


@dataclass(frozen=True)
class Law:
    """A user's ``t -> values`` or, with ``state``, ``(t, q, qd) -> values`` callable of fixed size.

    Hashed by the function's identity, so repeated simulations with the same
    function reuse the compiled program.
    """

    fn: Callable
    size: int
    state: bool = False

    def __call__(self, t, q=None, qd=None):
        out = self.fn(t, q, qd) if self.state else self.fn(t)
        # in the simulation's dtype (that of t): a float64 law must not lift a float32 run
        return jnp.reshape(jnp.asarray(out).astype(jnp.result_type(t)), (self.size,))


def _vector(xs) -> jax.Array:
    return jnp.stack([lie.as_array(x) for x in xs])


class FreeDynamics:
    """The free DoFs' equations with the prescribed ones following ``motion``.

    ``tension``, ``joint_force``, ``wrench`` and ``strain_force`` are ``Law``-like
    callables ``(t, q, qd)`` (or None: zero); ``q``, ``qd`` are the full coordinate
    vectors. ``strain_force`` returns (n,), a generalized force added to F as it is
    (e.g. ``gvsjax.core.muscles``' moments mapped onto the strain coordinates); ``rest_strain``
    returns the values at ``robot.rest_strains``, added as ``B @ values``
    (``gvsjax.core.active_strain``; ``rest_map`` is B when already built).
    """

    def __init__(self, robot: Robot, motion: Callable, tension: Callable | None = None,
                 joint_force: Callable | None = None, wrench: Callable | None = None,
                 strain_force: Callable | None = None, rest_strain: Callable | None = None,
                 rest_map: jax.Array | None = None):
        self.robot, self.motion, self.tension, self.joint_force = robot, motion, tension, joint_force
        self.wrench, self.strain_force, self.rest_strain = wrench, strain_force, rest_strain
        # built once per program, outside the time loop
        self.rest_map = rest_map if rest_map is not None or rest_strain is None else active_strain.force_map(robot)
        self.a, self.u = robot.prescribed, robot.free

    def with_inputs(self, **laws: Callable | None) -> FreeDynamics:
        """The same system with some input laws replaced (a controller's held outputs)."""
        own = dict(tension=self.tension, joint_force=self.joint_force, wrench=self.wrench,
                   strain_force=self.strain_force, rest_strain=self.rest_strain)
        own.update(laws)
        rest_map = self.rest_map if own["rest_strain"] is not None else None
        if rest_map is None and own["rest_strain"] is not None:
            rest_map = active_strain.force_map(self.robot)
        return FreeDynamics(self.robot, self.motion, rest_map=rest_map, **own)

    def generalized_input(self, t, q, qd):
        """The inputs acting on the coordinates directly, (n,) or None: strain_force + B rest_strain."""
        tau = None
        if self.strain_force is not None or self.rest_strain is not None:
            qv, qdv = _vector(q), _vector(qd)
            if self.strain_force is not None:
                tau = self.strain_force(t, qv, qdv)
            if self.rest_strain is not None:
                assert self.rest_map is not None
                extra = self.rest_map.astype(qv.dtype) @ self.rest_strain(t, qv, qdv)
                tau = extra if tau is None else tau + extra
        return tau

    def prescribed_state(self, t):
        """q_a, qd_a, qdd_a at time t (derivatives of the law by autodiff)."""
        if not self.a:
            return (), (), ()
        first = lambda s: jax.jvp(self.motion, (s,), (jnp.ones_like(s),))  # noqa: E731
        (qa, qda), (_, qdda) = jax.jvp(first, (t,), (jnp.ones_like(t),))
        k = range(len(self.a))
        return [qa[i] for i in k], [qda[i] for i in k], [qdda[i] for i in k]

    def full_state(self, t, q_u, qd_u):
        """The full (q, qd) as lists of scalars and the prescribed accelerations."""
        qa, qda, qdda = self.prescribed_state(t)
        n = self.robot.n_dofs
        q, qd = [None] * n, [None] * n
        for k, i in enumerate(self.a):
            q[i], qd[i] = qa[k], qda[k]
        for k, i in enumerate(self.u):
            q[i], qd[i] = q_u[k], qd_u[k]
        return q, qd, qdda

    def inputs(self, t, q, qd) -> tuple[list, list, list]:
        """(tendon tensions, joint forces, wrenches) at (t, q, qd): lists of scalars, and of
        6-tuples for the wrenches; empty where no input is given."""
        n_t, n_j, n_w = len(self.robot.tendons), len(self.robot.actuated), len(self.robot.wrenches)
        given = [(law, n) for law, n in ((self.tension, n_t), (self.joint_force, n_j), (self.wrench, n_w))
                 if law is not None and n]
        qv, qdv = (_vector(q), _vector(qd)) if given else (None, None)
        T = self.tension(t, qv, qdv) if self.tension is not None and n_t else jnp.zeros(n_t, jnp.result_type(t))
        f = self.joint_force(t, qv, qdv) if self.joint_force is not None and n_j else None
        w = jnp.reshape(self.wrench(t, qv, qdv), (n_w, 6)) if self.wrench is not None and n_w else None
        return ([T[i] for i in range(n_t)], [] if f is None else [f[i] for i in range(n_j)],
                [] if w is None else [tuple(w[i, k] for k in range(6)) for i in range(n_w)])

    def _mf(self, t, q_u, qd_u):
        q, qd, qdda = self.full_state(t, q_u, qd_u)
        tension, force, wrench = self.inputs(t, q, qd)
        M, F = dynamics.mass_and_forces(self.robot, q, qd, tension, force, wrench, t)
        tau = self.generalized_input(t, q, qd)
        if tau is not None:
            F = [lie.add(f, tau[i]) for i, f in enumerate(F)]
        return q, qd, qdda, M, F

    def accel(self, t, q_u, qd_u):
        _, _, qdda, M, F = self._mf(t, q_u, qd_u)
        return tuple(lie.as_array(x) for x in dynamics.split_solve(self.robot, M, F, qdda))

    def parts(self, t, q_u, qd_u):
        """M_uu (lower triangle), f_u = F_u - M_ua qdd_a, K_uu, D_uu for IMEX."""
        _, _, qdda, M, F = self._mf(t, q_u, qd_u)
        a, u = self.a, self.u
        Mf = lambda i, j: M[i][j] if i >= j else M[j][i]  # noqa: E731
        f = [lie.sub(F[i], lie.total([lie.mul(Mf(i, k), x) for k, x in zip(a, qdda)])) for i in u]
        K, D = dynamics.stiffness_and_damping(self.robot)
        pick = lambda A: [[A[i][j] for j in u] for i in u]  # noqa: E731
        return [[Mf(i, j) for j in u] for i in u], f, pick(K), pick(D)

    def effort(self, t, q_u, qd_u):
        """Prescribed joints' effort (n_a,) by inverse dynamics."""
        q, qd, qdda, M, F = self._mf(t, q_u, qd_u)
        qdd_u = dynamics.split_solve(self.robot, M, F, qdda)
        qdd = [None] * self.robot.n_dofs
        for k, i in enumerate(self.a):
            qdd[i] = qdda[k]
        for k, i in enumerate(self.u):
            qdd[i] = qdd_u[k]
        tau = dynamics.prescribed_effort(self.robot, M, F, qdd)
        return jnp.stack([lie.as_array(x) for x in tau]) if tau else jnp.zeros((0,))
