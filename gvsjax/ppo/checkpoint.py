"""Checkpoints: flax.serialization bytes, written atomically, with a checksum; and
``load_policy``, a trained policy back from a checkpoint.

File layout (msgpack): ``{"format": FORMAT, "sha256": hex, "payload": bytes}``
where ``payload`` is itself msgpack of ``{"train_state": flax to_bytes(state),
"config": JSON str, "task": str, "step": int, "extra": dict}``. Writing goes to a
temporary file in the same folder, is fsync'ed, then ``os.replace``d over the
target, so a crash never leaves a half-written checkpoint under the real name.
A truncated or altered file raises ``CheckpointError`` naming the file.
With several processes (``gvsjax.utils.distributed``) ``save`` is collective: the
state is gathered whole, process 0 writes, and every process returns once the
file is in place; ``load`` then reads the same file on every process.

PRNG keys: typed keys (``jax.random.key``) are stored as their raw key data
and re-wrapped on load; legacy uint32 keys are stored as they are.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
from flax import serialization

from gvsjax import sac
from gvsjax.ppo.config import RUN_KEYS, config_from_json
from gvsjax.ppo.networks import make_network
from gvsjax.ppo.rollout import policy_action
from gvsjax.ppo.train import init
from gvsjax.tasks import make
from gvsjax.tasks.randomized import wrap
from gvsjax.utils import distributed

FORMAT = "gvsjax-checkpoint-v1"


class CheckpointError(RuntimeError):
    """A checkpoint file is missing, truncated, corrupted or of another format."""


def _is_typed_key(x) -> bool:
    return isinstance(x, jax.Array) and jnp.issubdtype(x.dtype, jax.dtypes.prng_key)


def _raw(tree):
    return jax.tree.map(lambda x: jax.random.key_data(x) if _is_typed_key(x) else x, tree)


def write_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` via a fsync'ed temp file and ``os.replace``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    try:  # make the rename itself durable
        dir_fd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
    except OSError:
        pass


def save(path, train_state, config: dict, task: str, step: int, extra: dict | None = None) -> None:
    """Save ``train_state`` (any pytree) with its config (JSON-able dict) atomically.

    Several processes: every one calls it; process 0 writes the gathered state.
    """
    whole = distributed.fetch(_raw(train_state))  # collective when split over processes
    if distributed.is_main():
        _write(path, whole, config, task, step, extra)
    distributed.barrier(f"checkpoint {step}")  # nobody reads it before it is there


def _write(path, train_state, config: dict, task: str, step: int, extra: dict | None) -> None:
    payload = serialization.msgpack_serialize({
        "train_state": serialization.to_bytes(train_state),
        "config": json.dumps(config),  # JSON: msgpack here cannot hold tuples
        "task": task,
        "step": int(step),
        "extra": json.dumps(extra or {}),
    })
    blob = serialization.msgpack_serialize({
        "format": FORMAT, "sha256": hashlib.sha256(payload).hexdigest(), "payload": payload,
    })
    write_atomic(path, blob)


FILE_NAME = "checkpoint.ckpt"  # the checkpoint's name inside a run folder


def resolve(path) -> Path:
    """A checkpoint file from a file path or a run folder (which holds ``FILE_NAME``)."""
    path = Path(path)
    if path.is_dir():
        if not (path / FILE_NAME).is_file():
            raise CheckpointError(f"checkpoint {str(path)!r} is a folder without {FILE_NAME}: "
                                  "give a run folder or a checkpoint file")
        return path / FILE_NAME
    return path


def load_raw(path) -> dict:
    """The checked payload: ``{"train_state": bytes, "config", "task", "step", "extra"}``.

    ``path`` is a checkpoint file or a run folder holding one.
    """
    path = resolve(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {str(path)!r} does not exist")
    try:
        data = path.read_bytes()
    except OSError as e:
        raise CheckpointError(f"checkpoint {str(path)!r} cannot be read: {e}") from None
    bad = CheckpointError(
        f"checkpoint {str(path)!r} is truncated, corrupted or not a {FORMAT} file ({len(data)} bytes)"
    )
    try:
        outer = serialization.msgpack_restore(data)
    except Exception:  # msgpack raises several types on truncated input
        raise bad from None
    if not (isinstance(outer, dict) and outer.get("format") == FORMAT
            and isinstance(outer.get("payload"), bytes) and isinstance(outer.get("sha256"), str)):
        raise bad
    if hashlib.sha256(outer["payload"]).hexdigest() != outer["sha256"]:
        raise CheckpointError(f"checkpoint {str(path)!r} is corrupted: checksum mismatch")
    try:  # the checksum matched: only a writer bug could make the rest fail
        raw = serialization.msgpack_restore(outer["payload"])
        raw["config"], raw["extra"] = json.loads(raw["config"]), json.loads(raw["extra"])
        ok = (isinstance(raw["train_state"], bytes) and isinstance(raw["config"], dict)
              and isinstance(raw["task"], str) and isinstance(raw["step"], int))
    except Exception:
        ok = False
    if not ok:
        raise CheckpointError(f"checkpoint {str(path)!r} has a malformed payload")
    return raw


def restore_state(template, state_bytes: bytes, field: str | None = None):
    """Fill ``template`` (a pytree of the right structure) from saved state bytes, or, given
    ``field``, from that field of the saved state alone (e.g. ``"params"``).

    A saved state of another structure or shape (e.g. another ``num_envs`` or
    network size) raises ``CheckpointError`` instead of loading a mix.
    """
    try:
        if field is None:
            restored = serialization.from_bytes(_raw(template), state_bytes)
        else:
            restored = serialization.from_state_dict(_raw(template), serialization.msgpack_restore(state_bytes)[field])
    except Exception as e:  # flax raises ValueError/KeyError on a structure mismatch
        raise CheckpointError(f"the checkpoint's state does not match this configuration: {e}") from None
    for (where, t), r in zip(jax.tree_util.tree_leaves_with_path(_raw(template)), jax.tree.leaves(restored)):
        if jnp.shape(t) != jnp.shape(r):
            raise CheckpointError(
                f"the checkpoint's state does not match this configuration: "
                f"{jax.tree_util.keystr(where)} has shape {jnp.shape(r)}, expected {jnp.shape(t)}"
            )
    return jax.tree.map(
        lambda t, r: jax.random.wrap_key_data(r, impl=jax.random.key_impl(t))
        if _is_typed_key(t) else jnp.asarray(r, dtype=jnp.asarray(t).dtype),
        template, restored,
    )


def remove_stale_temps(path) -> list[Path]:
    """Delete temp files a killed ``write_atomic`` left next to ``path``; returns them."""
    path = Path(path)
    stale = sorted(path.parent.glob(f".{path.name}.*.tmp"))
    for p in stale:
        p.unlink(missing_ok=True)
    return stale


def load(path, template) -> tuple[Any, dict]:
    """``(train_state, meta)``; ``meta`` holds config, task, step and extra."""
    raw = load_raw(path)
    state = restore_state(template, raw.pop("train_state"))
    return state, raw


def load_policy(path):
    """``(config, env, env_params, network params)`` of a training checkpoint (file or run folder).

    ``env_params`` are the task's ``default_params()``, the evaluation distribution. A run
    trained with ``randomize=`` gives its ``Randomized`` env, whose ``evaluate`` is the task's
    on the nominal model (``gvsjax.tasks.randomized.nominal`` gives the task and a policy of its
    observations). Only the network params are restored, so a policy stays loadable when the
    env's internal state (saved for resuming) gains a field; its observations must not change.
    A run trained with ``algo=sac`` gives a ``gvsjax.sac.SACConfig`` and the actor's params.
    """
    meta = load_raw(path)
    sac_run = meta["config"].get("algo", "ppo") == "sac"
    source = f"the config saved in {path}"
    config: Any = (sac.config_from_json(meta["config"], source, RUN_KEYS) if sac_run
                   else config_from_json(meta["config"], source))
    env = wrap(make(meta["task"]), meta["config"].get("randomize", ""),
               meta["config"].get("randomize_observe", False))
    env_params = env.default_params()
    start = sac.init if sac_run else init
    template = jax.eval_shape(lambda: start(config, env, env_params, jax.random.PRNGKey(0)))
    template = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), template.params)
    params = restore_state(template, meta["train_state"], "params")  # CheckpointError if mismatched
    return config, env, env_params, params["actor"] if sac_run else params


def make_policy(config, action_size: int, net_params):
    """The deterministic policy as ``obs (n, k) -> actions (n, a)``: the Gaussian's mean, clipped
    (PPO), or its tanh (SAC: ``config`` a ``SACConfig``, ``net_params`` the actor's)."""
    if isinstance(config, sac.SACConfig):
        actor = sac.make_actor(config, action_size).apply
        return lambda obs: sac.policy_action(net_params, actor, obs).astype(jnp.float64)
    apply_fn = make_network(config, action_size).apply
    return lambda obs: policy_action(net_params, apply_fn, obs.astype(jnp.float32)).astype(jnp.float64)
