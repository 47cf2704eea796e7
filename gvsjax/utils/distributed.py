"""Several processes (hosts) running one computation: start-up and the host-side helpers.

Every process runs the same program (JAX's multi-controller SPMD): after
``initialize``, ``jax.devices()`` lists the devices of all processes, the
mesh of ``gvsjax.utils.sharding`` spans them and each process holds only its own
devices' rows of a split array. On CPU the processes exchange data over TCP
(gloo). The command line wraps it:

    python -m gvsjax.train task=basketball out=runs/b coordinator=HOST:PORT num_processes=2 process_id=0
    python -m gvsjax.train task=basketball out=runs/b coordinator=HOST:PORT num_processes=2 process_id=1

``fetch``, ``agree`` and ``barrier`` are collectives with several processes:
every process must call them, in the same order. With one process they are
local and ``initialize`` is a no-op.
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np


def check_args(coordinator: str, num_processes: int, process_id: int) -> None:
    """Raise ``ValueError`` naming the argument if the three do not describe a valid run.

    ``coordinator``: ``HOST:PORT`` of process 0 (port in 1..65535), required
    with ``num_processes`` > 1; ``process_id`` in ``[0, num_processes)``.
    """
    if num_processes < 1:
        raise ValueError(f"num_processes={num_processes} is invalid; expected an int >= 1")
    if not 0 <= process_id < num_processes:
        raise ValueError(f"process_id={process_id} is invalid; expected an int in [0, num_processes) "
                         f"= [0, {num_processes})")
    if num_processes == 1:
        if coordinator:
            raise ValueError(f"coordinator={coordinator!r} needs num_processes >= 2")
        return
    host, _, port = coordinator.rpartition(":")
    if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ValueError(f"coordinator={coordinator!r} is invalid; expected HOST:PORT of process 0 "
                         "with PORT in 1..65535 (e.g. localhost:12355)")


def initialize(coordinator: str, num_processes: int, process_id: int, timeout_s: int = 300) -> None:
    """Join the ``num_processes`` processes (``jax.distributed.initialize``); no-op for one.

    Must run before anything starts JAX's backend (importing gvsjax does not).
    Waits up to ``timeout_s`` seconds for the others. A second call is a no-op.
    """
    check_args(coordinator, num_processes, process_id)
    if num_processes == 1 or jax.distributed.is_initialized():
        return
    from jax._src import xla_bridge  # private: only to turn JAX's late-call error into advice

    if xla_bridge.backends_are_initialized():
        raise RuntimeError("jax.distributed.initialize must run before any JAX computation; "
                           "call gvsjax.utils.distributed.initialize first")
    jax.distributed.initialize(coordinator_address=coordinator, num_processes=num_processes,
                               process_id=process_id, initialization_timeout=timeout_s)


def is_main() -> bool:
    """True on process 0, the one that writes files."""
    return jax.process_index() == 0


def fetch(tree: Any) -> Any:
    """``jax.device_get(tree)``, also for arrays split over processes: NumPy copies, each whole.

    A leaf split over several processes is gathered (a collective); replicated
    or local leaves are copied locally.
    """
    def one(x):
        if not isinstance(x, jax.Array) or x.is_fully_addressable:
            return jax.device_get(x)
        if x.is_fully_replicated:
            return np.asarray(x.addressable_data(0))
        from jax.experimental import multihost_utils

        return np.asarray(multihost_utils.process_allgather(x, tiled=True))

    return jax.tree.map(one, tree)


def agree(flag: bool) -> bool:
    """Process 0's ``flag`` on every process: decisions taken from clocks (when to save)
    must match, since the saving is collective."""
    if jax.process_count() == 1:
        return flag
    from jax.experimental import multihost_utils

    return bool(multihost_utils.broadcast_one_to_all(np.asarray(flag)))


def barrier(name: str) -> None:
    """Wait until every process got here (e.g. until process 0 wrote a file)."""
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices(name)
