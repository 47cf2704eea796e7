"""MkDocs hooks (``hooks:`` in mkdocs.yml): the pages made at build time and the checks.

- the API reference pages (``api_reference.py``) and the results pages (``gen_results.py``) are made
  here, from the source and from the committed JSON, never written by hand;
- ``figures/``, ``notebooks/`` and ``benchmarks/`` live at the repository root; they join the site under
  the same names, and relative links to them from the docs (``../figures/x.png``, as GitHub reads
  them) are rewritten for the site; a link to any other file outside docs/ (a source file) becomes
  plain code text, and a link to a file that does not exist is a warning;
- every public name must have a docstring and an entry on the API pages: each miss is a warning, which
  ``mkdocs build --strict`` turns into a failed build.
"""

from __future__ import annotations

import logging
import posixpath
import re
import sys
from pathlib import Path

from mkdocs.plugins import event_priority
from mkdocs.structure.files import File, Files

sys.path.insert(0, str(Path(__file__).resolve().parent))
import api_reference  # noqa: E402
import gen_results  # noqa: E402

log = logging.getLogger("mkdocs.hooks.gvsjax")
ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
# repository folders served under the same name
MOUNTED = {"figures": ("*",), "notebooks": ("*.ipynb",), "benchmarks": ("*.json", "*.csv", "README.md")}
LINK = re.compile(r"(!?\[[^\]]*\])\(([^)\s]+)\)")
# a generated table's place, and the line GitHub readers see instead of it (dropped from the site)
RESULTS = re.compile(r"<!-- results: (\w+) -->(\n> Generated table:[^\n]*)?")
_pkg = None
_generated: dict[str, str] = {}
_tables: dict[str, str] = {}


def _griffe():
    global _pkg
    if _pkg is None:
        _pkg = api_reference.load(ROOT)
    return _pkg


@event_priority(100)  # before mkdocs-jupyter's on_files, which converts the notebooks added here
def on_files(files: Files, config) -> Files:
    for folder, patterns in MOUNTED.items():
        for pattern in patterns:
            for path in sorted((ROOT / folder).glob(pattern)):
                files.append(File(f"{folder}/{path.name}", str(ROOT), config["site_dir"],
                                  config["use_directory_urls"]))
    _generated.clear()
    _generated.update(api_reference.pages(_griffe()))
    _generated.update(gen_results.pages(ROOT))
    _tables.clear()
    _tables.update(gen_results.tables(ROOT))
    for uri, content in _generated.items():
        files.append(File.generated(config, uri, content=content))
    return files


def _site_uri(real: Path) -> str | None:
    """Where a repository file is on the site (its docs-relative path), or None."""
    try:
        return real.relative_to(DOCS).as_posix()
    except ValueError:
        pass
    try:
        rel = real.relative_to(ROOT)
    except ValueError:
        return None
    if rel.parts and rel.parts[0] in MOUNTED:
        return rel.as_posix()
    return None


def rewrite_links(markdown: str, src_real: Path, src_uri: str) -> str:
    """Point relative links that leave docs/ at the site's copy; unlink files the site does not hold."""

    def fix(m: re.Match) -> str:
        text, target = m.group(1), m.group(2)
        if "://" in target or target.startswith(("#", "mailto:", "/")):
            return m.group(0)
        path, _, anchor = target.partition("#")
        if not path.startswith(".."):
            return m.group(0)
        real = Path(posixpath.normpath((src_real.parent / path).as_posix()))
        if not real.exists():  # else unlinked below, a dead link would pass unseen
            log.warning(f"{src_uri}: link to a file that does not exist: {target}")
        uri = _site_uri(real)
        if uri is None:  # a source file: name it
            label = text[1:-1]
            return label if label.startswith("`") else f"`{label}`"
        new = posixpath.relpath(uri, posixpath.dirname(src_uri) or ".")
        return f"{text}({new}{'#' + anchor if anchor else ''})"

    return LINK.sub(fix, markdown)


def insert_tables(markdown: str, where: str) -> str:
    """Put each generated table where its ``<!-- results: NAME -->`` line is."""

    def table(m: re.Match) -> str:
        if m.group(1) not in _tables:
            log.warning(f"{where}: no generated table named {m.group(1)!r} (docs/gen_results.py)")
            return m.group(0)
        return _tables[m.group(1)]

    return RESULTS.sub(table, markdown)


def on_page_markdown(markdown: str, page, config, files) -> str:
    f = page.file
    if f.src_uri in _generated or not f.abs_src_path:
        return markdown
    return insert_tables(rewrite_links(markdown, Path(f.abs_src_path), f.src_uri), f.src_uri)


def on_post_build(config) -> None:
    for name in api_reference.undocumented(_griffe()):
        log.warning(f"public name without a docstring: {name}")
    site = Path(config["site_dir"])
    for page, ids in api_reference.anchors(_griffe()).items():
        html_path = site / (page[:-3] + "/index.html" if config["use_directory_urls"] else page[:-3] + ".html")
        html = html_path.read_text() if html_path.exists() else ""
        for ident in ids:
            if f'id="{ident}"' not in html:
                log.warning(f"public name missing from the API reference ({page}): {ident}")
