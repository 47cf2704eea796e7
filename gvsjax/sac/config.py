"""Typed, validated SAC hyperparameters.

``SACConfig`` is a frozen dataclass like ``gvsjax.ppo.PPOConfig``: every field has a one-line
help text (``FIELD_DOCS``), so the command line exposes it as a ``key=value`` override, and
construction raises a ``ValueError`` naming the field, the value and the allowed range.

Defaults: the soft-arm benchmark's SAC (Choi & Tong, arXiv 2511.06667, run with ALF): twin
critics, a tanh-squashed Gaussian actor with a state-dependent std, 3 x 256 layers with layer
normalisation, Adam at 1e-3, a soft target update (tau 0.005) every 8 gradient steps, an
automatically tuned entropy temperature with the target entropy log(0.1 x 2) per action
dimension, no entropy bonus in the critic's target, 4 gradient steps of 1024 samples per
iteration of ``num_envs`` environment steps. ``num_envs`` is 128 here, theirs 500: on two CPU
cores the gradient steps, not the simulation, bound an iteration (docs/tasks_benchmark.md).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from gvsjax.utils import keyvalue

_f = keyvalue.field


@dataclass(frozen=True)
class SACConfig:
    """SAC hyperparameters. See ``FIELD_DOCS`` (or each field's metadata) for meanings."""

    seed: int = _f(0, "PRNG seed for network init, exploration and replay sampling")
    num_envs: int = _f(128, "parallel environments; one iteration steps each once")
    total_episodes: int = _f(10_000, "training budget in episodes (x episode_length env steps)")
    buffer_size: int = _f(1_000_000, "replay capacity in transitions (oldest overwritten first)")
    batch_size: int = _f(1024, "transitions per gradient step")
    updates_per_iteration: int = _f(4, "gradient steps per iteration of num_envs env steps")
    learning_starts: int = _f(1000, "env steps of uniform random actions before the first gradient step")
    learning_rate: float = _f(1e-3, "Adam learning rate of the actor, the critics and the temperature")
    gamma: float = _f(0.99, "discount factor")
    tau: float = _f(0.005, "soft target update: target += tau (critic - target)")
    target_update_period: int = _f(8, "gradient steps between soft target updates")
    hidden: tuple[int, ...] = _f((256, 256, 256), "hidden sizes of the actor and of each critic")
    layer_norm: bool = _f(True, "layer normalisation after each hidden dense layer")
    init_log_alpha: float = _f(0.0, "initial log entropy temperature")
    target_entropy_per_dim: float = _f(
        math.log(0.2), "entropy the temperature steers the policy to, per action dimension "
        "(ALF's default: a density concentrated on 0.1 of the [-1, 1] range, log 0.2)")
    entropy_reward: bool = _f(False, "include -alpha log pi of the next action in the critic's target")
    min_log_std: float = _f(-10.0, "lower clip of the actor's log std (before the tanh)")
    max_log_std: float = _f(2.0, "upper clip of the actor's log std (before the tanh)")
    max_grad_norm: float = _f(math.inf, "global gradient-norm clip of each loss (inf disables)")

    def __post_init__(self) -> None:
        keyvalue.validate(self, _CHECKS)
        if self.batch_size > self.buffer_size:
            raise ValueError(f"batch_size={self.batch_size} is invalid; it must be <= buffer_size={self.buffer_size}")
        if self.num_envs > self.buffer_size:
            raise ValueError(f"num_envs={self.num_envs} is invalid; it must be <= buffer_size={self.buffer_size}")
        if self.min_log_std >= self.max_log_std:
            raise ValueError(f"min_log_std={self.min_log_std!r} is invalid; it must be < "
                             f"max_log_std={self.max_log_std!r}")

    def replace(self, **overrides: Any) -> SACConfig:
        """A copy with ``overrides`` applied and validated."""
        unknown = sorted(set(overrides) - set(FIELD_DOCS))
        if unknown:
            raise ValueError(f"unknown SACConfig key(s) {unknown}; valid keys: {sorted(FIELD_DOCS)}")
        return dataclasses.replace(self, **overrides)


FIELD_DOCS: dict[str, str] = keyvalue.field_docs(SACConfig)
"""Each ``SACConfig`` field's help text, by field name (what ``--help`` prints)."""


def _positive_int(v: Any) -> bool:
    return isinstance(v, int) and v >= 1


def _finite(v: float) -> bool:
    return math.isfinite(v)


_CHECKS: dict[str, tuple[Any, str]] = {
    "seed": (lambda v: 0 <= v < 2**63, "integer in [0, 2**63)"),
    "num_envs": (_positive_int, "integer >= 1"),
    "total_episodes": (_positive_int, "integer >= 1"),
    "buffer_size": (_positive_int, "integer >= 1"),
    "batch_size": (_positive_int, "integer >= 1"),
    "updates_per_iteration": (lambda v: v >= 0, "integer >= 0"),
    "learning_starts": (lambda v: v >= 0, "integer >= 0"),
    "learning_rate": (lambda v: _finite(v) and v > 0, "finite float > 0"),
    "gamma": (lambda v: 0.0 <= v < 1.0, "0 <= gamma < 1"),
    "tau": (lambda v: 0.0 < v <= 1.0, "0 < tau <= 1"),
    "target_update_period": (_positive_int, "integer >= 1"),
    "hidden": (lambda v: len(v) >= 1 and all(isinstance(h, int) and h >= 1 for h in v),
               "non-empty comma-separated positive integers, e.g. 256,256,256"),
    "init_log_alpha": (_finite, "finite float"),
    "target_entropy_per_dim": (_finite, "finite float"),
    "min_log_std": (_finite, "finite float"),
    "max_log_std": (_finite, "finite float"),
    "max_grad_norm": (lambda v: v > 0, "float > 0 (inf disables clipping)"),
}


def field_parsers() -> dict[str, Any]:
    """``{field: text -> value}`` for ``keyvalue.parse``."""
    return {name: (lambda text, name=name: keyvalue.parse_field(SACConfig, name, text)) for name in FIELD_DOCS}


def build_config(task_defaults: dict[str, Any], overrides: dict[str, Any]) -> SACConfig:
    """A task's SAC defaults, then the user's overrides (validated)."""
    return SACConfig().replace(**{**task_defaults, **overrides})


def config_from_json(d: dict, source: str = "config", ignore: tuple[str, ...] = ()) -> SACConfig:
    """SACConfig from a saved dict; keys in ``ignore`` (a run's own keys) are skipped, other
    unknown keys and invalid values raise ValueError naming ``source``."""
    if not isinstance(d, dict):
        raise ValueError(f"{source} is invalid: expected a JSON object of SACConfig fields")
    unknown = sorted(set(d) - set(FIELD_DOCS) - set(ignore))
    if unknown:
        raise ValueError(f"{source} has unknown key(s) {unknown}; valid keys: {sorted(FIELD_DOCS)}")
    fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items() if k in FIELD_DOCS}
    try:
        return SACConfig(**fields)
    except ValueError as e:
        raise ValueError(f"{source} is invalid: {e}") from None


def describe(config: SACConfig | None = None) -> str:
    """One line per field, ``key=value  help``, for a command line's ``--help``."""
    return keyvalue.describe_fields(config or SACConfig())
