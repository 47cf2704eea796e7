"""Receding-horizon control by gradients through the simulator (model-predictive control).

At every control step the controller optimises the next ``horizon`` actions of each
episode by Adam on the task's own reward, differentiated through ``env.step`` (and so
through ``simulate``) from the episode's current state, projects them onto the action
box, applies the first one, and warm-starts the next step from the rest of the plan.
It is a reference a learned policy is measured against, and a baseline in its own
right:

    python -m gvsjax.evaluate task=NAME controller=mpc [horizon=10 iterations=10]

The planner sees the environment's full state (``q``, ``qd``, the target), and models
the world by ``env.planning_params(params)``: the task's params with what the
controller cannot know removed (e.g. the moving target's random turns), simulated in
``MPCConfig.sim_dtype`` (by default the precision the task trains in). Gradients of
the reward's piecewise-constant bonuses are zero; the planner climbs the smooth part
(``-d^2`` and the like), and keeps the best plan it evaluated, so a bonus it reached is
not lost.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import optax

from gvsjax.core.validation import require
from gvsjax.tasks.base import Environment, PyTree

PLAN_SEED = 7  # the planner's own keys: it never sees the episode's random draws


@dataclasses.dataclass(frozen=True)
class MPCConfig:
    """The controller's settings.

    ``horizon``: actions optimised per control step; ``iterations``: Adam steps per control
    step (each one forward and one backward pass over the horizon); ``gradient``: "reverse"
    (``jax.grad``) or "forward" (``jax.jacfwd``: one tangent per planned action entry, horizon x
    action_size of them, which compiles and runs faster when that number is small, e.g. a
    single-input task); ``learning_rate``: Adam's
    step in action units (actions lie in [-1, 1]); ``discount``: the weight of step h's reward
    is ``discount**h``; ``sim_dtype``: the planner's simulation precision ("float32" or
    "float64"; the episode itself is simulated by the task's params).
    """

    horizon: int = 10
    iterations: int = 10
    learning_rate: float = 0.1
    discount: float = 1.0
    gradient: str = "reverse"
    sim_dtype: str = ""

    def __post_init__(self):
        require(isinstance(self.horizon, int) and 1 <= self.horizon <= 1000, "horizon", self.horizon,
                "an int in [1, 1000]")
        require(isinstance(self.iterations, int) and 1 <= self.iterations <= 10_000, "iterations", self.iterations,
                "an int in [1, 10000]")
        require(isinstance(self.learning_rate, (int, float)) and 0 < self.learning_rate <= 10, "learning_rate",
                self.learning_rate, "a number in (0, 10]")
        require(isinstance(self.discount, (int, float)) and 0 < self.discount <= 1, "discount", self.discount,
                "a number in (0, 1]")
        require(self.gradient in ("reverse", "forward"), "gradient", self.gradient, "'reverse' or 'forward'")
        require(self.sim_dtype in ("", "float32", "float64"), "sim_dtype", self.sim_dtype,
                "'float32', 'float64' or '' (the task's training precision)")

    @property
    def passes_per_step(self) -> int:
        """Simulated control intervals per control step, forward and backward counted apart."""
        return 2 * self.horizon * self.iterations


class MPC:
    """A gradient-based receding-horizon controller of ``env`` with ``params``.

    It is a ``gvsjax.tasks.base.Controller``: ``init(obs, state)`` gives the batched warm
    start (zero plans), ``act(plan, obs, state, t)`` the batched actions and the next warm
    start. ``env.evaluate(params, MPC(env, params), n, seed)`` scores it like a policy.
    """

    def __init__(self, env: Environment, params: PyTree, config: MPCConfig | None = None):
        self.env = env
        self.config = config or MPCConfig()
        self.model = env.with_sim_dtype(env.planning_params(params), self.config.sim_dtype or env.train_sim_dtype)

    def init(self, obs: jax.Array, state: PyTree) -> jax.Array:
        """Zero plans, (batch, horizon, action_size)."""
        return jnp.zeros((obs.shape[0], self.config.horizon, self.env.action_size), obs.dtype)

    def act(self, plan: jax.Array, obs: jax.Array, state: PyTree, t: jax.Array) -> tuple[jax.Array, jax.Array]:
        """``(actions (batch, action_size), next warm start)`` from the states (batched)."""
        best = jax.vmap(self.optimise)(plan, state)
        return best[:, 0], jnp.concatenate([best[:, 1:], best[:, -1:]], axis=1)

    def cost(self, actions: jax.Array, state: PyTree) -> jax.Array:
        """Minus the discounted reward of ``actions`` (horizon, action_size) from one ``state``."""
        env, model = self.env, self.model
        keys = jax.random.split(jax.random.PRNGKey(PLAN_SEED), actions.shape[0])

        def one(s, xs):
            a, k = xs
            _, s, r, _, _ = env.step(k, s, a, model)
            return s, r

        _, rewards = jax.lax.scan(one, state, (actions, keys))
        weights = self.config.discount ** jnp.arange(actions.shape[0])
        return -jnp.sum(weights * rewards)

    def optimise(self, plan: jax.Array, state: PyTree) -> jax.Array:
        """The best plan (horizon, action_size) found by projected Adam from ``plan``."""
        opt = optax.adam(self.config.learning_rate)
        if self.config.gradient == "forward":
            value_and_grad = lambda a, s: (self.cost(a, s), jax.jacfwd(self.cost)(a, s))  # noqa: E731
        else:
            value_and_grad = jax.value_and_grad(self.cost)

        def iteration(carry, _):
            a, opt_state, best, best_cost = carry
            c, g = value_and_grad(a, state)
            g = jnp.where(jnp.isfinite(g), g, 0.0)
            better = c < best_cost  # NaN compares False: a diverged plan is never kept
            best, best_cost = jnp.where(better, a, best), jnp.where(better, c, best_cost)
            step, opt_state = opt.update(g, opt_state)
            return (jnp.clip(a + step, -1.0, 1.0), opt_state, best, best_cost), None

        plan = jnp.clip(plan, -1.0, 1.0)
        init = (plan, opt.init(plan), plan, jnp.asarray(jnp.inf, plan.dtype))
        (a, _, best, best_cost), _ = jax.lax.scan(iteration, init, None, length=self.config.iterations)
        # the last iterate is scored too: one more forward pass
        last = self.cost(a, state)
        return jnp.where(last < best_cost, a, best)


def describe(config: MPCConfig) -> dict[str, Any]:
    """The settings as a JSON-able dict (for eval.json)."""
    return {**dataclasses.asdict(config), "passes_per_step": config.passes_per_step}


__all__ = ["MPCConfig", "MPC", "describe"]
