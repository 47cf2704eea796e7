"""What a training run writes as it goes: metrics.csv (and TensorBoard events), and
the finiteness check of every call's metrics and weights."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import jax
import numpy as np

from gvsjax.utils import distributed


class MetricsLog:
    """metrics.csv (append, columns fixed by the first row) and optional TensorBoard."""

    def __init__(self, out: Path, resume_update: int | None):
        self.path = out / "metrics.csv"
        self.columns: list[str] | None = None
        if resume_update is not None and self.path.exists():
            with open(self.path, newline="") as f:  # drop rows past the checkpoint
                text = f.read()
            if not text.endswith("\n"):  # a row cut short by a kill is dropped whole
                text = text[: text.rfind("\n") + 1]
            rows = list(csv.DictReader(text.splitlines()))
            if rows:
                self.columns = list(rows[0].keys())
                rows = [r for r in rows if None not in r.values() and _int(r["update"]) < resume_update]
                with open(self.path, "w", newline="") as f:
                    w = csv.DictWriter(f, self.columns)
                    w.writeheader()
                    w.writerows(rows)
        elif self.path.exists():
            self.path.unlink()
        self.tb = _tensorboard(out)

    def write(self, rows: list[dict[str, float]]) -> None:
        if not rows:
            return
        if self.columns is None:
            self.columns = list(rows[0].keys())
            with open(self.path, "w", newline="") as f:
                csv.DictWriter(f, self.columns).writeheader()
        with open(self.path, "a", newline="") as f:
            w = csv.DictWriter(f, self.columns, extrasaction="ignore")
            w.writerows(rows)
        if self.tb is not None:
            for r in rows:
                for k, v in r.items():
                    if k not in ("update", "episodes") and math.isfinite(v):
                        self.tb.add_scalar(k, v, int(r["episodes"]))
            self.tb.flush()


def _int(text: str) -> float:
    """An int from a CSV cell; inf (dropped) when garbled."""
    try:
        return int(text)
    except (TypeError, ValueError):
        return math.inf


def _tensorboard(out: Path):
    import importlib.util

    for module, needs in (("tensorboardX", ("tensorboardX",)),
                          ("torch.utils.tensorboard", ("torch", "tensorboard"))):
        # look before importing: importing torch only to fail on a missing tensorboard
        # costs seconds and ~0.3 GB of memory per process
        if any(importlib.util.find_spec(m) is None for m in needs):
            continue
        try:
            mod = __import__(module, fromlist=["SummaryWriter"])
            return mod.SummaryWriter(str(out / "tb"))
        except Exception:  # not installed (or broken): CSV only
            continue
    return None


def rows_of(metrics: dict, wall: float) -> list[dict[str, float]]:
    m = {k: np.asarray(v) for k, v in distributed.fetch(metrics).items()}
    rows = []
    for i in range(len(m["update"])):
        if int(m["update"][i]) < 0:  # skipped past the budget
            continue
        row = {"update": int(m["update"][i]), "episodes": int(m["episodes"][i]), "wall_s": wall}
        row.update({k: float(v[i]) for k, v in m.items() if k not in ("update", "episodes")})
        rows.append(row)
    return rows


def non_finite(rows: list[dict[str, float]], state) -> str | None:
    """What became NaN/inf in a call's metric rows or the new weights/optimizer state, else None.

    Checked: every loss/optimisation metric, ``episode_reward`` when an
    episode completed, the ``train_*`` returns once an episode has ended. Not
    checked: the other ``episode_<info>`` means (NaN whenever no episode ended
    in the rollout; diagnostics, not learned from).
    """
    for r in rows:
        for k, v in r.items():
            if k.startswith("episode_") and (k != "episode_reward" or r.get("episodes_completed", 0) == 0):
                continue
            if k.startswith("train_") and r.get("train_window_episodes", 0) == 0:
                continue
            if not math.isfinite(v):
                return f"metric {k}={v} at update {int(r['update'])}"
    for name in ("params", "opt_state"):
        leaves = jax.tree_util.tree_leaves_with_path(distributed.fetch(getattr(state, name)))
        for where, x in leaves:
            x = np.asarray(x)
            if np.issubdtype(x.dtype, np.floating) and not np.all(np.isfinite(x)):
                return f"{name}{jax.tree_util.keystr(where)} became non-finite by update {int(state.update) - 1}"
    return None


def final_training_returns(metrics_csv) -> dict | None:
    """The discounted returns of the last finished training episodes (sampled actions) at the end of a
    run's ``metrics.csv`` (``gvsjax.utils.episode_returns``), or None when it has none."""
    path = Path(metrics_csv)
    if not path.exists():
        return None
    with open(path, newline="") as f:
        rows = [r for r in csv.DictReader(f) if float(r.get("train_window_episodes") or 0) > 0]
    if not rows:
        return None
    last = rows[-1]
    return {"what": f"the last {int(float(last['train_window_episodes']))} finished training episodes, "
                    "actions sampled from the policy (the benchmark's logged metric)",
            "at_episode": int(last["episodes"]),
            **{k.removeprefix("train_"): float(last[k]) for k in ("train_discounted_return_average",
                                                                  "train_discounted_return_start", "train_return",
                                                                  "train_failed_fraction")}}

