"""PPO hyperparameters (gvsjax.ppo.config): validation naming the field, the ``key=value``
overrides, presets and a task's defaults in ``build_config``, and saved configs read back
by ``config_from_json`` (a garbled value names the key and the file, before anything compiles)."""

import dataclasses
import math

import pytest
from helpers import raises_naming
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gvsjax.ppo.config import (
    FIELD_DOCS,
    MATLAB_LIKE,
    PRESETS,
    PPOConfig,
    build_config,
    config_from_json,
    describe,
    from_overrides,
)

CHOICE_FIELDS = {"network": ("shared", "separate"), "activation": ("relu", "tanh"),
                 "std_mode": ("learned", "network")}


@pytest.mark.parametrize(
    "overrides, field",
    [
        (dict(num_envs=0), "num_envs"),
        (dict(num_envs=2.5), "num_envs"),
        (dict(num_steps=-1), "num_steps"),
        (dict(gamma=1.5), "gamma"),
        (dict(gae_lambda=-0.1), "gae_lambda"),
        (dict(clip_eps=0.0), "clip_eps"),
        (dict(learning_rate=float("nan")), "learning_rate"),
        (dict(network="lstm"), "network"),
        (dict(activation="gelu"), "activation"),
        (dict(std_mode="fixed"), "std_mode"),
        (dict(shared_hidden=()), "shared_hidden"),
        (dict(actor_hidden=(64, 0)), "actor_hidden"),
        (dict(finetune_fraction=1.5), "finetune_fraction"),
        (dict(anneal_lr="yes"), "anneal_lr"),
        (dict(num_envs=64, num_steps=4, num_minibatches=3), "num_minibatches"),
        (dict(init_log_std=-6.0, min_log_std=-5.0), "init_log_std"),
    ],
)
def test_config_rejects_bad_values_naming_the_field(overrides, field):
    with pytest.raises(ValueError, match=field):
        PPOConfig(**overrides)
    with pytest.raises(ValueError, match=field):
        PPOConfig().replace(**overrides)


def test_config_error_mentions_value_and_range():
    with pytest.raises(ValueError, match=r"gamma=1\.5.*0 <= gamma <= 1"):
        PPOConfig(gamma=1.5)
    with pytest.raises(ValueError, match=r"must divide num_envs\*num_steps=256"):
        PPOConfig(num_envs=64, num_steps=4, num_minibatches=3)


def test_config_is_frozen_documented_and_replace_validates():
    config = PPOConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.num_envs = 3  # type: ignore[misc]
    assert set(FIELD_DOCS) == {f.name for f in dataclasses.fields(PPOConfig)}
    assert all(FIELD_DOCS.values())
    assert "finetune_clip_eps=0.02" in describe(config)
    assert (config.learning_rate, config.clip_eps) == (1e-4, 0.1)
    assert (config.finetune_learning_rate, config.finetune_clip_eps) == (1e-5, 0.02)
    assert config.replace(num_envs=32).num_envs == 32
    assert config.replace(learning_rate=1).learning_rate == 1.0  # int widened to float
    with pytest.raises(ValueError, match="valid keys"):
        config.replace(nonsense=1)


def test_from_overrides_parses_each_type():
    config = from_overrides(
        PPOConfig(),
        [
            "num_envs=32", "total_episodes=1e5", "learning_rate=3e-4", "anneal_lr=true",
            "normalize_advantages=0", "network=separate", "actor_hidden=64,16",
            "shared_hidden=(32, 8)", "max_grad_norm=inf",
        ],
    )
    assert config.num_envs == 32 and isinstance(config.num_envs, int)
    assert config.total_episodes == 100_000
    assert config.learning_rate == 3e-4
    assert config.anneal_lr is True and config.normalize_advantages is False
    assert config.network == "separate"
    assert config.actor_hidden == (64, 16) and config.shared_hidden == (32, 8)
    assert config.max_grad_norm == math.inf


def test_from_overrides_errors():
    with pytest.raises(ValueError, match=r"unknown key 'lr'; valid keys: \[.*'learning_rate'"):
        from_overrides(PPOConfig(), ["lr=1e-3"])
    with pytest.raises(ValueError, match="num_envs='abc'"):
        from_overrides(PPOConfig(), ["num_envs=abc"])
    with pytest.raises(ValueError, match="anneal_lr"):
        from_overrides(PPOConfig(), ["anneal_lr=maybe"])
    with pytest.raises(ValueError, match="key=value"):
        from_overrides(PPOConfig(), ["num_envs"])
    with pytest.raises(ValueError, match="num_envs=0"):
        from_overrides(PPOConfig(), ["num_envs=0"])


def test_build_config_applies_task_defaults_then_preset_then_overrides():
    task = {"num_envs": 32, "learning_rate": 3e-3, "clip_eps": 0.3}
    config = build_config(task, "paper", {"clip_eps": 0.05})
    assert config.num_envs == 32  # the task's, untouched by the preset
    assert config.learning_rate == PRESETS["paper"]["learning_rate"]  # the preset over the task
    assert config.clip_eps == 0.05  # the user's over both
    assert build_config(task, "none", {}) == PPOConfig().replace(**task)
    assert build_config({}, "matlab", {}).std_mode == MATLAB_LIKE["std_mode"]
    with pytest.raises(ValueError, match=r"preset='fast' is unknown; choose one of \['matlab', 'none', 'paper'\]"):
        build_config(task, "fast", {})
    with pytest.raises(ValueError, match="num_envs=0"):
        build_config(task, "none", {"num_envs": 0})


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), name=st.sampled_from(sorted(FIELD_DOCS)))
def test_saved_config_with_a_garbled_value_names_the_key(data, name):
    value = data.draw(st.one_of(st.text(max_size=4), st.none(), st.just([[1]]), st.just({"x": 1}))
                      .filter(lambda v: not (isinstance(v, str) and name in CHOICE_FIELDS
                                             and v in CHOICE_FIELDS[name])))
    config = {**dataclasses.asdict(PPOConfig()), name: value}
    message = raises_naming(name, config_from_json, config, "the config saved in X")
    assert "saved in X" in message


def test_saved_config_unknown_key_or_not_an_object():
    raises_naming("bogus", config_from_json, {"bogus": 1})
    raises_naming("JSON object", config_from_json, [1, 2])
    assert config_from_json({"task": "basketball", "preset": "paper"}) == PPOConfig()
    saved = {"task": "basketball", "train_targets": "", "sim_dtype": "float64",
             **dataclasses.asdict(PPOConfig(shared_hidden=(64, 8)))}  # tuples saved as JSON lists
    saved["shared_hidden"] = list(saved["shared_hidden"])
    assert config_from_json(saved) == PPOConfig(shared_hidden=(64, 8))
