"""Receding-horizon control through the simulator (model-predictive control).

At every control step the controller optimises the next ``horizon`` actions of each
episode on the task's own reward, simulated by ``env.step`` (and so by ``simulate``) from
the episode's current state, applies the first one, and warm-starts the next step from
the rest of the plan. Two planners: ``adam`` climbs the reward's gradient through the
simulator (projected onto the action box); ``mppi`` (model-predictive path integral)
samples perturbed plans around the current one and moves it to their average weighted by
exp(-cost / temperature), using forward simulations only, where a task's derivative is
too large a program to compile.
It is a reference a learned policy is measured against, and a baseline in its own
right:

    python -m gvsjax.evaluate task=NAME controller=mpc [horizon=10 iterations=10]
    python -m gvsjax.evaluate task=NAME controller=mpc planner=mppi [samples=64 noise=0.3]

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

from gvsjax.core import linalg
from gvsjax.core.validation import require
from gvsjax.tasks.base import Environment, PyTree

PLAN_SEED = 7  # the planner's own keys: it never sees the episode's random draws
# The gradient planner traces its model with stacked solves (from 1 DoF on): the entry-by-entry
# solve's transpose is the larger program, slower to compile and to run, on the balance arm
# (3 DoFs) and the benchmark arm (14) alike (experiments/benchmarks/bench_mpc_derivative.py)
DERIVATIVE_STACKED_MIN_DOFS = 1


@dataclasses.dataclass(frozen=True)
class MPCConfig:
    """The controller's settings.

    ``horizon``: actions optimised per control step; ``iterations``: updates of the plan per
    control step; ``planner``: "adam" (gradients) or "mppi" (sampling). For ``adam`` each
    iteration is one forward and one backward pass over the horizon; ``gradient``: "reverse"
    (``jax.grad``) or "forward" (``jax.jacfwd``: one tangent per planned action entry, horizon x
    action_size of them, which compiles and runs faster when that number is small, e.g. a
    single-input task); ``learning_rate``: Adam's
    step in action units (actions lie in [-1, 1]); ``discount``: the weight of step h's reward
    is ``discount**h``; ``sim_dtype``: the planner's simulation precision ("float32" or
    "float64"; the episode itself is simulated by the task's params). For ``mppi`` each
    iteration simulates ``samples`` plans: the current one and ``samples - 1`` perturbed by
    Gaussian noise of std ``noise`` (action units, clipped to the box); the new plan is their
    average weighted by exp(-(cost - min) / (temperature x s)), s the costs'
    root-mean-square distance from their minimum (so the weights do not depend on the reward's scale).
    """

    horizon: int = 10
    iterations: int = 10
    learning_rate: float = 0.1
    discount: float = 1.0
    gradient: str = "reverse"
    sim_dtype: str = ""
    planner: str = "adam"
    samples: int = 64
    noise: float = 0.3
    temperature: float = 0.1

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
        require(self.planner in ("adam", "mppi"), "planner", self.planner, "'adam' or 'mppi'")
        require(isinstance(self.samples, int) and 2 <= self.samples <= 100_000, "samples", self.samples,
                "an int in [2, 100000]")
        require(isinstance(self.noise, (int, float)) and 0 < self.noise <= 2, "noise", self.noise,
                "a number in (0, 2]")
        require(isinstance(self.temperature, (int, float)) and 0 < self.temperature <= 100, "temperature",
                self.temperature, "a number in (0, 100]")

    @property
    def passes_per_step(self) -> int:
        """Simulated control intervals per control step (adam: forward and backward passes counted
        apart; mppi: every sampled plan), the last plan's scoring left out."""
        if self.planner == "mppi":
            return self.samples * self.horizon * self.iterations
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
        if self.config.planner == "mppi":
            keys = jax.random.split(jax.random.fold_in(jax.random.PRNGKey(PLAN_SEED + 1), t), plan.shape[0])
            best = jax.vmap(self.sample)(plan, state, keys)
        else:
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
        with linalg.stacked_solves(DERIVATIVE_STACKED_MIN_DOFS):
            return self._optimise(plan, state)

    def _optimise(self, plan: jax.Array, state: PyTree) -> jax.Array:
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


    def sample(self, plan: jax.Array, state: PyTree, key: jax.Array) -> jax.Array:
        """The best plan (horizon, action_size) the MPPI iterations evaluated, from ``plan``."""
        c = self.config
        costs_of = jax.vmap(self.cost, in_axes=(0, None))

        def iteration(carry, k):
            a, best, best_cost = carry
            noise = c.noise * jax.random.normal(k, (c.samples - 1, *a.shape), a.dtype)
            plans = jnp.concatenate([a[None], jnp.clip(a + noise, -1.0, 1.0)])
            costs = costs_of(plans, state)
            finite = jnp.isfinite(costs)
            costs = jnp.where(finite, costs, jnp.inf)  # a diverged plan gets no weight
            i = jnp.argmin(costs)
            better = costs[i] < best_cost
            best, best_cost = jnp.where(better, plans[i], best), jnp.where(better, costs[i], best_cost)
            spread = jnp.sqrt(jnp.sum(jnp.where(finite, (costs - costs[i]) ** 2, 0.0)) / jnp.maximum(finite.sum(), 1))
            # scale-free weights: the temperature is a fraction of the sampled costs' spread
            w = jax.nn.softmax(jnp.where(finite, -(costs - costs[i]) / (c.temperature * spread + 1e-12), -jnp.inf))
            return (jnp.tensordot(w, plans, axes=1), best, best_cost), None

        plan = jnp.clip(plan, -1.0, 1.0)
        init = (plan, plan, jnp.asarray(jnp.inf, plan.dtype))
        (a, best, best_cost), _ = jax.lax.scan(iteration, init, jax.random.split(key, c.iterations))
        last = self.cost(a, state)
        return jnp.where(last < best_cost, a, best)


def describe(config: MPCConfig) -> dict[str, Any]:
    """The settings as a JSON-able dict (for eval.json)."""
    return {**dataclasses.asdict(config), "passes_per_step": config.passes_per_step}


__all__ = ["MPCConfig", "MPC", "describe"]
