from __future__ import annotations

import atexit
import gc
from pathlib import Path

import pytest

import packetloss_cvx as pl

EXAMPLES = Path(__file__).resolve().parent.parent / "packetloss_cvx" / "model" / "examples"


@pytest.fixture(scope="session")
def two_actuator() -> pl.System:
    return pl.load_system(EXAMPLES / "two_actuator.toml")


@pytest.fixture(scope="session")
def pendulum() -> pl.System:
    return pl.load_system(EXAMPLES / "pendulum.toml")


#: the test files that take longest (wall seconds of one run, -n 0, b25c584, load 2-3), longest first. They run
#: first, and the many short files fill in behind them: with ``--dist loadfile --no-loadscope-reorder`` (pyproject)
#: xdist hands out files in this order, so no worker is left starting a 20 s file while the other has finished.
#: (xdist's own order, by the number of tests in a file, put these few-test files last.) A file missing here
#: only runs later; nothing else depends on the order.
HEAVIEST_FIRST = (
    "tests/cli/test_examples_kernels.py",        # 60 s (every example and command, under a second kernel too)
    "tests/docs/test_docs_site.py",               # 21 s (the mkdocs build, then Chromium)
    "tests/cli/test_reproduce_kernels.py",       # 10 s (reproduce --quick under a second kernel)
    "tests/allocation/test_allocation_stability.py",    # 15 s
    "tests/allocation/test_allocation_power.py",        # 13 s
    "tests/claims/test_claims_doc.py",              # 13 s
    "tests/lq/test_properties.py",              # 13 s
    "tests/cli/test_cli_output_files.py",          # 11 s (subprocesses killed in their writes)
    "tests/closedloop/test_region.py",                  # 8 s
    "tests/closedloop/test_markov_region.py",           # 8 s
    "tests/cli/test_reproduce.py",               # 8 s
    "tests/house/test_packaging.py",               # 7 s (a wheel built by pip)
    "tests/studies/test_dask.py",                    # 7 s
    "tests/montecarlo/test_simulate_markov.py",         # 7 s
    "tests/sensing/test_sensing_estimation.py",      # 6 s
    "tests/cli/test_closed_form_imports.py",     # 6 s (fresh interpreters)
    "tests/allocation/test_allocation_chains.py",       # 5 s
)


def pytest_collection_modifyitems(items):
    """The files of HEAVIEST_FIRST first, in that order; every other test keeps its place relative to the others
    (a stable sort), and a file's tests keep theirs. O(items log items)."""
    rank = {path: k for k, path in enumerate(HEAVIEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))


def pytest_configure(config):
    """At this process's exit (an atexit handler, after pytest has returned, its last garbage collection and
    unraisable-exception check done), move every object to the garbage collector's permanent generation, so the
    interpreter's shutdown does not walk and free the ~230,000 objects of the imported numerical stack one
    cycle at a time: ~0.8 s CPU less for each of the three pytest processes (the workers' exits are on the run's
    critical path). What it skips: freeing memory the OS takes back anyway, and ``__del__`` of objects in reference
    cycles still alive at exit, which Python never promised to call; atexit handlers and ``weakref.finalize``
    still run. O(1)."""
    atexit.register(gc.freeze)


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
    """After a verbose run (``-v``): the files over LONG_FILE_LINES lines, for a maintainer to look at their seams
    (a user's run of the README's command is not a code review)."""
    if terminalreporter.config.get_verbosity() < 1:
        return
    listed = long_files(EXAMPLES.parents[1])
    if listed:
        terminalreporter.write_sep("-", f"files over {LONG_FILE_LINES} lines (for review along their seams, "
                                        "not a failure)")
        for name, lines in listed:
            terminalreporter.write_line(f"{lines:6d}  {name}")
