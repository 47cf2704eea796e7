"""Pick and place's targets: pairs the arm reaches exactly, drawn by table look-up.

The tendon moment is at most 30 N x 2.5 cm = 0.75 N m, about 2 % of the
gravity moment of a horizontal arm (38.5 N m): the arm mostly hangs from its
base angle and the tension trims the tip by ~1-2 cm, mostly *along* the
circle. The reachable set is therefore a thin band hugging the 1 m circle,
98.6-100 cm from the joint and ~1.2 mm thick at a given angle. Targets off the
band, such as the paper's pair (94.9 and 97.8 cm from the joint), cannot be
reached exactly (the differentiable baseline's best: 4.05 and 1.56 cm).

``make_params`` simulates ``n_pairs`` random episodes (actions uniform in
[-1, 1]^2 for both steps, with the env's own ``motion.episode``) and stores
the end-of-step tips: row i is a (pick, place) pair that the stored actions
reach. The last ``n_test`` rows are held out: ``split="test"`` draws only from
them, ``"train"`` only from the others. ``reset`` never simulates.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from gvsjax.core.robots import paper_arm
from gvsjax.tasks.pickplace.motion import episode
from gvsjax.tasks.pickplace.params import PickPlaceParams


def _tables(base: PickPlaceParams, n_pairs: int, seed: int, batch: int = 1024) -> dict:
    rng = np.random.default_rng(seed)
    acts = rng.uniform(-1.0, 1.0, (n_pairs, 2, 2))
    run = jax.jit(jax.vmap(lambda a: tuple(tr.tip[-1, :2] for tr in episode(base, a))))
    tips = [run(jnp.asarray(acts[i:i + batch])) for i in range(0, n_pairs, batch)]
    pick = np.concatenate([np.asarray(t[0]) for t in tips])
    place = np.concatenate([np.asarray(t[1]) for t in tips])
    if not (np.all(np.isfinite(pick)) and np.all(np.isfinite(place))):
        raise RuntimeError("pickplace: a table episode diverged; check the arm and n_steps")
    return dict(pick=pick, place=place, pick_action=acts[:, 0], place_action=acts[:, 1])


_CACHE: dict[tuple, dict] = {}  # tables of the default arm, per argument set


def make_params(n_pairs: int = 4096, n_test: int = 1024, seed: int = 0,
                **overrides) -> PickPlaceParams:
    """Params with target tables built (seconds the first time; cached for the default arm).

    ``overrides`` are fields of ``PickPlaceParams`` (e.g. ``n_steps``,
    ``split``, ``arm``); ``arm`` defaults to ``paper_arm(tendon_offset=0.025)``.
    """
    unknown = sorted(set(overrides) - set(PickPlaceParams.__dataclass_fields__))
    if unknown:
        raise ValueError(f"unknown pickplace parameter(s) {unknown}; valid: "
                         f"{sorted(PickPlaceParams.__dataclass_fields__)}")
    if not 0 < n_test < n_pairs:
        raise ValueError(f"n_test={n_test} must be in (0, n_pairs={n_pairs})")
    if overrides.get("sim_dtype", "float64") not in ("float64", "float32"):
        raise ValueError(f"sim_dtype={overrides['sim_dtype']!r} is invalid; choose 'float64' or 'float32'")
    arm = overrides.pop("arm", None)
    base = PickPlaceParams(arm=arm if arm is not None else paper_arm(tendon_offset=0.025),
                           n_test=n_test, **overrides)
    table_key = (n_pairs, seed, base.n_steps, base.integrator, base.step_time, base.angle_max, base.tension_max)
    exact = dataclasses.replace(base, sim_dtype="float64")  # the tables' targets: float64 whatever sim_dtype is
    if arm is not None:
        tables = _tables(exact, n_pairs, seed)
    else:
        if table_key not in _CACHE:
            _CACHE[table_key] = _tables(exact, n_pairs, seed)
        tables = _CACHE[table_key]
    radii = np.hypot(*np.concatenate([tables["pick"], tables["place"]]).T)
    band = overrides.get("radius_range", (float(radii.min()), float(radii.max())))
    arrays: dict[str, Any] = {k: jnp.asarray(v) for k, v in tables.items()}  # the table fields
    return dataclasses.replace(base, radius_range=band, **arrays)


def _table(x: jax.Array | None) -> jax.Array:
    if x is None:
        raise ValueError("params has no target tables (a bare PickPlaceParams); build it with "
                         "make_params() or the env's default_params()")
    return x


def row_range(params: PickPlaceParams) -> tuple[int, int]:
    """[lo, hi) rows of the table that ``reset`` draws from."""
    n = _table(params.pick).shape[0]
    return {"train": (0, n - params.n_test), "test": (n - params.n_test, n),
            "all": (0, n)}[params.split]


def sample_targets(key, params: PickPlaceParams):
    """A reachable (pick, place) pair (2, 2) m and its table row."""
    lo, hi = row_range(params)
    row = jax.random.randint(key, (), lo, hi)
    return jnp.stack([_table(params.pick)[row], _table(params.place)[row]]), row


def eval_targets(params: PickPlaceParams, n: int, seed: int) -> np.ndarray:
    """(n, 2, 2) target pairs from the held-out rows (distinct while n <= n_test)."""
    n_rows = _table(params.pick).shape[0]
    lo = n_rows - params.n_test
    rng = np.random.default_rng(seed)
    rows = lo + (rng.permutation(params.n_test)[:n] if n <= params.n_test
                 else rng.integers(0, params.n_test, n))
    return np.stack([np.asarray(_table(params.pick))[rows], np.asarray(_table(params.place))[rows]], 1)
