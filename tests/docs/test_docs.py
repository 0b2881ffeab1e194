"""The documentation site's pages: their tutorials' code runs and the nav names every page (the strict build and
the browser check: tests/docs/test_docs_site.py)."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = ["getting-started.md", "tutorials/design-study.md", "tutorials/formula-vs-solver.md",
         "tutorials/allocation-constraints.md", "tutorials/lossy-sensors.md"]


def python_blocks(page: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", (ROOT / "docs" / page).read_text(encoding="utf-8"), flags=re.S)


@pytest.mark.parametrize("page", PAGES)
def test_tutorial_code_runs(page, capsys, monkeypatch, tmp_path):
    """Each page's Python blocks, in order, in one namespace (as a reader pastes them); their asserts check."""
    blocks = python_blocks(page)
    assert blocks, f"{page} has no Python block"
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__tutorial__"}
    for block in blocks:
        exec(compile(block, page, "exec"), namespace)   # noqa: S102 - the page's own code
    assert capsys.readouterr().out       # each page prints what it shows


def test_nav_names_every_page():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    pages = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")}
    assert pages == set(re.findall(r":\s*([\w/-]+\.md)\s*$", nav, flags=re.M))
