"""What safe writes cost (docs/performance.md, "Other benchmarks"): saving issue 20's large sweep, this tree
against a baseline checkout, interleaved, in fresh processes.

    OPENBLAS_NUM_THREADS=1 python benchmarks/safe_writes.py --baseline /work/base/cfb251d [--points 400000]
        [--repeats 3] [--json]

Each run computes ``sweep(two_actuator, x0_scales=linspace(0, 1, P))`` (not timed) and then times
``save_sweep(result, DIR)`` into a fresh folder: CPU time (time.process_time: the writes, the CSV text,
and here the manifest's sha256 of every file) and wall time (which holds the fsyncs). The same snippet
runs on both sides: the baseline's save_sweep writes in place, this tree's writes atomically with a lock
and a manifest.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

SNIPPET = """
import sys, time, tempfile
import numpy as np
import packetloss_cvx as pl
from packetloss_cvx.studies import save_sweep, sweep
points = int(sys.argv[1])
result = sweep(pl.load_example("two_actuator"), x0_scales=np.linspace(0.0, 1.0, points), progress=False)
with tempfile.TemporaryDirectory(dir=sys.argv[2]) as tmp:
    cpu, wall = time.process_time(), time.perf_counter()
    save_sweep(result, tmp + "/out")
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
print(cpu, wall)
"""


def one(tree: str, points: int, scratch: str) -> tuple[float, float]:
    env = {**os.environ, "PYTHONPATH": tree, "OPENBLAS_NUM_THREADS": "1"}
    # cwd=tree: "python -c" puts the working folder ahead of PYTHONPATH (the baseline would import this tree)
    done = subprocess.run([sys.executable, "-c", SNIPPET, str(points), str(Path(scratch).resolve())], env=env,
                          capture_output=True, text=True, check=True, cwd=tree)
    cpu, wall = map(float, done.stdout.split())
    return cpu, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", required=True, help="a checkout of the commit to compare with")
    parser.add_argument("--points", type=int, default=400_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    runs: dict[str, list[tuple[float, float]]] = {"baseline": [], "this tree": []}
    with tempfile.TemporaryDirectory() as scratch:
        for _ in range(args.repeats):                        # interleaved: old, new, old, new, ...
            runs["baseline"].append(one(args.baseline, args.points, scratch))
            runs["this tree"].append(one(str(ROOT), args.points, scratch))
    best = {side: (min(c for c, _ in r), min(w for _, w in r)) for side, r in runs.items()}
    ratio = (best["this tree"][0] / best["baseline"][0], best["this tree"][1] / best["baseline"][1])
    if args.json:
        print(json.dumps({"points": args.points, "runs": runs, "best": best, "ratio_cpu": ratio[0],
                          "ratio_wall": ratio[1]}))
        return
    print(f"save_sweep of a {args.points}-point x0-scale sweep of two_actuator (best of {args.repeats}, interleaved)")
    for side, (cpu, wall) in best.items():
        print(f"  {side:10s} CPU {cpu:6.2f} s   wall {wall:6.2f} s")
    print(f"  ratio (this tree / baseline): CPU {ratio[0]:.2f}, wall {ratio[1]:.2f}")


if __name__ == "__main__":
    main()
