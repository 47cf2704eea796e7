"""The API reference pages, made from the packages' ``__all__``, and the check that every public name
has a docstring.

The public API is ``gvsjax.__all__`` (``gv.*``), ``gvsjax.tasks.__all__`` and ``gvsjax.ppo.__all__``.
Each page groups its names by the module that defines them and asks mkdocstrings for each one
(``::: gvsjax.simulate``), so a new name in an ``__all__`` appears without editing a page.
``undocumented`` reads the source with griffe (what mkdocstrings renders) and lists the public names
whose docstring is empty; the mkdocs hook turns each into a warning, which ``mkdocs build --strict``
makes fatal.
"""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# (page, package, title, what the page covers)
PAGES = [
    ("api/gvsjax.md", "gvsjax", "gvsjax (gv.*)",
     "The simulator: robot descriptions, ready-made robots, simulation, kinematics, dynamics, statics, "
     "identification and contact. `import gvsjax as gv`."),
    ("api/tasks.md", "gvsjax.tasks", "gvsjax.tasks",
     "The functional environment API (gymnax style) and the task registry."),
    ("api/ppo.md", "gvsjax.ppo", "gvsjax.ppo",
     "PPO: configuration, networks, losses, rollouts, the jittable training function and checkpoints."),
    ("api/sac.md", "gvsjax.sac", "gvsjax.sac",
     "SAC: configuration, networks, losses, the replay buffer and the jittable training iteration "
     "(`python -m gvsjax.train algo=sac`)."),
    ("api/mpc.md", "gvsjax.mpc", "gvsjax.mpc",
     "Model-predictive control by gradients through the simulator: a reference controller for the "
     "closed-loop tasks."),
]


def load(search_path: Path = ROOT):
    import griffe

    # by path: a package name would be looked up in the working directory first
    return griffe.load(str(search_path / "gvsjax"), resolve_aliases=True, resolve_external=False)


def _module(pkg, name: str):
    return pkg if name == pkg.path else pkg[name.split(".", 1)[1]]


def _target(obj):
    return obj.final_target if obj.is_alias else obj


def resolve(pkg, package: str, name: str):
    """(object, identifier for mkdocstrings) of ``package.name``. A function named like the submodule
    that defines it (``gvsjax.core.curvature_arm``) is, at run time, the function: take it from the module."""
    obj = _target(_module(pkg, package)[name])
    if obj.is_module and name in obj.members:
        obj = _target(obj[name])
        return obj, obj.path
    return obj, f"{package}.{name}"


def public_names(pkg, package: str) -> list[str]:
    """The names in ``package.__all__``, in their order there."""
    exports = _module(pkg, package).exports
    if not exports:
        raise ValueError(f"{package} has no __all__")
    return [str(n) for n in exports]


def undocumented(pkg=None) -> list[str]:
    """Public names (``package.name``) whose object has no docstring, or that do not resolve."""
    pkg = load() if pkg is None else pkg
    bad = []
    for _, package, _, _ in PAGES:
        for name in public_names(pkg, package):
            try:
                obj, _ = resolve(pkg, package, name)
            except Exception as err:  # an alias to nothing: a name in __all__ that is not defined
                bad.append(f"{package}.{name} ({type(err).__name__})")
                continue
            if obj.docstring is None or not obj.docstring.value.strip():
                bad.append(f"{package}.{name}")
    return bad


def _heading(module) -> str:
    doc = module.docstring.value.strip() if module.docstring else ""
    first = doc.split("\n\n")[0].replace("\n", " ")
    return first


def pages(pkg=None) -> dict[str, str]:
    """{page path: markdown} for the API reference: an index and one page per package."""
    pkg = load() if pkg is None else pkg
    out = {}
    index = ["# API reference", "",
             "Generated from the docstrings of every public name (each package's `__all__`). "
             "Units are SI unless a docstring says otherwise; shapes are given as `(n,)`, `(n, 6)` and so on.",
             ""]
    for page, package, title, about in PAGES:
        names = public_names(pkg, package)
        index.append(f"- [{title}]({Path(page).name}): {about} ({len(names)} names)")
        groups: dict[str, list[str]] = {}
        for name in names:
            try:
                obj, ident = resolve(pkg, package, name)
                where = obj.parent.path
            except Exception:
                where, ident = package, f"{package}.{name}"
            groups.setdefault(where, []).append(ident)
        lines = [f"# {title}", "", about, ""]
        lines.append("Contents: " + " · ".join(f"[`{g}`](#{g.replace('.', '')})" for g in groups))
        lines.append("")
        for where, group in groups.items():
            lines += [f"## `{where}`", ""]
            heading = _heading(_module(pkg, where)) if where.startswith("gvsjax") else ""
            if heading:
                lines += [heading, ""]
            for ident in group:
                lines += [f"::: {ident}", ""]
        out[page] = "\n".join(lines)
    out["api/index.md"] = "\n".join(index) + "\n"
    return out


def anchors(pkg=None) -> dict[str, list[str]]:
    """{page path: the HTML ids its public names must have} (mkdocstrings ids are the dotted paths)."""
    pkg = load() if pkg is None else pkg
    return {page: [resolve(pkg, package, n)[1] for n in public_names(pkg, package)] for page, package, _, _ in PAGES}
