"""Train (and evaluate) a task with some of its default params replaced.

    python experiments/studies/train_variant.py task=reach_obstacles residual_scale=1 final_weight=10 -- out=runs/v

Every ``name=value`` before ``--`` replaces a numeric field of the task's ``default_params()``
(``name=x,y,z`` a tuple of numbers);
what follows ``--`` goes to ``python -m gvsjax.train`` unchanged. The variant is registered in this
process as ``<task>_variant``, so the training's own final evaluation (``eval_targets``) runs on the
variant's params; ``python -m gvsjax.evaluate`` in another process does not know the variant and
refuses the checkpoint.
"""

from __future__ import annotations

import dataclasses
import sys

import gvsjax.train
from gvsjax.tasks import make, register


def check_overrides(task: str, params, overrides: dict) -> None:
    """Exit naming the ``overrides`` that are not fields of ``task``'s ``params``."""
    fields = {f.name for f in dataclasses.fields(params)}
    unknown = sorted(set(overrides) - fields)
    if unknown:
        raise SystemExit(f"{unknown} are not params of {task}; choose from {sorted(fields)}")


def variant(task: str, overrides: dict[str, float]) -> str:
    """Register ``task`` with ``overrides`` in its default params; returns the variant's name."""
    base = type(make(task))
    check_overrides(task, base().default_params(), overrides)

    class Variant(base):  # type: ignore[misc, valid-type]
        def default_params(self):
            return dataclasses.replace(super().default_params(), **overrides)

    name = f"{task}_variant"
    register(name, Variant)
    return name


def parse(value: str) -> float | tuple[float, ...]:
    """A number, or numbers separated by commas (a tuple field such as ``layout_jitter=0.05,0.05,0.05``)."""
    return tuple(float(x) for x in value.split(",")) if "," in value else float(value)


def main(argv: list[str]) -> int:
    split = argv.index("--") if "--" in argv else len(argv)
    pairs = dict(a.split("=", 1) for a in argv[:split])
    if "task" not in pairs:
        raise SystemExit(__doc__)
    task = pairs.pop("task")
    name = variant(task, {k: parse(v) for k, v in pairs.items()})
    return gvsjax.train.main([f"task={name}", *argv[split + 1:]])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
