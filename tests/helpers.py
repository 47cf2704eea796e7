"""Shared test helpers: "fails before compiling" checks, figure capture, a 3D test robot.

``no_compile`` counts XLA compilations (jax.monitoring) inside a block and
fails if there were any: bad input must be rejected before anything is traced
or compiled. ``capture_figures`` records the lines of every figure a
``gvsjax`` drawing saves, so a test can check what was drawn, not only that a
PNG exists.
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from pathlib import Path

import jax
import numpy as np
import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

import gvsjax  # noqa: F401  (x64 and the XLA flag before JAX starts its backend)

_COMPILES = [0]

# hypothesis settings and strategies for bad-input tests
FAST = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])

nan_inf = st.sampled_from([math.nan, math.inf, -math.inf])
not_a_number = st.one_of(st.text(max_size=5), st.none(), st.booleans(), st.just([]),
                         st.just({"a": 1}), st.just(object()))
not_positive = st.one_of(st.floats(max_value=0.0, allow_nan=False), st.integers(max_value=0), nan_inf,
                         not_a_number)


def _on_event(event, duration, **kwargs):
    if event == "/jax/core/compile/backend_compile_duration":
        _COMPILES[0] += 1


jax.monitoring.register_event_duration_secs_listener(_on_event)


@contextmanager
def no_compile():
    """Fail if XLA compiles anything inside the block."""
    before = _COMPILES[0]
    yield
    assert _COMPILES[0] == before, f"{_COMPILES[0] - before} compilation(s) before the error"


def raises_naming(name, fn, /, *args, exc=ValueError, **kwargs):
    """``fn(*args, **kwargs)`` raises ``exc`` whose message contains ``name``; no compilation.
    (For arbitrary keyword names, e.g. generated ones, pass a closure: a key "exc" would land here.)"""
    with no_compile(), pytest.raises(exc) as info:
        fn(*args, **kwargs)
    assert name in str(info.value), f"{name!r} not in {str(info.value)!r}"
    return str(info.value)


# modules that bind ``gvsjax.utils.plots.save`` at import (``from gvsjax.utils.plots import save``)
_SAVERS = ("gvsjax.utils.plots", "gvsjax.tasks.basketball.figures", "gvsjax.tasks.pickplace.figures",
           "gvsjax.tasks.throw3d.figures")


def capture_figures(monkeypatch) -> dict[str, list[dict]]:
    """Record every figure saved through ``gvsjax.utils.plots.save`` (the files are still written).

    Returns ``{file name: [line, ...]}``, filled as figures are saved; each line is
    ``{"label", "x", "y", "axes"}`` (x, y float arrays; axes: the index of its axes). The
    heights of a figure's bars are under ``"bars"`` in its entry's ``{"label": "bars"}`` line
    (as ``y``), when it has any; the points of a 2D scatter plot are a ``{"label": "scatter"}`` line.
    """
    import importlib

    from matplotlib.collections import PathCollection
    from matplotlib.container import BarContainer

    from gvsjax.utils import plots

    real = plots.save
    captured: dict[str, list[dict]] = {}

    def save(fig, path):
        lines = []
        for i, ax in enumerate(fig.axes):
            for line in ax.get_lines():
                x, y = (np.asarray(v, float) for v in line.get_data())
                lines.append({"label": str(line.get_label()), "x": x, "y": y, "axes": i})
            for bars in (c for c in ax.containers if isinstance(c, BarContainer)):
                x = np.array([b.get_x() + b.get_width() / 2 for b in bars], float)
                y = np.array([b.get_height() for b in bars], float)
                lines.append({"label": "bars", "x": x, "y": y, "axes": i})
            flat = ax.name != "3d"  # a 3D scatter's offsets are its projection: not recorded
            for points in (c for c in ax.collections if flat and isinstance(c, PathCollection)):
                xy = np.asarray(points.get_offsets(), float).reshape(-1, 2)
                lines.append({"label": "scatter", "x": xy[:, 0], "y": xy[:, 1], "axes": i})
        captured[Path(path).name] = lines
        return real(fig, path)

    for name in _SAVERS:
        monkeypatch.setattr(importlib.import_module(name), "save", save)
    return captured


def finite_line(lines: list[dict], label: str, min_points: int = 2) -> dict:
    """The one line labelled ``label``, checked non-empty and finite."""
    found = [ln for ln in lines if ln["label"] == label]
    assert len(found) == 1, f"{len(found)} lines labelled {label!r} in {[ln['label'] for ln in lines]}"
    line = found[0]
    assert line["x"].size >= min_points and line["x"].shape == line["y"].shape, (label, line["x"].shape)
    assert np.all(np.isfinite(line["x"])) and np.all(np.isfinite(line["y"])), f"{label!r} has NaN/inf"
    return line


def rigid_soft_chain(damping=0.0, n_gauss=4):
    """A rigid upper arm on a free shoulder, then a soft forearm on a free elbow, in 3D."""
    import gvsjax as gv

    upper = gv.RigidLink(mass=0.8, inertia=(2e-3, 1e-2, 1e-2), com=(0.15, 0.0, 0.0), length=0.3,
                         joint=gv.Joint("revolute", (0.0, 0.0, 1.0)))
    fore = gv.SoftLink(length=0.6, radius=0.03, material=gv.Material(2e6, 1100.0, damping, 0.5),
                       basis=gv.StrainBasis(orders=(0, 1, 1, -1, -1, -1), kind="legendre"),
                       joint=gv.Joint("revolute", (0.0, 1.0, 0.0)), n_gauss=n_gauss)
    return gv.Robot(links=(upper, fore), gravity=9.81,
                    loads=(gv.PointLoad(magnitude=2.0, link=1, X=0.5, direction=(0.0, 0.0, -1.0)),),
                    masses=(gv.PointMass(mass=0.2, link=1, X=1.0),))
