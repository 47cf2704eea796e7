"""SAC for gvsjax tasks: ``config`` (hyperparameters), ``networks`` (the actor, the twin critics),
``losses`` (TD target, critic, actor and temperature losses), ``replay`` (the buffer), ``train``
(pure, jittable iterations). The command line runs it with ``algo=sac``."""

from gvsjax.sac.config import FIELD_DOCS, SACConfig, build_config, config_from_json, describe
from gvsjax.sac.losses import actor_loss, alpha_loss, critic_loss, td_target
from gvsjax.sac.networks import Actor, TwinCritic, make_actor, make_critic, squashed_sample
from gvsjax.sac.replay import Buffer, Transitions
from gvsjax.sac.train import SACState, gradient_step, init, iteration, make_update, num_updates, policy_action

__all__ = [
    "FIELD_DOCS", "SACConfig", "build_config", "config_from_json", "describe",
    "actor_loss", "alpha_loss", "critic_loss", "td_target",
    "Actor", "TwinCritic", "make_actor", "make_critic", "squashed_sample",
    "Buffer", "Transitions",
    "SACState", "gradient_step", "init", "iteration", "make_update", "num_updates", "policy_action",
]
