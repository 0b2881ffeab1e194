"""The documentation site: its tutorials' code runs, and ``mkdocs build --strict`` passes."""

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = ["getting-started.md", "tutorials/design-study.md", "tutorials/formula-vs-solver.md",
         "tutorials/allocation-constraints.md"]


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


@pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings") is None,
                    reason="the docs extra (mkdocs-material, mkdocstrings[python]) is not installed")
def test_mkdocs_build_strict(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True, check=False, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "site" / "api" / "solve" / "index.html").exists()
