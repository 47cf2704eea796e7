"""Typed, validated PPO hyperparameters.

``PPOConfig`` is a frozen dataclass; every field carries a one-line help text
(``FIELD_DOCS``) so a command line can expose it as a ``key=value`` override.
Construction validates every field and raises a ``ValueError`` naming the
field, the offending value and the allowed range.

Defaults: the paper's two-phase schedule (phase 1: lr 1e-4, clip 0.1; phase 2,
"fine-tuning": lr 1e-5, clip 0.02) on top of otherwise modern PPO settings
(PureJaxRL/CleanRL: advantage normalisation, grad-norm clipping, orthogonal
init, state-independent log-std). ``MATLAB_LIKE`` lists the overrides that
approximate MATLAB's ``rlPPOAgent`` as the paper used it. ``PRESETS`` are named
override sets for the command line; ``config_from_json`` reads a saved config back.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from gvsjax.utils import keyvalue

_f = keyvalue.field


@dataclass(frozen=True)
class PPOConfig:
    """PPO hyperparameters. See ``FIELD_DOCS`` (or each field's metadata) for meanings."""

    seed: int = _f(0, "PRNG seed for network init, rollouts and minibatch shuffling")
    num_envs: int = _f(64, "parallel environments per rollout")
    num_steps: int = _f(4, "env steps per environment per update (rollout length)")
    total_episodes: int = _f(100_000, "training budget in episodes; sets the number of updates")
    update_epochs: int = _f(4, "passes over each rollout batch per update")
    num_minibatches: int = _f(4, "minibatches per epoch; must divide num_envs*num_steps")
    gamma: float = _f(0.99, "discount factor")
    gae_lambda: float = _f(0.95, "GAE lambda")
    clip_eps: float = _f(0.1, "PPO ratio clip in phase 1 (paper: 0.1)")
    clip_value_loss: bool = _f(False, "clip the value update to +-clip_eps around the old value")
    vf_coef: float = _f(0.5, "value-loss coefficient")
    ent_coef: float = _f(0.01, "entropy-bonus coefficient")
    max_grad_norm: float = _f(0.5, "global gradient-norm clip (inf disables)")
    target_kl: float = _f(
        math.inf, "skip an update's remaining epochs once an epoch's mean approx KL exceeds "
        "1.5 x target_kl (inf: never)")
    adaptive_kl: float = _f(
        math.inf, "KL-adaptive learning rate (rsl_rl style): after an update whose mean approx KL "
        "exceeds 2 x adaptive_kl the rate is divided by 1.5, below adaptive_kl/2 multiplied by 1.5, "
        "never above the phase's (annealed) rate (inf: off)")
    l2_coef: float = _f(0.0, "L2 regularisation added to gradients (MATLAB default 1e-4)")
    learning_rate: float = _f(1e-4, "Adam learning rate in phase 1 (paper: 1e-4)")
    anneal_lr: bool = _f(False, "scale the phase's lr by 1 - update/num_updates")
    normalize_advantages: bool = _f(True, "normalise advantages per minibatch")
    network: str = _f("shared", "actor-critic layout: 'shared' trunk or 'separate' MLPs")
    shared_hidden: tuple[int, ...] = _f((128, 32, 16), "hidden sizes of the shared trunk")
    actor_hidden: tuple[int, ...] = _f((128, 32), "hidden sizes of the separate actor")
    critic_hidden: tuple[int, ...] = _f((128, 32), "hidden sizes of the separate critic")
    activation: str = _f("relu", "hidden activation: 'relu' or 'tanh'")
    std_mode: str = _f("learned", "'learned' state-independent log-std or 'network' head (MATLAB)")
    init_log_std: float = _f(-0.5, "initial log standard deviation of the Gaussian policy")
    min_log_std: float = _f(-5.0, "floor on the log standard deviation")
    finetune_fraction: float = _f(0.2, "fraction of total_episodes spent in phase 2 (fine-tuning)")
    finetune_learning_rate: float = _f(1e-5, "Adam learning rate in phase 2 (paper: 1e-5)")
    finetune_clip_eps: float = _f(0.02, "PPO ratio clip in phase 2 (paper: 0.02)")
    clipped_log_prob: bool = _f(
        False, "log-probabilities of the actions the env plays (clipped to [-1, 1]): a sample beyond "
        "a bound counts with the mass beyond it (Fujita & Maeda 2018, clipped action policy gradient)")
    stagger_starts: bool = _f(
        False, "cut each env's first episode after a random number of steps in [1, episode_length], "
        "so that every rollout holds all phases of the episode rather than the same phase in "
        "every env (rsl_rl's random initial episode length; for episodes much longer than num_steps)")
    antithetic: bool = _f(
        False, "pair env i with env i + num_envs/2: same reset keys (targets) and mirrored "
        "action noise +-eps, kept in one minibatch; a pair's policy gradient then does not "
        "depend on the critic's error (exact for single-step tasks)")

    def __post_init__(self) -> None:
        keyvalue.validate(self, _CHECKS)
        batch = self.num_envs * self.num_steps
        if self.antithetic:
            if self.num_envs % 2:
                raise ValueError(f"num_envs={self.num_envs} is invalid with antithetic=True; "
                                 "it must be even (envs come in mirrored pairs)")
            if (batch // 2) % self.num_minibatches:
                raise ValueError(
                    f"num_minibatches={self.num_minibatches} is invalid with antithetic=True; "
                    f"it must divide the number of pairs num_envs*num_steps/2={batch // 2}")
        if batch % self.num_minibatches:
            raise ValueError(
                f"num_minibatches={self.num_minibatches} is invalid; it must divide "
                f"num_envs*num_steps={batch}"
            )
        if self.init_log_std < self.min_log_std:
            raise ValueError(
                f"init_log_std={self.init_log_std!r} is invalid; it must be >= "
                f"min_log_std={self.min_log_std!r}"
            )

    def replace(self, **overrides: Any) -> PPOConfig:
        """A copy with ``overrides`` applied and validated."""
        unknown = sorted(set(overrides) - set(FIELD_DOCS))
        if unknown:
            raise ValueError(
                f"unknown PPOConfig key(s) {unknown}; valid keys: {sorted(FIELD_DOCS)}"
            )
        return dataclasses.replace(self, **overrides)


FIELD_DOCS: dict[str, str] = keyvalue.field_docs(PPOConfig)
"""Each ``PPOConfig`` field's help text, by field name (what ``--help`` prints)."""

# Overrides approximating MATLAB rlPPOAgentOptions as the paper used them (its toolbox
# defaults where the paper is silent); use as ``PPOConfig().replace(**MATLAB_LIKE)``.
MATLAB_LIKE: dict[str, Any] = dict(
    update_epochs=3,
    normalize_advantages=False,
    max_grad_norm=math.inf,
    l2_coef=1e-4,
    std_mode="network",
    network="separate",
)
"""Overrides approximating MATLAB's ``rlPPOAgent`` as the paper used it: ``PPOConfig().replace(**MATLAB_LIKE)``."""


def _positive_int(v: Any) -> bool:
    return isinstance(v, int) and v >= 1


def _sizes(v: Any) -> bool:
    return len(v) >= 1 and all(isinstance(h, int) and h >= 1 for h in v)


def _finite(v: float) -> bool:
    return math.isfinite(v)


_CHECKS: dict[str, tuple[Any, str]] = {
    "seed": (lambda v: 0 <= v < 2**63, "integer in [0, 2**63)"),
    "num_envs": (_positive_int, "integer >= 1"),
    "num_steps": (_positive_int, "integer >= 1"),
    "total_episodes": (_positive_int, "integer >= 1"),
    "update_epochs": (_positive_int, "integer >= 1"),
    "num_minibatches": (_positive_int, "integer >= 1"),
    "gamma": (lambda v: 0.0 <= v <= 1.0, "0 <= gamma <= 1"),
    "gae_lambda": (lambda v: 0.0 <= v <= 1.0, "0 <= gae_lambda <= 1"),
    "clip_eps": (lambda v: _finite(v) and v > 0, "finite float > 0"),
    "vf_coef": (lambda v: _finite(v) and v >= 0, "finite float >= 0"),
    "ent_coef": (lambda v: _finite(v) and v >= 0, "finite float >= 0"),
    "max_grad_norm": (lambda v: v > 0, "float > 0 (inf disables clipping)"),
    "target_kl": (lambda v: v > 0, "float > 0 (inf disables the early stop)"),
    "adaptive_kl": (lambda v: v > 0, "float > 0 (inf disables the adaptation)"),
    "l2_coef": (lambda v: _finite(v) and v >= 0, "finite float >= 0"),
    "learning_rate": (lambda v: _finite(v) and v > 0, "finite float > 0"),
    "network": (lambda v: v in ("shared", "separate"), "'shared' or 'separate'"),
    "shared_hidden": (_sizes, "non-empty comma-separated positive integers, e.g. 128,32,16"),
    "actor_hidden": (_sizes, "non-empty comma-separated positive integers, e.g. 128,32"),
    "critic_hidden": (_sizes, "non-empty comma-separated positive integers, e.g. 128,32"),
    "activation": (lambda v: v in ("relu", "tanh"), "'relu' or 'tanh'"),
    "std_mode": (lambda v: v in ("learned", "network"), "'learned' or 'network'"),
    "init_log_std": (_finite, "finite float"),
    "min_log_std": (_finite, "finite float"),
    "finetune_fraction": (lambda v: 0.0 <= v <= 1.0, "0 <= finetune_fraction <= 1"),
    "finetune_learning_rate": (lambda v: _finite(v) and v > 0, "finite float > 0"),
    "finetune_clip_eps": (lambda v: _finite(v) and v > 0, "finite float > 0"),
}


def parse_value(name: str, text: str) -> Any:
    """Parse the string ``text`` to the type of field ``name`` (no range checks)."""
    return keyvalue.parse_field(PPOConfig, name, text)


def field_parsers() -> dict[str, Any]:
    """``{field: text -> value}`` for ``keyvalue.parse``."""
    return {name: (lambda text, name=name: parse_value(name, text)) for name in FIELD_DOCS}


def from_overrides(base: PPOConfig, overrides: Iterable[str]) -> PPOConfig:
    """``base`` with ``["key=value", ...]`` applied and validated.

    Example: ``from_overrides(PPOConfig(), ["num_envs=32", "shared_hidden=64,16"])``.
    """
    return base.replace(**keyvalue.parse(overrides, field_parsers()))


# Named override sets applied before a command line's own overrides.
PRESETS: dict[str, dict[str, Any]] = {
    "none": {},
    # the paper's two phases: lr 1e-4 / clip 0.1, then fine-tuning at 1e-5 / 0.02
    "paper": dict(learning_rate=1e-4, clip_eps=0.1, finetune_learning_rate=1e-5,
                  finetune_clip_eps=0.02, finetune_fraction=0.3, anneal_lr=False),
    "matlab": {**MATLAB_LIKE, "learning_rate": 1e-4, "clip_eps": 0.1},
}
"""Named groups of ``PPOConfig`` overrides, chosen by ``preset=NAME`` on the command line."""


def build_config(task_defaults: dict[str, Any], preset: str, overrides: dict[str, Any]) -> PPOConfig:
    """A task's defaults, then the preset, then the user's overrides (validated)."""
    if preset not in PRESETS:
        raise ValueError(f"preset={preset!r} is unknown; choose one of {sorted(PRESETS)}")
    return PPOConfig().replace(**{**task_defaults, **PRESETS[preset], **overrides})


# keys a run's saved config holds beside the PPOConfig fields
RUN_KEYS = ("task", "preset", "train_targets", "sim_dtype", "randomize", "randomize_observe", "algo")


def config_from_json(d: dict, source: str = "config") -> PPOConfig:
    """PPOConfig from a saved dict (the ``RUN_KEYS`` are ignored; other unknown keys and
    invalid values raise ValueError naming ``source``)."""
    if not isinstance(d, dict):
        raise ValueError(f"{source} is invalid: expected a JSON object of PPOConfig fields, "
                         f"got {type(d).__name__}")
    unknown = sorted(set(d) - set(FIELD_DOCS) - set(RUN_KEYS))
    if unknown:
        raise ValueError(f"{source} has unknown key(s) {unknown}; valid keys: {sorted(FIELD_DOCS)}")
    d = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items() if k in FIELD_DOCS}
    try:
        return PPOConfig(**d)
    except ValueError as e:
        raise ValueError(f"{source} is invalid: {e}") from None


def describe(config: PPOConfig | None = None) -> str:
    """One line per field, ``key=value  help``, for a command line's ``--help``."""
    return keyvalue.describe_fields(config or PPOConfig())
