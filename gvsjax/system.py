"""The equations the integrators step: free DoFs, with prescribed DoFs and tendon
tensions following time laws.

``FreeDynamics`` offers the integrator interface (``accel``, ``parts``) on the
free coordinates u; the prescribed ones a follow ``motion(t)``, their velocity
and acceleration by forward-mode autodiff of the law.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from gvsjax import dynamics, lie
from gvsjax.model import Robot


@dataclass(frozen=True)
class Law:
    """A user's t -> values callable of fixed output size.

    Hashed by the function's identity, so repeated simulations with the same
    function reuse the compiled program.
    """

    fn: Callable
    size: int

    def __call__(self, t):
        # in the simulation's dtype (that of t): a float64 law must not lift a float32 run
        return jnp.reshape(jnp.asarray(self.fn(t)).astype(jnp.result_type(t)), (self.size,))


class FreeDynamics:
    """The free DoFs' equations with the prescribed ones following ``motion``."""

    def __init__(self, robot: Robot, motion: Callable, tension: Callable | None):
        self.robot, self.motion, self.tension = robot, motion, tension
        self.a, self.u = robot.prescribed, robot.free

    def prescribed_state(self, t):
        """q_a, qd_a, qdd_a at time t (derivatives of the law by autodiff)."""
        if not self.a:
            return (), (), ()
        first = lambda s: jax.jvp(self.motion, (s,), (jnp.ones_like(s),))  # noqa: E731
        (qa, qda), (_, qdda) = jax.jvp(first, (t,), (jnp.ones_like(t),))
        k = range(len(self.a))
        return [qa[i] for i in k], [qda[i] for i in k], [qdda[i] for i in k]

    def _full(self, t, q_u, qd_u):
        qa, qda, qdda = self.prescribed_state(t)
        n = self.robot.n_dofs
        q, qd = [None] * n, [None] * n
        for k, i in enumerate(self.a):
            q[i], qd[i] = qa[k], qda[k]
        for k, i in enumerate(self.u):
            q[i], qd[i] = q_u[k], qd_u[k]
        return q, qd, qdda

    def _tension(self, t):
        if not self.robot.tendons:
            return ()
        T = jnp.atleast_1d(self.tension(t)) if self.tension is not None else jnp.zeros(len(self.robot.tendons))
        return [T[i] for i in range(len(self.robot.tendons))]

    def _mf(self, t, q_u, qd_u):
        q, qd, qdda = self._full(t, q_u, qd_u)
        M, F = dynamics.mass_and_forces(self.robot, q, qd, self._tension(t))
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
