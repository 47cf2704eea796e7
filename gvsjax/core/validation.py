"""Input checks that fail early with a message naming the parameter."""

from __future__ import annotations

import math
from typing import Any

import jax
import numpy as np


def concrete(x: Any) -> bool:
    """True when x holds actual numbers (not a JAX tracer) at every leaf."""
    return not any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(x))


def require(ok: bool | np.bool_, name: str, value: Any, allowed: str) -> None:
    """Raise ``ValueError('<name>=<value> is invalid: expected <allowed>')`` unless ok."""
    if not ok:
        shown = value if not isinstance(value, np.ndarray) else np.array2string(value, threshold=8)
        raise ValueError(f"{name}={shown!r} is invalid: expected {allowed}")


def _numbers(name: str, value: Any, shape: tuple | None) -> np.ndarray:
    """``value`` as a float array of ``shape`` (None: any), else a ValueError naming ``name``."""
    if isinstance(value, (bool, np.bool_, str, bytes)) or value is None:
        require(False, name, value, "a number" if shape in (None, ()) else f"numbers, shape {shape}")
    # a flag inside a sequence (True in a 3-vector) would otherwise pass as the number 1
    items = np.asarray(value, dtype=object).ravel() if isinstance(value, (list, tuple)) else ()
    bad_item = any(isinstance(x, (bool, np.bool_, str, bytes)) or x is None for x in items)
    if bad_item or (isinstance(value, np.ndarray) and value.dtype == bool):
        require(False, name, value, "a number" if shape in (None, ()) else f"numbers, shape {shape}")
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        require(False, name, value, "a number" if shape in (None, ()) else f"numbers, shape {shape}")
    require(v.size >= 1, name, value, "a number")
    if shape is not None:
        require(v.shape == shape, name, value, "a scalar" if shape == () else f"an array of shape {shape}")
    return v


def positive(name: str, value: Any, shape: tuple | None = None) -> None:
    if concrete(value):
        v = _numbers(name, value, shape)
        require(bool(np.all(np.isfinite(v)) and np.all(v > 0)), name, value, "a finite number > 0")


def nonnegative(name: str, value: Any, shape: tuple | None = None) -> None:
    if concrete(value):
        v = _numbers(name, value, shape)
        require(bool(np.all(np.isfinite(v)) and np.all(v >= 0)), name, value, "a finite number >= 0")


def finite(name: str, value: Any, shape: tuple | None = None) -> None:
    if concrete(value):
        v = _numbers(name, value, shape)
        require(bool(np.all(np.isfinite(v))), name, value, "a finite number")


def integer(name: str, value: Any, low: int = 1) -> None:
    """An int (not a bool) >= ``low``."""
    require(isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
            and value >= low, name, value, f"an int >= {low}")


def check_robot(robot) -> None:
    """Physical sanity of every link, load, mass and tendon (concrete leaves only)."""
    from gvsjax.core.model import SECTION_SHAPES, TORSION_CONSTANTS, RigidLink, RoutedTendon, SoftLink, Tendon

    require(len(robot.links) >= 1, "links", robot.links, "at least one link")
    nonnegative("gravity", robot.gravity)
    for i, link in enumerate(robot.links):
        if not isinstance(link, (SoftLink, RigidLink)):
            raise ValueError(f"links[{i}]={type(link).__name__} is invalid: expected SoftLink or RigidLink")
        nj = link.joint.n_dofs
        for name in ("joint_stiffness", "joint_damping"):
            value = getattr(link, name)
            if concrete(value):
                v = _numbers(f"links[{i}].{name}", value, None)
                require(v.shape in ((), (nj,)), f"links[{i}].{name}", value,
                        f"a scalar or {nj} values (one per joint DoF)")
            nonnegative(f"links[{i}].{name}", value)
        if isinstance(link, SoftLink):
            positive(f"links[{i}].length", link.length)
            require(link.shape in SECTION_SHAPES, f"links[{i}].shape", link.shape, f"one of {SECTION_SHAPES}")
            require(link.torsion_constant in TORSION_CONSTANTS, f"links[{i}].torsion_constant",
                    link.torsion_constant, f"one of {TORSION_CONSTANTS}")
            for name in ("radius",) if link.shape == "circle" else ("width", "height"):
                positive(f"links[{i}].{name}", getattr(link, name))
            positive(f"links[{i}].taper", link.taper)
            if link.rest_strain is not None and concrete(link.rest_strain):
                v = _numbers(f"links[{i}].rest_strain", link.rest_strain, None)
                require(v.ndim in (1, 2) and v.shape[0] == 6 and bool(np.all(np.isfinite(v))),
                        f"links[{i}].rest_strain", link.rest_strain, "finite values of shape (6,) or (6, k)")
            positive(f"links[{i}].material.youngs_modulus", link.material.youngs_modulus)
            positive(f"links[{i}].material.density", link.material.density)
            nonnegative(f"links[{i}].material.damping", link.material.damping)
            if concrete(link.material.poisson):
                nu = float(_numbers(f"links[{i}].material.poisson", link.material.poisson, ()))
                require(-1.0 < nu <= 0.5, f"links[{i}].material.poisson", nu, "a ratio in (-1, 0.5]")
            integer(f"links[{i}].n_gauss", link.n_gauss)
            top = max(link.basis.orders)
            require(link.n_gauss >= top + 1, f"links[{i}].n_gauss", link.n_gauss,
                    f">= {top + 1} (highest basis order + 1), else K is under-integrated")
            require(link.recursion in ("auto", "unrolled", "scan"), f"links[{i}].recursion", link.recursion,
                    "'auto', 'unrolled' or 'scan'")
        elif isinstance(link, RigidLink):
            positive(f"links[{i}].mass", link.mass)
            positive(f"links[{i}].inertia", link.inertia)
            nonnegative(f"links[{i}].length", link.length)
            finite(f"links[{i}].com", link.com)
        else:
            raise ValueError(f"links[{i}]={type(link).__name__} is invalid: expected SoftLink or RigidLink")
    n = len(robot.links)
    if robot.parents:
        require(isinstance(robot.parents, tuple) and len(robot.parents) == n, "parents", robot.parents,
                f"empty (a serial chain) or a tuple of {n} parent indices, one per link")
        for i, parent in enumerate(robot.parents):
            require(isinstance(parent, (int, np.integer)) and not isinstance(parent, bool) and -1 <= parent < i,
                    f"parents[{i}]", parent, f"an int in [-1, {i - 1}] (-1: the base; else an earlier link)")
    for k, load in enumerate(robot.loads):
        finite(f"loads[{k}].magnitude", load.magnitude)
        require(-n <= load.link < n, f"loads[{k}].link", load.link, f"a link index in [-{n}, {n})")
        require(0.0 <= load.X <= 1.0, f"loads[{k}].X", load.X, "a material coordinate in [0, 1]")
    for k, site in enumerate(robot.wrenches):
        require(-n <= site.link < n, f"wrenches[{k}].link", site.link, f"a link index in [-{n}, {n})")
        require(0.0 <= site.X <= 1.0, f"wrenches[{k}].X", site.X, "a material coordinate in [0, 1]")
    require(robot.distributed is None or callable(robot.distributed), "distributed", robot.distributed,
            "None or a callable (X, R, p, eta, t) -> (6,) per-metre wrench")
    for k, seg in enumerate(robot.rest_strains):
        _check_rest_segments(robot, k, seg)
    for k, pm in enumerate(robot.masses):
        nonnegative(f"masses[{k}].mass", pm.mass)
        require(-n <= pm.link < n, f"masses[{k}].link", pm.link, f"a link index in [-{n}, {n})")
        require(0.0 <= pm.X <= 1.0, f"masses[{k}].X", pm.X, "a material coordinate in [0, 1]")
    for k, td in enumerate(robot.tendons):
        if isinstance(td, RoutedTendon):
            _check_routed(robot, k, td)
            continue
        require(isinstance(td, Tendon), f"tendons[{k}]", type(td).__name__, "a Tendon or a RoutedTendon")
        require(-n <= td.link < n and isinstance(robot.links[td.link], SoftLink), f"tendons[{k}].link",
                td.link, "the index of a soft link")
        finite(f"tendons[{k}].offset", td.offset)
        link = robot.links[td.link]
        half = link.radius if link.shape == "circle" else (link.width, link.height)
        if concrete(td.offset) and concrete(half) and concrete(link.taper):
            inside = _inside(link)
            require(abs(float(td.offset)) <= inside, f"tendons[{k}].offset", td.offset,
                    f"|offset| <= {inside:.4g} m, the section's smallest half-extent (the tendon runs inside)")
        require(math.isclose(math.hypot(*td.direction), 1.0, rel_tol=1e-9), f"tendons[{k}].direction",
                td.direction, "a unit 2-vector in the section's (y, z) plane")
    for i in robot.prescribed:
        require(0 <= i < robot.n_dofs, "prescribed", robot.prescribed, f"DoF indices in [0, {robot.n_dofs})")
    if getattr(robot, "contact", None) is not None:
        robot.contact.validate(robot)  # the contact layer's own checks, reached without importing it


def _inside(link, X: Any = None) -> Any:
    """The section's smallest half-extent (m), where a cable may run: over the whole link,
    or at the material points X (the taper scales it linearly)."""
    half = link.radius if link.shape == "circle" else (link.width, link.height)
    base = float(np.min(half)) * (1.0 if link.shape == "circle" else 0.5)
    if X is None:
        return base * min(1.0, float(link.taper))
    return base * (1.0 + (float(link.taper) - 1.0) * np.asarray(X, dtype=float))


def _check_routed(robot, k: int, td) -> None:
    """A routed tendon's paths: soft links base to tip, joined where one link ends and the next
    starts across a fixed joint, knots increasing, offsets of shape (K, 2) inside the section."""
    from gvsjax.core.model import SoftLink, TendonPath

    n = len(robot.links)
    require(isinstance(td.paths, tuple) and len(td.paths) >= 1, f"tendons[{k}].paths", td.paths,
            "a tuple of at least one TendonPath")
    previous = None
    for j, path in enumerate(td.paths):
        name = f"tendons[{k}].paths[{j}]"
        require(isinstance(path, TendonPath), name, type(path).__name__, "a TendonPath")
        require(-n <= path.link < n and isinstance(robot.links[path.link], SoftLink), f"{name}.link", path.link,
                "the index of a soft link")
        li = path.link % n
        link = robot.links[li]
        integer(f"{name}.n_quad", path.n_quad)
        if path.path is not None:
            require(path.offsets is None and not path.knots, f"{name}.path", path.path,
                    "a function X -> (y, z), given without offsets and knots")
            require(callable(path.path), f"{name}.path", path.path, "a function X -> (y, z)")
            require(0.0 <= path.X0 < path.X1 <= 1.0, f"{name}.X0, X1", (path.X0, path.X1), "0 <= X0 < X1 <= 1")
            probe = np.linspace(path.X0, path.X1, 9)
            where = probe
            with jax.ensure_compile_time_eval():  # concrete numbers also inside a jit trace
                d = np.stack([np.reshape(np.asarray(path.path(float(x)), dtype=float), (2,)) for x in probe])
        else:
            knots = np.asarray(path.knots, dtype=float)
            require(knots.ndim == 1 and len(knots) >= 2 and bool(np.all(np.diff(knots) > 0))
                    and knots[0] >= 0.0 and knots[-1] <= 1.0, f"{name}.knots", path.knots,
                    "two or more increasing material points in [0, 1]")
            require(path.offsets is not None, f"{name}.offsets", None, f"({len(knots)}, 2) offsets (y, z) in m")
            where = knots  # |d| is convex and the half-extent linear on a piece: its ends suffice
            if not concrete(path.offsets):
                d = None
            else:
                d = _numbers(f"{name}.offsets", path.offsets, None)
                require(d.shape == (len(knots), 2) and bool(np.all(np.isfinite(d))), f"{name}.offsets",
                        path.offsets, f"finite values of shape ({len(knots)}, 2): (y, z) in m at each knot")
        half = link.radius if link.shape == "circle" else (link.width, link.height)
        if d is not None and concrete(half) and concrete(link.taper):
            excess = np.hypot(d[:, 0], d[:, 1]) - _inside(link, where)
            i = int(np.argmax(excess))
            require(excess[i] <= 1e-12, f"{name}.offsets", f"|d| = {excess[i] + _inside(link, where[i]):.4g} m "
                    f"at X = {where[i]:.3g}", f"|d| <= {_inside(link, where[i]):.4g} m there, the section's "
                    "smallest half-extent (the cable runs inside)")
        start = path.X0 if path.path is not None else float(path.knots[0])
        stop = path.X1 if path.path is not None else float(path.knots[-1])
        if previous is not None:
            p_li, p_stop = previous
            joint = link.joint
            require(robot.parent(li) == p_li and p_stop == 1.0 and start == 0.0 and joint.n_dofs == 0,
                    f"{name}", f"link {li} from X={start}",
                    f"the continuation of paths[{j - 1}]: a child of link {p_li} from X=0 after link {p_li} "
                    "ended at X=1, across a fixed joint")
        previous = (li, stop)


def _check_rest_segments(robot, k: int, seg) -> None:
    """A ``RestStrainSegments`` on a soft link whose basis has each named strain, with ordered knots."""
    from gvsjax.core.model import STRAIN_NAMES, RestStrainSegments, SoftLink

    where = f"rest_strains[{k}]"
    require(isinstance(seg, RestStrainSegments), where, type(seg).__name__, "a RestStrainSegments")
    n = len(robot.links)
    require(isinstance(seg.link, (int, np.integer)) and -n <= seg.link < n
            and isinstance(robot.links[seg.link], SoftLink), f"{where}.link", seg.link, "the index of a soft link")
    knots = np.asarray(seg.knots, dtype=float) if isinstance(seg.knots, (tuple, list)) else np.zeros(0)
    require(knots.ndim == 1 and knots.size >= 2 and knots[0] >= 0.0 and knots[-1] <= 1.0
            and bool(np.all(np.diff(knots) > 0)), f"{where}.knots", seg.knots,
            "a tuple of >= 2 increasing material points in [0, 1] (the segments' ends)")
    comps = seg.components
    require(isinstance(comps, (tuple, list)) and len(comps) >= 1 and len(set(comps)) == len(comps)
            and all(c in STRAIN_NAMES for c in comps), f"{where}.components", comps,
            f"distinct names among {list(STRAIN_NAMES)}")
    orders = robot.links[seg.link].basis.orders
    lacking = [c for c in comps if orders[STRAIN_NAMES.index(c)] < 0]
    require(not lacking, f"{where}.components", comps,
            f"strains the link's basis has (orders {orders}; inactive: {lacking})")

