"""The docs check of CI can fail: its own line of ``.ci/run``, run on a copy of the site's sources with
one planted fault, exits non-zero and names the fault. Each build takes several seconds."""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# what the build reads: the hook imports the package's source (griffe) and experiments/ (tables)
SOURCES = ("mkdocs.yml", "docs", "gvsjax", "experiments", "benchmarks", "figures", "notebooks")
MISSING = [m for m in ("mkdocs", "material", "mkdocs_jupyter", "mkdocstrings", "griffe")
           if importlib.util.find_spec(m) is None]
needs_docs = pytest.mark.skipif(bool(MISSING), reason=f"the docs extra is not installed ({', '.join(MISSING)}): "
                                "pip install -e '.[docs]' (CI installs it, and its build step needs it)")


def ci_docs_command() -> str:
    lines = [line for line in (ROOT / ".ci" / "run").read_text().splitlines()
             if "mkdocs build" in line and not line.lstrip().startswith("#")]
    assert len(lines) == 1, f".ci/run should build the docs on one line: {lines}"
    return lines[0]


def build_with(tmp: Path, path: str, addition: str) -> tuple[int, str]:
    """CI's docs build on a copy of the sources with ``addition`` appended to ``path``: (exit code, output)."""
    for name in SOURCES:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, tmp / name, ignore=shutil.ignore_patterns("__pycache__", ".ipynb_checkpoints"))
        else:
            shutil.copy2(src, tmp / name)
    cache = ROOT / ".cache" / "mkdocs-jupyter"  # rendered notebooks, by content: half a build without it
    if cache.is_dir():  # (CI's build step, before the tests, makes it)
        shutil.copytree(cache, tmp / ".cache" / "mkdocs-jupyter")
    with open(tmp / path, "a") as f:
        f.write(addition)
    # this interpreter's mkdocs, even when its environment is not activated
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    run = subprocess.run(["bash", "-c", f"set -euo pipefail\n{ci_docs_command()}"], cwd=tmp, env=env,
                         capture_output=True, text=True, timeout=600)
    return run.returncode, run.stdout + run.stderr


def test_ci_builds_strictly_and_shows_warnings():
    command = ci_docs_command()
    assert re.search(r"\bmkdocs build\b.*--strict", command), command
    assert not re.search(r"\s(-q|--quiet)\b", command), "--quiet drops the warnings before --strict counts them"


@pytest.mark.slow
@needs_docs
def test_a_broken_anchor_fails_the_build(tmp_path):
    code, out = build_with(tmp_path, "docs/index.md", "\n[planted](speed.md#no-such-section)\n")
    assert code != 0, out
    assert "'speed.md#no-such-section'" in out and "does not contain an anchor" in out, out


@pytest.mark.slow
@needs_docs
def test_an_undocumented_public_name_fails_the_build(tmp_path):
    plant = '\n\ndef planted_undocumented():\n    return None\n\n\n__all__ += ["planted_undocumented"]\n'
    code, out = build_with(tmp_path, "gvsjax/__init__.py", plant)
    assert code != 0, out
    assert "public name without a docstring: gvsjax.planted_undocumented" in out, out
