"""The exact chain cost evaluated point by point, as a chain allocation's references and searches do: the
41 x 41 grid of mean rates of tests/allocation/test_allocation_chains.py (two channels, N = 4, Gilbert channels with
burstiness (0.6, 0.3) held; ChainEvaluator.cost, i.e. exact_closed_form by the augmented recursion) and the
same grid behind a 3-state chain on channel 2 (deliveries scaled). CPU seconds (time.process_time,
OPENBLAS_NUM_THREADS=1), least of the rounds; with --baseline the same cases run by that checkout in a
subprocess, interleaved round by round, ratios side by side and the floats compared bit for bit.

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD python benchmarks/chain_grid.py --baseline /work/base/4815b1d
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: run by either checkout: one JSON line of [case, CPU seconds, the costs]
CASES = """
import json, time
import numpy as np
import packetloss_cvx as pl
from packetloss_cvx.allocation.chains import ChainEvaluator, chain_family
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.channel import MarkovChannel

def two_channel(channel):
    return pl.System(A=[[1.05, 0.2], [0.0, 0.9]], B=[[0.0, 1.0], [1.0, 0.3]], horizon=4, state_weight=[1.0, 1.0],
                     input_weight=[0.5, 0.5], x0=[1.0, 1.0], channel=channel)

gilbert = two_channel(GilbertElliott(p=[0.08, 0.35], r=[0.32, 0.35])).with_mu([0.8, 0.5])
three = [[0.8, 0.15, 0.05], [0.2, 0.6, 0.2], [0.1, 0.3, 0.6]]
mixed = two_channel(MarkovChannel(transition=[[[0.9, 0.1], [0.3, 0.7]], three],
                                  delivery=[[1.0, 0.0], [0.9, 0.5, 0.0]]))
cases = {"41 x 41 grid, Gilbert channels": (ChainEvaluator(gilbert, np.array([0.6, 0.3])), 1.0),
         "41 x 41 grid, a Gilbert and a 3-state chain": (ChainEvaluator(mixed, chain_family(mixed)), None)}
out = []
for name, (ev, top) in cases.items():
    top = ev.family.top[1] if top is None else top
    points = [np.array([x, y]) for x in np.linspace(0.0, 1.0, 41) for y in np.linspace(0.0, top, 41)]
    start = time.process_time()
    costs = [ev.cost(mu) for mu in points]
    out.append([name, time.process_time() - start, costs])
print(json.dumps(out))
"""


def run(tree: str) -> list:
    env = {**os.environ, "PYTHONPATH": tree, "OPENBLAS_NUM_THREADS": "1"}
    # cwd=tree: "python -c" puts the working folder ahead of PYTHONPATH, so run elsewhere the baseline would import
    # the tree the benchmark is run from
    return json.loads(subprocess.run([sys.executable, "-c", CASES], env=env, capture_output=True, text=True,
                                     check=True, cwd=tree).stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="a checkout to run side by side")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    times: dict[str, dict[str, list[float]]] = {}
    answers: dict[str, dict[str, list]] = {}
    trees = [("this tree", str(ROOT))] + ([("baseline", args.baseline)] if args.baseline else [])
    for _ in range(args.rounds):
        for label, tree in trees:
            for name, seconds, values in run(tree):
                times.setdefault(name, {}).setdefault(label, []).append(seconds)
                answers.setdefault(name, {})[label] = values
    for name, by in times.items():
        line = f"{name}: this tree {min(by['this tree']):.3f} s"
        if args.baseline:
            same = answers[name]["this tree"] == answers[name]["baseline"]
            line += (f", baseline {min(by['baseline']):.3f} s, ratio {min(by['baseline']) / min(by['this tree']):.2f}x"
                     f", costs {'identical' if same else 'DIFFERENT'}")
        print(line + " (least of the rounds, CPU)")


if __name__ == "__main__":
    main()
