"""Design for stability and the stabilisable set, this tree against a baseline checkout, side by side in one run
(docs/performance.md, "Other benchmarks").

    OPENBLAS_NUM_THREADS=1 python benchmarks/stability_speed.py --baseline /work/base/e520261 [--repeats 2]

Each case runs in a fresh interpreter (PYTHONPATH = this tree, then the baseline; interleaved, best of
``--repeats``), timed in CPU seconds (time.process_time) around the call only, and prints its answer so the two
trees can be compared (the largest difference of mu, beta'mu and the lower bound; the boxes): the channel of
``stability_allocate`` (targets "stable" and "dp-cost", the cases of benchmarks/stability_design.py), and the
least radius ``homogeneous_riccati`` over a 21 x 21 grid of two_actuator point by point (the search's probe).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

CASES = {
    "stable (1, 1)": "stability_allocate(load_example('two_actuator'), 'stable', [1.0, 1.0], progress=False)",
    "stable (1, 1) margin 0.9, mu2 <= mu1": (
        "stability_allocate(load_example('two_actuator'), 'stable', [1.0, 1.0], margin=0.9, "
        "constraints=[([[-1.0, 1.0]], [0.0])], bounds=(0.01, 1.0), gap=1e-3, progress=False)"),
    "stable (1, 0.05)": "stability_allocate(load_example('two_actuator'), 'stable', [1.0, 0.05], progress=False)",
    "stable (1, 0.3)": "stability_allocate(load_example('two_actuator'), 'stable', [1.0, 0.3], progress=False)",
    "stable (1, 1) margin 0.5": (
        "stability_allocate(load_example('two_actuator'), 'stable', [1.0, 1.0], margin=0.5, progress=False)"),
    "dp-cost (1, 0.05) alpha 10": (
        "stability_allocate(load_example('two_actuator'), 'dp-cost', [1.0, 0.05], alpha=10.0, progress=False)"),
    "dp-cost (1, 1) alpha 10": (
        "stability_allocate(load_example('two_actuator'), 'dp-cost', [1.0, 1.0], alpha=10.0, progress=False)"),
    "least radius, 441 points one by one": (
        "[homogeneous_riccati(s.A, s.B, np.array([x, y]))[0] for x in np.linspace(0, 1, 21) "
        "for y in np.linspace(0, 1, 21)]"),
}

SCRIPT = """
import json, time, numpy as np
from packetloss_cvx import load_example
from packetloss_cvx.allocation.stability import stability_allocate
from packetloss_cvx.closedloop.region import homogeneous_riccati
s = load_example('two_actuator')
start = time.process_time()
got = {call}
seconds = time.process_time() - start
answer = got.mu.tolist() + [got.cost, got.lower_bound, got.boxes] if hasattr(got, 'mu') else [float(np.max(got))]
print(json.dumps([seconds, answer]))
"""


def run(tree: Path, call: str) -> tuple[float, list]:
    env = dict(os.environ, PYTHONPATH=str(tree), OPENBLAS_NUM_THREADS="1")
    # cwd = the tree: "-c" puts the working folder first on sys.path, ahead of PYTHONPATH
    out = subprocess.run([sys.executable, "-c", SCRIPT.format(call=call)], env=env, capture_output=True, text=True,
                         check=True, cwd=tree)
    seconds, answer = json.loads(out.stdout.strip().splitlines()[-1])
    return seconds, answer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--baseline", type=Path, required=True, help="a checkout of the commit to compare against")
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    print("| case | baseline CPU s | this tree CPU s | ratio | largest answer difference | boxes |")
    print("|---|---|---|---|---|---|")
    for name, call in CASES.items():
        old, new = [], []
        for _ in range(args.repeats):
            old.append(run(args.baseline, call))
            new.append(run(ROOT, call))
        t_old, a_old = min(old)
        t_new, a_new = min(new)
        boxes = f"{a_old[-1]} -> {a_new[-1]}" if len(a_old) > 1 else "-"
        numbers = slice(0, -1) if len(a_old) > 1 else slice(None)
        diff = max(abs(x - y) for x, y in zip(a_old[numbers], a_new[numbers], strict=True))
        print(f"| {name} | {t_old:.2f} | {t_new:.2f} | {t_old / t_new:.2f} | {diff:.1e} | {boxes} |", flush=True)


if __name__ == "__main__":
    main()
