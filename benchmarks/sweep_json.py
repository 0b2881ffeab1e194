"""What ``sweep --json`` costs now that it carries the points (docs/performance.md, "Other benchmarks"): the
issue's grid, this tree against a baseline checkout, interleaved, each run a fresh process.

    OPENBLAS_NUM_THREADS=1 python benchmarks/sweep_json.py --baseline /work/base/cfb251d [--grid 201] [--repeats 3]

Times ``packetloss-cvx sweep two_actuator --mu-grid K --json -q`` as a whole (the sweep, the summary, the
points' JSON and its printing): the child's CPU time (resource.RUSAGE_CHILDREN, user + system), and the
bytes printed on stdout. Prints each side's median and the ratio.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def one(tree: str, grid: int) -> tuple[float, int]:
    env = {**os.environ, "PYTHONPATH": tree, "OPENBLAS_NUM_THREADS": "1"}     # run outside both trees
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run([sys.executable, "-m", "packetloss_cvx", "sweep", "two_actuator", "--mu-grid", str(grid),
                           "--json", "-q"], env=env, capture_output=True, check=True, cwd=tempfile.gettempdir())
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, len(done.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", required=True, help="a checkout of the commit to compare with")
    parser.add_argument("--grid", type=int, default=201)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    runs: dict[str, list[tuple[float, int]]] = {"baseline": [], "this tree": []}
    for _ in range(args.repeats):                        # interleaved: old, new, old, new, ...
        runs["baseline"].append(one(args.baseline, args.grid))
        runs["this tree"].append(one(str(ROOT), args.grid))
    cpu = {side: statistics.median(c for c, _ in rows) for side, rows in runs.items()}
    for side, rows in runs.items():
        print(f"{side:>9}: CPU {', '.join(f'{c:.2f}' for c, _ in rows)} s (median {cpu[side]:.2f}); "
              f"stdout {rows[0][1]:,} bytes")
    print(f"ratio this tree / baseline (CPU median): {cpu['this tree'] / cpu['baseline']:.2f}")


if __name__ == "__main__":
    main()
