"""The coupled homogeneous Riccati eigenpair behind Gilbert-Elliott chains (closedloop.markov_region), this tree
against a baseline checkout, side by side in one run (docs/performance.md, "Other benchmarks").

    OPENBLAS_NUM_THREADS=1 python benchmarks/coupled_eigenpair.py --baseline /work/base/1bc1ef6 [--repeats 2]

The 24 chains of tests/closedloop/test_markov_region.py's "current"-convention test (seeds 100..105, four chains each),
each tree in a fresh interpreter started in its own folder (interleaved, best of ``--repeats``), CPU seconds
(time.process_time) around the 24 calls of ``homogeneous_coupled_riccati``, and per tree the accuracy: the
chains where ``|lambda - rho(L_K)| > 1e-9 lambda``, K the returned gains and rho closedloop.mjls's
operator (the radius of the law the eigenpair reports: lambda where K is the minimiser; a least-squares gain that
leaves a mode P vanishes on at 0 can be dearer), the largest and the second largest.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

SCRIPT = """
import json, time, numpy as np
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.closedloop.mjls import mean_square_radius
from packetloss_cvx.closedloop import markov_region as mr
cases = []
for seed in range(6):
    rng = np.random.default_rng(100 + seed)
    A = np.array([[1.0 + rng.uniform(0, 0.4), rng.uniform(-0.5, 0.5)], [0.0, rng.uniform(0.5, 1.3)]])
    B = rng.normal(size=(2, 2))
    cases += [(A, B, GilbertElliott(p=rng.uniform(0.05, 0.6, 2), r=rng.uniform(0.05, 0.9, 2))) for _ in range(4)]
start = time.process_time()
found = [mr.homogeneous_coupled_riccati(A, B, ch, "current") for A, B, ch in cases]
seconds = time.process_time() - start
gaps = [abs(lam - mean_square_radius(A, B, ch, K, "current")) / lam for (A, B, ch), (lam, P, K) in zip(cases, found)]
print(json.dumps([seconds, sum(g > 1e-9 for g in gaps), max(gaps), sorted(gaps)[-2]]))
"""


def run(tree: Path) -> list[float]:
    env = dict(os.environ, PYTHONPATH=str(tree), OPENBLAS_NUM_THREADS="1")
    # cwd = the tree: "-c" puts the working folder first on sys.path, ahead of PYTHONPATH
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True,
                         cwd=tree)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--baseline", type=Path, required=True, help="a checkout of the commit to compare against")
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    old, new = [], []
    for _ in range(args.repeats):
        old.append(run(args.baseline))
        new.append(run(ROOT))
    print("| tree | CPU s (24 chains) | chains abs(lambda - rho(L_K)) > 1e-9 lambda | largest | second largest |")
    print("|---|---|---|---|---|")
    for name, runs in (("baseline", old), ("this tree", new)):
        seconds, count, gap, second = min(runs)
        print(f"| {name} | {seconds:.3f} | {count} | {gap:.1e} | {second:.1e} |")
    print(f"ratio {min(old)[0] / min(new)[0]:.1f}")


if __name__ == "__main__":
    main()
