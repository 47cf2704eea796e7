"""The documentation: the generated results tables hold the committed numbers, every task page shows
its table, every public name has a docstring, and the README's links and commands are true."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS))
import api_reference  # noqa: E402
import gen_results  # noqa: E402


@pytest.fixture(scope="module")
def tables():
    return gen_results.tables(ROOT)


def _row(table: str, run: str) -> str:
    rows = [line for line in table.splitlines() if line.startswith(f"| {run} |")]
    assert len(rows) == 1, f"no single row for {run!r}"
    return rows[0]


def test_every_recorded_evaluation_is_in_its_table(tables):
    """Each run of each benchmarks/eval_<task>.json is a row of its task's table (or of its variants'),
    and each of its values is in that row as stored."""
    for path in sorted((ROOT / "benchmarks").glob("eval_*.json")):
        d = json.loads(path.read_text())
        if d["task"] == "basketball":
            continue
        for run in d["runs"]:
            name = d["task"] + ("_variants" if run["group"] == "variant" else "")
            row = _row(tables[name], run["run"])
            for column in d["columns"]:
                for key in column["keys"]:
                    if key in run:
                        assert f" {run[key]}" in row or f"/ {run[key]}" in row, (path.name, run["run"], key)


def test_basketball_rows_are_the_time_to_quality_evaluations(tables):
    for seed, name in [("0", "time_to_quality.json"), ("3", "time_to_quality_seed3.json")]:
        final = json.loads((ROOT / "benchmarks" / name).read_text())["curve"][-1]
        row = _row(tables["basketball"], seed)
        assert f"{100 * final['within_1cm']:.1f}%" in row
        assert f"{1000 * final['median_m']:.1f} mm" in row
        assert f"{100 * final['max_m']:.2f} cm" in row


def test_study_tables_are_the_json(tables):
    rows = json.loads((ROOT / "benchmarks" / "track3d_substeps.json").read_text())["rows"]
    for r in rows:
        line = next(x for x in tables["track3d_substeps"].splitlines() if x.startswith(f"| {r['n_substeps']} |"))
        assert f"{r['env_steps_per_s']:,.0f}" in line
        if r["random_p95_tip_error_m"] == r["random_p95_tip_error_m"]:  # not NaN
            assert gen_results.sig(1000 * r["random_p95_tip_error_m"]) in line
        else:
            assert "diverges" in line
    ws = json.loads((ROOT / "benchmarks" / "muscle_workspace.json").read_text())["muscle_90"]
    assert f"{100 * ws['box_within_5cm']:.1f}%" in tables["muscle_workspace"]


def test_a_changed_number_changes_the_table(tmp_path):
    """The tables are read, not remembered: a copy of benchmarks/ with one number changed shows it."""
    (tmp_path / "benchmarks").mkdir()
    for f in (ROOT / "benchmarks").glob("*.json"):
        (tmp_path / "benchmarks" / f.name).write_text(f.read_text())
    path = tmp_path / "benchmarks" / "eval_track3d.json"
    d = json.loads(path.read_text())
    d["runs"][0]["mean_cm"] = 12.345
    path.write_text(json.dumps(d))
    assert " 12.345 cm" in gen_results.tables(tmp_path)["track3d"]
    assert " 12.345 cm" not in gen_results.tables(ROOT)["track3d"]


def test_every_task_page_shows_its_generated_table(tables):
    used = set()
    for page in DOCS.rglob("*.md"):
        used |= set(re.findall(r"<!-- results: (\w+) -->", page.read_text()))
    assert used <= set(tables), f"pages name tables that do not exist: {sorted(used - set(tables))}"
    for task, page in gen_results.TASK_PAGES.items():
        assert f"<!-- results: {task} -->" in (DOCS / page).read_text(), page
    assert "<!-- results: pickplace_variants -->" in (DOCS / "studies" / "ablations.md").read_text()


def test_every_public_name_has_a_docstring():
    pytest.importorskip("griffe")
    assert api_reference.undocumented() == []


def test_the_docstring_check_finds_a_name_without_one(tmp_path):
    pytest.importorskip("griffe")
    pkg = tmp_path / "gvsjax"
    for sub in ("", "tasks", "ppo", "sac"):
        (pkg / sub).mkdir(parents=True, exist_ok=True)
    (pkg / "__init__.py").write_text('"""A package."""\n__all__ = ["good", "bad", "CONST"]\n'
                                     'def good():\n    """Documented."""\n'
                                     'def bad():\n    pass\nCONST = 1\n')
    (pkg / "tasks" / "__init__.py").write_text('"""Tasks."""\n__all__ = ["make"]\ndef make():\n    """Make."""\n')
    (pkg / "ppo" / "__init__.py").write_text('"""PPO."""\n__all__ = ["PRESETS"]\nPRESETS = {}\n"""Presets."""\n')
    (pkg / "sac" / "__init__.py").write_text('"""SAC."""\n__all__ = ["SACConfig"]\n'
                                            'class SACConfig:\n    """Config."""\n')
    (pkg / "mpc.py").write_text('"""MPC."""\n__all__ = ["MPC"]\nclass MPC:\n    """A controller."""\n')
    found = api_reference.undocumented(api_reference.load(tmp_path))
    assert found == ["gvsjax.bad", "gvsjax.CONST"]


def _links(text: str) -> list[str]:
    return [t for t in re.findall(r"\]\(([^)\s]+)\)", text) if "://" not in t and not t.startswith("#")]


def test_readme_links_resolve_and_it_stays_short():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 150
    for target in _links(readme):
        assert (ROOT / target.split("#")[0]).exists(), target


def test_readme_test_command_is_the_one_ci_runs():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    assert "python -m pytest -q -n 2" in readme
    assert "python -m gvsjax.train task=basketball" in readme
    assert ci.strip().splitlines()[-1] == "python -m pytest -q -n 2" or "\npython -m pytest -q -n 2\n" in ci
    assert 'pip install -e ".[docs]" && mkdocs serve' in readme


def test_every_nav_page_exists():
    nav = re.findall(r":\s*([\w/.-]+\.(?:md|ipynb))\s*$", (ROOT / "mkdocs.yml").read_text(), re.M)
    generated = set(gen_results.pages(ROOT)) | {p for p, _, _, _ in api_reference.PAGES} | {"api/index.md"}
    for page in nav:
        if page in generated:
            continue
        where = ROOT / page if page.startswith(("notebooks/", "benchmarks/")) else DOCS / page
        assert where.exists(), page


@pytest.mark.extended
def test_the_readme_simulator_block_runs():
    """The README's simulator example, as a newcomer pastes it (minutes: it compiles a vmapped and a
    differentiated simulation)."""
    block = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)[0]
    scope: dict = {}
    exec(compile(block, "README.md", "exec"), scope)
    assert scope["tips"].shape == (1024, 3)
    assert abs(float(scope["jax"].grad(scope["tip_x"])(5e6))) > 0


def _commands() -> list[tuple[str, str]]:
    """(where, command) for every ``python ...`` command line in the docs, the README and the eval files."""
    found = []
    texts = [(p, p.read_text()) for p in [ROOT / "README.md", *DOCS.rglob("*.md")]]
    texts += [(p, p.read_text()) for p in (ROOT / "benchmarks").glob("eval_*.json")]
    texts.append((DOCS / "gen_results.py", "\n".join(gen_results.tables(ROOT).values())))
    for path, text in texts:
        for m in re.finditer(r"python3? (?:-m [\w.]+|[\w/]+\.py)[^\n`\"|#]*", text):
            found.append((path.name, m.group(0)))
    return found


def test_every_documented_command_names_what_exists():
    """Scripts and modules exist, and a ``task=`` names a registered task (or its variant)."""
    from gvsjax.tasks import registered

    tasks = set(registered())
    commands = _commands()
    assert len(commands) > 50
    for where, cmd in commands:
        script = re.match(r"python3? ([\w/]+\.py)", cmd)
        if script and not script.group(1).startswith("-"):
            assert (ROOT / script.group(1)).exists() or script.group(1) == "docs/gen_results.py", (where, cmd)
        module = re.match(r"python3? -m ([\w.]+)", cmd)
        if module and module.group(1).startswith("gvsjax"):
            assert (ROOT / (module.group(1).replace(".", "/") + ".py")).exists(), (where, cmd)
        for task in re.findall(r"\btask=(\w+)", cmd):
            assert task in tasks or task in ("NAME", "bend"), (where, cmd)


def test_the_front_pages_show_one_table_of_tasks():
    """The README's table of tasks is the one the site's home page is given (``gen_results.task_table``):
    each task's episode and its default run's headline, from the same committed files."""
    assert "<!-- results: tasks -->" in (DOCS / "index.md").read_text()
    expected = gen_results.task_table(ROOT, "docs/")
    assert expected in (ROOT / "README.md").read_text(), f"README.md's table of tasks should read:\n{expected}"


def test_every_registered_task_is_on_the_front_pages():
    """A task has its row, or is a variant shown on its task's page, or is one of the benchmark tasks."""
    import re

    # the library's own registry lines: other tests register tasks of their own in this process
    tasks = re.findall(r'^register\("(\w+)"', (ROOT / "gvsjax" / "tasks" / "__init__.py").read_text(), re.M)
    assert len(tasks) >= 10, tasks
    pages = {gen_results.TASK_PAGES[t] for t in gen_results.EPISODES}
    for task in tasks:
        assert (task in gen_results.EPISODES or gen_results.TASK_PAGES.get(task) in pages
                or f"`{task}`" in gen_results.BENCHMARK_ROW[0]), task
