"""A small system's fixed costs, this tree against a baseline checkout, side by side in one run
(docs/performance.md, "Other benchmarks").

    OPENBLAS_NUM_THREADS=1 python benchmarks/small_system_overhead.py --baseline /work/base/4815b1d [--repeats 2]

What test_properties' 2800 random draws pay per example, and what a user pays per system loaded or solved: a
System from a TOML-like dict (time-invariant and time-varying weights), random_system with its options drawn,
and the default closed form on a freshly loaded system (its caches empty: the prediction matrices built).
Each tree runs in a fresh interpreter (PYTHONPATH = this tree, then the baseline; interleaved, best of
``--repeats`` rounds, each the best of 7 timing loops), timed in CPU microseconds per call (time.process_time),
and prints the closed form's cost so the two trees can be compared (they must be equal).
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
import packetloss_cvx as pl
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.model.random_systems import random_system

def per_call(f, k=300, rounds=7):
    f()
    best = float('inf')
    for _ in range(rounds):
        start = time.process_time()
        for _ in range(k):
            f()
        best = min(best, (time.process_time() - start) / k * 1e6)
    return best

fixed = random_system(np.random.default_rng(1), horizon=20, spectral_radius=0.9, time_varying=False).to_dict()
varying = random_system(np.random.default_rng(2), n=2, m=3, horizon=20, spectral_radius=0.9,
                        time_varying=True).to_dict()
out = {
    'System from a dict, one weight (us)': per_call(lambda: system_from_dict(fixed)),
    'System from a dict, 20 per-step weights (us)': per_call(lambda: system_from_dict(varying)),
    'random_system, options drawn (us)': per_call(
        lambda: [random_system(np.random.default_rng(i), horizon=20, spectral_radius=0.9) for i in range(10)],
        k=30) / 10,
    'closed_form udp on a fresh system, incl. loading (us)': per_call(
        lambda: pl.closed_form(system_from_dict(varying), 'udp')),
}
print(json.dumps([out, pl.closed_form(system_from_dict(varying), "udp").cost, pl.__file__]))
"""


def run(tree: Path) -> tuple[dict, float]:
    env = {**os.environ, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, cwd=tree, capture_output=True, text=True,
                          check=True)     # cwd: "-c" puts the working directory first on sys.path
    times, cost, where = json.loads(done.stdout.strip().splitlines()[-1])
    if not Path(where).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"{tree}: imported packetloss_cvx from {where}")
    return times, cost


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, required=True)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    best: dict[str, dict[str, float]] = {"this": {}, "baseline": {}}
    costs = {}
    for _ in range(args.repeats):
        for label, tree in (("this", ROOT), ("baseline", args.baseline)):
            times, costs[label] = run(tree)
            for name, us in times.items():
                best[label][name] = min(us, best[label].get(name, float("inf")))
    print(f"{'case':56s} {'baseline':>10s} {'this':>10s} {'ratio':>6s}")
    for name, us in best["this"].items():
        base = best["baseline"][name]
        print(f"{name:56s} {base:10.0f} {us:10.0f} {us / base:6.2f}")
    print(f"closed-form cost: baseline {costs['baseline']!r}, this {costs['this']!r}, "
          f"{'equal' if costs['baseline'] == costs['this'] else 'DIFFERENT'}")


if __name__ == "__main__":
    main()
