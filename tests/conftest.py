from pathlib import Path

import pytest

import packetloss_cvx as pl

EXAMPLES = Path(__file__).resolve().parent.parent / "packetloss_cvx" / "examples"


@pytest.fixture(scope="session")
def two_actuator() -> pl.System:
    return pl.load_system(EXAMPLES / "two_actuator.toml")


@pytest.fixture(scope="session")
def pendulum() -> pl.System:
    return pl.load_system(EXAMPLES / "pendulum.toml")


#: files longer than this are listed for review at the end of a test run (a report, never a failure: a
#: module is cut at its seams, not at a line count)
LONG_FILE_LINES = 600
#: the folders whose Python files the report covers, relative to the repository root
REPORTED_FOLDERS = ("packetloss_cvx", "tests", "benchmarks")


def long_files(root: Path, folders=REPORTED_FOLDERS) -> list[tuple[str, int]]:
    """(path relative to root, lines) of every .py file under ``folders`` with more than LONG_FILE_LINES
    lines, longest first. O(total lines)."""
    found = {}
    for folder in folders:
        for path in (root / folder).rglob("*.py"):
            lines = len(path.read_text(encoding="utf-8").splitlines())
            if lines > LONG_FILE_LINES:
                found[path.relative_to(root).as_posix()] = lines
    return sorted(found.items(), key=lambda item: (-item[1], item[0]))


def pytest_terminal_summary(terminalreporter):
    """After every run: the files over LONG_FILE_LINES lines, for a maintainer to look at their seams."""
    listed = long_files(EXAMPLES.parents[1])
    if listed:
        terminalreporter.write_sep("-", f"files over {LONG_FILE_LINES} lines (for review along their seams, "
                                        "not a failure)")
        for name, lines in listed:
            terminalreporter.write_line(f"{lines:6d}  {name}")
