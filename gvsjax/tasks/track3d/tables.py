"""The default arms' holdable-tip tables, computed once and shipped with the package.

The reachable target set needs the tips of the arm's static equilibria under ``TABLE_SIZE``
held actions (``holdable.sample_actions`` of ``TABLE_SEED``): 16,384 statics solves, about a
minute per process. For the default arm of each actuation (``arm3d.ArmParams(actuation=...)``)
they are shipped in ``holdable_tips.npz`` beside this module, one (TABLE_SIZE, 3) float64
array of tip positions (m) per actuation, and ``default_tips`` reads them. Regenerate the file
after changing the arm, its actuation or the statics (a few minutes on 2 cores):

    python -c "from gvsjax.tasks.track3d import tables; tables.write()"

tests/test_track3d.py recomputes a random subset of the rows with the statics and compares, so
the shipped numbers cannot drift from the physics unnoticed.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import jax
import numpy as np

from gvsjax.tasks import arm3d, holdable

TABLE_SIZE, TABLE_SEED = 16384, 7  # the holdable tips' table: held actions (holdable.sample_actions)
ACTUATIONS = ("tendon", "muscle")
PATH = Path(__file__).with_name("holdable_tips.npz")


def table_actions(arm: arm3d.ArmParams, n: int = TABLE_SIZE, seed: int = TABLE_SEED) -> np.ndarray:
    """(n, k) the held actions whose equilibria make the table, in its row order."""
    return holdable.sample_actions(jax.random.PRNGKey(seed), n, arm3d.n_actions(arm))


def holdable_tips(arm: arm3d.ArmParams, n: int = TABLE_SIZE, seed: int = TABLE_SEED) -> np.ndarray:
    """(n, 3) m: the tips of the arm's equilibria under ``n`` held actions of ``seed``
    (``holdable.sample_actions``: the box's corners, faces and inside). Raises if a solve fails."""
    tips = holdable.equilibrium_poses(arm, table_actions(arm, n, seed))
    if not np.all(tips["converged"]):
        raise RuntimeError(f"{int(np.sum(~tips['converged']))} of {n} equilibria did not converge")
    return tips["position"]


@functools.cache
def default_tips(actuation: str) -> np.ndarray:
    """(TABLE_SIZE, 3) m: ``holdable_tips`` of the default arm under ``actuation``, read from the
    shipped file (computed, ~1 min, when the file or its entry is missing)."""
    if PATH.exists():
        with np.load(PATH) as data:
            if actuation in data.files:
                return np.array(data[actuation])
    return holdable_tips(arm3d.ArmParams(actuation=actuation))


def write(path: Path = PATH) -> None:
    """Compute the default arms' tables and write them to ``path`` (float64, compressed)."""
    tables: dict[str, Any] = {a: holdable_tips(arm3d.ArmParams(actuation=a)) for a in ACTUATIONS}
    np.savez_compressed(path, **tables)
