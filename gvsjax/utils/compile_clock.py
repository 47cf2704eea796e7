"""Seconds spent compiling, from JAX's own compile events: a run's wall time splits into
compilation and execution without running it twice."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import jax

# tracing, lowering to MLIR and XLA's backend compile: the first call's cost beyond running
EVENTS = ("/jax/core/compile/jaxpr_trace_duration", "/jax/core/compile/jaxpr_to_mlir_module_duration",
          "/jax/core/compile/backend_compile_duration")


@contextlib.contextmanager
def compile_seconds() -> Iterator[list[float]]:
    """``with compile_seconds() as spent:`` ``spent[0]`` holds the seconds JAX spent tracing,
    lowering and compiling inside the block (in this thread's and any other's calls)."""
    spent = [0.0]

    def listen(event: str, duration_secs: float, **_: str | int) -> None:
        if event in EVENTS:
            spent[0] += duration_secs

    jax.monitoring.register_event_duration_secs_listener(listen)
    try:
        yield spent
    finally:
        jax.monitoring.unregister_event_duration_listener(listen)
