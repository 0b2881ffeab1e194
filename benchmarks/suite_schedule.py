"""The test suite's xdist schedule replayed from per-test durations, and the idle time inside its tests.

``replay``: pytest-xdist 3.8's ``--dist loadfile`` scheduler (pyproject's addopts, with ``--no-loadscope-reorder``)
run on a ``pytest --durations=0`` listing: each worker first gets one file, then one more whenever it has two
tests or fewer left, the files in the order the suite collects them (tests/conftest.py ``HEAVIEST_FIRST`` first).
Every worker starts after ``--start`` seconds (its own collection) and pays ``--per-test`` seconds a test on top
of the listed setup, call and teardown. Printed: when each worker finishes, for the order as configured, for the
plain collection order (HEAVIEST_FIRST undone) and for every file longest first; with ``--draws K`` also the
spread between the workers when each file's time is scaled by a seeded random factor in [0.3, 1.2] (other
branches making files faster). The durations must come from a run with the same worker count: a test's wall
time includes waiting for a core.

``idle``: runs the given test files in this process (``-n 0``) and prints, per file, the wall time, this process's
CPU and the CPU of the child processes it reaped (resource.getrusage, setup to teardown of each test). With
``--quiet-durations`` (a ``--durations=0`` listing from a quiet two-worker run) it also prints quiet wall minus
CPU: the seconds a core stood idle while that file ran (a subprocess, a browser, a socket), the time a third
worker could fill. (The first test run pays imports the suite's collection would have made: read it with care.)

    python benchmarks/suite_schedule.py replay DURATIONS [--workers 2] [--draws 5]
    OPENBLAS_NUM_THREADS=1 python benchmarks/suite_schedule.py idle [--quiet-durations D] tests/test_x.py ...

Run from the repository root (``replay`` collects the suite once, ``pytest --collect-only``, ~5 s CPU).
Replay: O(tests + files log files) a variant.
"""

from __future__ import annotations

import argparse
import collections
import random
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DURATION_LINE = re.compile(r"^([\d.]+)s (setup|call|teardown)\s+(\S.*?)\s*$")


def durations(path: Path) -> dict[str, float]:
    """nodeid -> setup + call + teardown seconds of a ``pytest --durations=0`` listing. O(lines)."""
    total: dict[str, float] = collections.Counter()
    for line in path.read_text(encoding="utf-8").splitlines():
        found = DURATION_LINE.match(line)
        if found:
            total[found[3]] += float(found[1])
    return dict(total)


def collected(root: Path) -> list[str]:
    """The suite's node ids in collection order (tests/conftest.py's reordering applied), by pytest itself."""
    out = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-n", "0", "-p",
                          "no:cacheprovider"], cwd=root, capture_output=True, text=True, check=True).stdout
    return [line for line in out.splitlines() if "::" in line and not line.startswith(" ")]


def files_of(ids: list[str]) -> dict[str, list[str]]:
    """file -> its node ids, files in first-seen order (the loadfile work units). O(ids)."""
    units: dict[str, list[str]] = {}
    for nodeid in ids:
        units.setdefault(nodeid.split("::", 1)[0], []).append(nodeid)
    return units


def replay(units: dict[str, list[str]], seconds: dict[str, float], workers: int, start: float,
           per_test: float) -> list[float]:
    """Each worker's finish time under xdist 3.8's LoadScopeScheduling (loadfile): one unit each, then a unit
    more to every worker with at most two tests pending, and again after each test it completes. O(tests log
    workers)."""
    queue = collections.deque(units.items())
    pending = [collections.deque() for _ in range(workers)]

    def top_up(worker: int) -> None:
        if queue and len(pending[worker]) <= 2:
            pending[worker].extend(queue.popleft()[1])

    for worker in range(workers):
        if queue:
            pending[worker].extend(queue.popleft()[1])
    for worker in range(workers):
        top_up(worker)
    clock = [start] * workers
    running = set(range(workers))
    while running:
        worker = min(running, key=lambda w: (clock[w], w))
        if not pending[worker]:
            running.discard(worker)
            continue
        clock[worker] += seconds.get(pending[worker].popleft(), 0.0) + per_test
        top_up(worker)
    return clock


def variants(ids: list[str], seconds: dict[str, float]) -> dict[str, dict[str, list[str]]]:
    """The order as collected, the plain collection order (test files by name, then the package's doctests, as
    pytest finds them) and every file longest first."""
    units = files_of(ids)
    per_file = {name: sum(seconds.get(i, 0.0) for i in tests) for name, tests in units.items()}
    found = {name: k for k, name in enumerate(units)}
    plain = sorted(units, key=lambda name: (not name.startswith("tests/"), name if name.startswith("tests/")
                                            else found[name]))
    longest = sorted(units, key=lambda name: -per_file[name])
    return {"as configured": units, "collection order": {n: units[n] for n in plain},
            "longest file first": {n: units[n] for n in longest}}


def run_replay(args: argparse.Namespace) -> None:
    seconds = durations(args.durations)
    ids = collected(ROOT)
    missing = len([i for i in ids if i not in seconds])
    print(f"{len(ids)} tests collected, {len(seconds)} in the listing ({missing} not: counted as 0 s), "
          f"listed sum {sum(seconds.values()):.1f} s; {args.workers} workers, start {args.start} s, "
          f"{args.per_test * 1e3:.1f} ms a test")
    rng = random.Random(args.seed)
    files = list(files_of(ids))
    draws = [{name: rng.uniform(0.3, 1.2) for name in files} for _ in range(args.draws)]
    for label, units in variants(ids, seconds).items():
        finish = replay(units, seconds, args.workers, args.start, args.per_test)
        line = f"{label:20s} workers finish at " + ", ".join(f"{t:6.1f}" for t in finish)
        line += f" s (spread {max(finish) - min(finish):4.1f})"
        if draws:
            spreads = []
            for scale in draws:
                scaled = {i: t * scale[i.split("::", 1)[0]] for i, t in seconds.items()}
                got = replay(units, scaled, args.workers, args.start, args.per_test)
                spreads.append(max(got) - min(got))
            line += "; scaled files: spread " + " ".join(f"{s:.1f}" for s in spreads)
        print(line)


class IdleMeter:
    """A pytest plugin: per test (setup to teardown) the wall time, this process's CPU and reaped children's."""

    def __init__(self) -> None:
        self.rows: list[tuple[str, float, float, float]] = []

    @staticmethod
    def cpu() -> tuple[float, float]:
        own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        return own.ru_utime + own.ru_stime, kids.ru_utime + kids.ru_stime

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(self, item, nextitem):
        wall, (own, kids) = time.perf_counter(), self.cpu()
        yield
        own_after, kids_after = self.cpu()
        self.rows.append((item.nodeid, time.perf_counter() - wall, own_after - own, kids_after - kids))


def run_idle(args: argparse.Namespace) -> int:
    meter = IdleMeter()
    code = pytest.main(["-q", "-n", "0", "-p", "no:cacheprovider", *args.files], plugins=[meter])
    quiet = durations(args.quiet_durations) if args.quiet_durations else {}
    per_file: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0.0, 0.0, 0.0])
    for nodeid, wall, own, kids in meter.rows:
        row = per_file[nodeid.split("::", 1)[0]]
        row[0] += wall
        row[1] += own
        row[2] += kids
        row[3] += quiet.get(nodeid, 0.0)
    print(f"{'file':45s} {'wall':>7s} {'own CPU':>8s} {'children':>8s}"
          + (f" {'quiet wall':>10s} {'idle':>6s}" if quiet else ""))
    total = [0.0, 0.0, 0.0, 0.0]
    for name, row in sorted(per_file.items(), key=lambda kv: -(kv[1][3] - kv[1][1] - kv[1][2])):
        total = [a + b for a, b in zip(total, row, strict=True)]
        print(f"{name:45s} {row[0]:7.2f} {row[1]:8.2f} {row[2]:8.2f}"
              + (f" {row[3]:10.2f} {row[3] - row[1] - row[2]:6.2f}" if quiet else ""))
    print(f"{'total':45s} {total[0]:7.2f} {total[1]:8.2f} {total[2]:8.2f}"
          + (f" {total[3]:10.2f} {total[3] - total[1] - total[2]:6.2f}" if quiet else ""))
    return int(code)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    rep = commands.add_parser("replay", help="replay xdist's loadfile schedule on a --durations=0 listing")
    rep.add_argument("durations", type=Path)
    rep.add_argument("--workers", type=int, default=2)
    rep.add_argument("--start", type=float, default=5.0, help="seconds before a worker's first test")
    rep.add_argument("--per-test", type=float, default=0.0015, help="seconds a test beyond its listed phases")
    rep.add_argument("--draws", type=int, default=5)
    rep.add_argument("--seed", type=int, default=30)
    idle = commands.add_parser("idle", help="wall, own and children's CPU of test files, run in this process")
    idle.add_argument("--quiet-durations", type=Path)
    idle.add_argument("files", nargs="+")
    args = parser.parse_args()
    if args.command == "replay":
        run_replay(args)
        return 0
    return run_idle(args)


if __name__ == "__main__":
    sys.exit(main())
