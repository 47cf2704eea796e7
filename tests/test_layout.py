"""The package's import graph: imports point one way, from the Lie-group math up to
the command line and Gymnasium, with no cycle (read from the source with ``ast``)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "gvsjax"

# Each module's layer; a module may import only its own layer or lower ones. The folders
# follow the layers: utils/ (0), core/ (1-6, the simulator), tasks/, the controllers, and the
# command line and Gymnasium at the top of the package. The subpackages' own __init__ files
# import nothing, so they sit at layer 0.
C = "gvsjax.core."
EXACT = {"gvsjax", "gvsjax.core"}
LAYERS = {
    "utilities": (0, ["gvsjax.utils", "gvsjax.core"]),
    "lie": (1, [C + "lie", C + "linalg"]),
    "model": (2, [C + m for m in ("model", "obstacles", "robots", "curvature_arm", "validation", "loads")]),
    "kinematics": (3, [C + m for m in ("magnus", "scan", "kinematics")]),
    "dynamics": (4, [C + m for m in ("muscles", "active_strain", "tendons", "penetration", "stacked_contact",
                                     "contact_samples", "contact", "dynamics")]),
    "integrators": (5, [C + "integrators"]),
    "simulation": (6, ["gvsjax"] + [C + m for m in ("trajectory", "system", "stability", "inputs", "simulation",
                                                     "statics", "identify")]),
    "tasks": (7, ["gvsjax.tasks"]),
    "controllers": (8, ["gvsjax.ppo", "gvsjax.sac", "gvsjax.mpc"]),
    "command line": (9, ["gvsjax.train", "gvsjax.evaluate", "gvsjax.animate"]),
    "gym": (10, ["gvsjax.gym"]),
}


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def modules(root: Path = ROOT) -> dict[str, Path]:
    return {module_name(p, root): p for p in sorted(root.rglob("*.py"))}


def import_edges(root: Path = ROOT) -> set[tuple[str, str]]:
    """(importer, imported) pairs between modules of the package, function-level imports included.

    ``from a import b`` points at module ``a.b`` when that is a module, else at ``a``.
    Importing ``gvsjax.p.m`` also runs ``gvsjax/p/__init__.py`` (a subpackage's init, for
    an importer outside it): that counts as an edge too; the top package's does not.
    """
    mods = modules(root)
    top = root.name
    edges = set()
    for name, path in mods.items():
        for node in ast.walk(ast.parse(path.read_text())):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in mods else node.module
                           for a in node.names]
            for t in targets:
                if t == top or t.startswith(top + "."):
                    while t not in mods:  # a name inside a module: the module
                        t = t.rsplit(".", 1)[0]
                    if t != name:
                        edges.add((name, t))
                    parent = t.rsplit(".", 1)[0]
                    while parent != top and "." in parent:
                        if parent != name and not name.startswith(parent + "."):
                            edges.add((name, parent))
                        parent = parent.rsplit(".", 1)[0]
    return edges


def layer_of(module: str, layers=LAYERS) -> int:
    best, best_len = None, -1
    for level, prefixes in layers.values():
        for p in prefixes:
            # exact for the packages whose modules have layers of their own; prefix for the rest
            if (module == p or (p not in EXACT and module.startswith(p + "."))) and len(p) > best_len:
                best, best_len = level, len(p)
    if best is None:
        raise AssertionError(f"module {module} has no layer in LAYERS: add it")
    return best


def upward(edges, layers=LAYERS) -> list[tuple[str, str]]:
    return sorted((a, b) for a, b in edges if layer_of(b, layers) > layer_of(a, layers))


def cycles(edges) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    graph: dict[str, list[str]] = {}
    for a, b in edges:
        graph.setdefault(a, []).append(b)
        graph.setdefault(b, [])
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_every_module_has_a_layer():
    for name in modules():
        layer_of(name)


def test_no_import_points_upward():
    bad = upward(import_edges())
    assert not bad, "upward imports (importer -> imported):\n" + "\n".join(f"  {a} -> {b}" for a, b in bad)


def test_no_import_cycle():
    found = cycles(import_edges())
    assert not found, f"import cycles: {found}"


def test_the_checks_catch_what_they_should(tmp_path):
    """An upward import and a cycle planted in a small tree are both found."""
    pkg = tmp_path / "gvsjax"
    (pkg / "tasks").mkdir(parents=True)
    (pkg / "core").mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "core" / "__init__.py").write_text("")
    (pkg / "core" / "lie.py").write_text("from gvsjax.tasks import env\n")  # upward: lie -> tasks
    (pkg / "tasks" / "__init__.py").write_text("")
    (pkg / "tasks" / "env.py").write_text("import gvsjax.tasks.other\n")
    (pkg / "tasks" / "other.py").write_text("def f():\n    from gvsjax.tasks import env\n")  # cycle
    edges = import_edges(pkg)
    assert upward(edges) == [("gvsjax.core.lie", "gvsjax.tasks"), ("gvsjax.core.lie", "gvsjax.tasks.env")]
    assert cycles(edges) == [["gvsjax.tasks.env", "gvsjax.tasks.other"]]


def _string_constants(path: Path) -> list[str]:
    """String literals of a module that are not docstrings."""
    tree = ast.parse(path.read_text())
    docs = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)):
            body = getattr(node, "body", [])
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                docs.add(id(body[0].value))
    return [n.value for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs]


def test_generic_modules_name_no_task():
    """The command line, Gymnasium, PPO and shared figures reach tasks only through the registry."""
    from gvsjax.tasks import registered

    generic = ["train.py", "evaluate.py", "animate.py", "gym.py", "mpc.py", "utils/runlog.py", "utils/plots.py",
               "utils/keyvalue.py", "tasks/base.py", "tasks/randomized.py"]
    generic += [str(p.relative_to(ROOT)) for d in ("ppo", "sac") for p in (ROOT / d).glob("*.py")]
    for rel in generic:
        for text in _string_constants(ROOT / rel):
            for task in registered():
                assert task not in text.lower(), f"{rel} names task {task!r} in {text!r}"
