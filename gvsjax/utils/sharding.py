"""Scale-out: split a batch of environments or simulations over all JAX devices.

Nothing to do for the user: with more than one device (GPUs, TPU cores, or
CPU devices from ``XLA_FLAGS=--xla_force_host_platform_device_count=N``),
PPO training (``gvsjax.ppo``) shards its ``num_envs`` axis over a 1-D
``Mesh`` of ``jax.devices()`` and replicates the network; with one device
every function here is a no-op. ``batched`` does the same for any batched
simulation:

    import gvsjax as gv
    from gvsjax.utils.sharding import batched

    arm = gv.paper_arm(tip_force=5.886)

    def release_tip(T, delta):
        law = lambda t: 3.665 * (t / T) ** 2
        return gv.simulate(arm, delta * T, n_steps=300, save_every=300, base_angle=law).tip[-1]

    tips = batched(release_tip)(jnp.linspace(0.5, 3, 4096), jnp.full(4096, 0.9))

The mesh uses as many devices as divide the batch (``num_envs`` = 6 on 4
devices: 2 devices); ``batched`` pads the batch to a multiple of the device
count instead, so it always uses every device. Several processes
(``gvsjax.utils.distributed``): ``jax.devices()`` lists all processes' devices and
the mesh spans them; the batch must then be a multiple of the device count
(a process left out of the mesh could not take part). ``put`` places a
process-local value (e.g. from ``init`` run under ``unsharded()``, or a
checkpoint) on the mesh. Set ``GVSJAX_SHARDING=0`` to switch sharding off
(e.g. to compare with a single-device run).
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import math
import os
from collections.abc import Callable, Iterator
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

AXIS = "batch"  # the mesh axis name the batch is split over


_OFF = contextvars.ContextVar("gvsjax_unsharded", default=False)


def enabled() -> bool:
    """Sharding is on unless ``GVSJAX_SHARDING=0`` or inside ``unsharded()`` (read at trace time)."""
    return os.environ.get("GVSJAX_SHARDING", "1") != "0" and not _OFF.get()


@contextlib.contextmanager
def unsharded() -> Iterator[None]:
    """Code traced or run inside uses this process's default device only (no mesh)."""
    token = _OFF.set(True)
    try:
        yield
    finally:
        _OFF.reset(token)


def mesh_for(batch_size: int) -> Mesh | None:
    """A 1-D mesh over the most devices that divide ``batch_size`` (None if only one).

    With several processes every device must take part: ``ValueError`` unless
    ``batch_size`` is a multiple of ``jax.device_count()``.
    """
    if not enabled():
        return None
    devices = jax.devices()
    k = math.gcd(len(devices), int(batch_size))
    if jax.process_count() > 1 and k < len(devices):
        raise ValueError(f"a batch of {batch_size} cannot be split over the {len(devices)} devices of "
                         f"{jax.process_count()} processes; use a multiple of {len(devices)}")
    if k <= 1:
        return None
    return Mesh(np.array(devices[:k]), (AXIS,))


def batch_spec(mesh: Mesh | None, axis: int = 0) -> NamedSharding | None:
    """Sharding of an array split along ``axis`` over the mesh."""
    if mesh is None:
        return None
    return NamedSharding(mesh, PartitionSpec(*([None] * axis), AXIS))


def replicated(mesh: Mesh | None) -> NamedSharding | None:
    """Sharding of an array copied to every device of the mesh."""
    return None if mesh is None else NamedSharding(mesh, PartitionSpec())


def put(tree: Any, sharding: NamedSharding | None) -> Any:
    """Place every array leaf, a whole process-local value, with ``sharding`` (None: as is).

    With several processes each process passes the same whole value and keeps
    its own devices' part of it.
    """
    if sharding is None:
        return tree
    return jax.tree.map(lambda x: jax.device_put(np.asarray(x), sharding), tree)


def constrain(tree: Any, sharding: NamedSharding | None) -> Any:
    """``with_sharding_constraint`` on every array leaf (no-op for ``None``).

    Leaves that cannot be split evenly (or are scalars when the sharding
    splits an axis) are left to XLA's propagation.
    """
    if sharding is None:
        return tree
    spec = sharding.spec
    n = sharding.mesh.size

    def one(x):
        axis = len(spec) - 1
        if len(spec) and (jnp.ndim(x) <= axis or jnp.shape(x)[axis] % n):
            return x
        return jax.lax.with_sharding_constraint(x, sharding)

    return jax.tree.map(one, tree)


def split_batch(vfn: Callable, mesh: Mesh | None, in_axes: tuple) -> Callable:
    """Run the batched ``vfn`` on each device's slice of the batch (``shard_map``).

    ``in_axes`` holds 0 (split along axis 0) or None (replicated) per
    positional argument; every output is split along axis 0. Each device runs
    ``vfn`` on its own rows with no communication. The batch size must be a
    multiple of ``mesh.size``. ``mesh=None``: ``vfn``.
    """
    if mesh is None:
        return vfn
    in_specs = tuple(PartitionSpec(AXIS) if a == 0 else PartitionSpec() for a in in_axes)
    return jax.shard_map(vfn, mesh=mesh, in_specs=in_specs, out_specs=PartitionSpec(AXIS),
                         check_vma=False)


def batched(fn: Callable, in_axes: int | tuple = 0) -> Callable:
    """``jit(vmap(fn, in_axes))`` with the batch (axis 0 of the batched inputs and of
    every output) split over all devices.

    ``in_axes`` is 0 (every argument batched) or a tuple of 0 / None per
    positional argument (None: the same value for every batch entry,
    replicated). The batch is padded with copies of its last entry to a
    multiple of the device count and the outputs are cut back, so any batch
    size works. Compiled once per input shape, like ``jax.jit``. Results equal
    the single-device ``jit(vmap(fn))`` up to the last bits: XLA compiles the
    partitioned program separately and may round a few float operations
    differently (e.g. 2 ulp on the throw's release position).
    """
    vfn = jax.vmap(fn, in_axes=in_axes)
    single = jax.jit(vfn)
    compiled: dict[tuple, Callable] = {}

    @functools.wraps(fn)
    def run(*args):
        axes = (in_axes,) * len(args) if not isinstance(in_axes, tuple) else in_axes
        if len(axes) != len(args):
            raise ValueError(f"in_axes has {len(axes)} entries for {len(args)} arguments")
        if any(a not in (0, None) for a in axes):
            raise ValueError(f"in_axes={in_axes!r} is invalid; use 0 or None per argument")
        sizes = {jnp.shape(x)[0] for a, arg in zip(axes, args) if a == 0
                 for x in jax.tree.leaves(arg)}
        if len(sizes) != 1:
            raise ValueError(f"batched arguments have leading sizes {sorted(sizes)}; "
                             "expected one common batch size")
        n = sizes.pop()
        devices = len(jax.devices())
        if devices == 1 or not enabled():
            return single(*args)
        mesh = Mesh(np.array(jax.devices()), (AXIS,))
        if axes not in compiled:
            compiled[axes] = jax.jit(split_batch(vfn, mesh, axes))
        pad = -n % devices

        def put(x):
            x = jnp.asarray(x)
            if pad:  # copies of the last entry: valid inputs, cut from the outputs
                x = jnp.concatenate([x, jnp.repeat(x[-1:], pad, axis=0)])
            return jax.device_put(x, batch_spec(mesh))

        placed = [jax.tree.map(put, a) if ax == 0 else jax.device_put(a, replicated(mesh))
                  for ax, a in zip(axes, args)]
        out = compiled[axes](*placed)
        return jax.tree.map(lambda y: y[:n], out) if pad else out

    return run
