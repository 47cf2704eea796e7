"""PPO for gvsjax tasks: ``config`` (hyperparameters, presets), ``networks`` (actor-critics),
``losses`` (GAE and the clipped objective), ``rollout`` (collecting experience),
``train`` (pure, jittable updates),
``checkpoint`` (atomic checkpoints, ``load_policy``)."""

from gvsjax.ppo.checkpoint import CheckpointError, load_policy, make_policy
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
from gvsjax.ppo.losses import (
    Batch,
    clipped_gaussian_log_prob,
    gae,
    gaussian_entropy,
    gaussian_log_prob,
    ppo_loss,
)
from gvsjax.ppo.networks import SeparateActorCritic, SharedActorCritic, make_network
from gvsjax.ppo.rollout import Rollout, TrainState, collect, episode_metrics, place, policy_action
from gvsjax.ppo.train import (
    finetune_start,
    init,
    make_train,
    make_update,
    num_updates,
    phase_hyperparams,
    update,
)

__all__ = [
    "CheckpointError", "load_policy", "make_policy",
    "FIELD_DOCS", "MATLAB_LIKE", "PRESETS", "PPOConfig", "build_config", "config_from_json", "describe",
    "from_overrides",
    "Batch", "clipped_gaussian_log_prob", "gae", "gaussian_entropy", "gaussian_log_prob", "ppo_loss",
    "SeparateActorCritic", "SharedActorCritic", "make_network",
    "TrainState", "Rollout", "collect", "episode_metrics", "finetune_start", "init", "make_train",
    "make_update", "num_updates", "phase_hyperparams", "place", "policy_action", "update",
]
