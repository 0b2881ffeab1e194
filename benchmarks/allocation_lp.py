"""The branch and bound's LPs through scipy's HiGHS called directly (allocation.boxes.highs_optimum) against
linprog (the checkout given, e.g. e520261): CPU seconds (time.process_time, OPENBLAS_NUM_THREADS=1) of each case
in a fresh process per checkout, the checkouts interleaved, the best of ``--rounds``, ratios side by side, and
the answers (cost, lower bound, boxes, the point) compared: they must be identical (the same simplex runs, bit for bit).

Cases: the UDP-like power problems of issue 24 on two_actuator (exponential, c = (1, 2)): least cost within
B = 3 (least_cost_within_power's docstring, 766 boxes) and least power at alpha = 8; the UDP-like mu
allocation with the row mu1 >= mu2 (alpha = 6, beta = (1, 1)); the UDP-like least cost within beta'mu <= 1.

    OPENBLAS_NUM_THREADS=1 python benchmarks/allocation_lp.py --baseline /work/base/e520261 [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

#: run in each checkout: every case once, one JSON line of [seconds, cost, lower bound, boxes, point] per case
CASES = """
import json, time
from packetloss_cvx import load_example
from packetloss_cvx.allocation import allocate, best_cost_within_budget, parse_constraint
from packetloss_cvx.allocation.delivery import power_model
from packetloss_cvx.allocation.power import least_cost_within_power, least_power
t, model = load_example("two_actuator"), power_model("exponential", 2, scale=[1.0, 2.0])
cases = {
    "least cost within power B = 3 (udp)": lambda: least_cost_within_power(t, "udp", model, 3.0),
    "least power alpha = 8 (udp)": lambda: least_power(t, "udp", model, 8.0),
    "allocate alpha = 6, mu1 >= mu2 (udp)": lambda: allocate(t, "udp", 6.0, (1.0, 1.0),
                                                              constraints=[parse_constraint("mu1 >= mu2", 2)]),
    "best cost within beta'mu <= 1 (udp)": lambda: best_cost_within_budget(t, "udp", (1.0, 1.0), 1.0),
}
least_cost_within_power(t, "udp", model, 0.5)        # imports and first-call work outside the clock
out = {}
for name, run in cases.items():
    start = time.process_time()
    r = run()
    seconds = time.process_time() - start
    point = getattr(r, "power", None) if hasattr(r, "power") else r.mu
    out[name] = [seconds, r.cost, r.lower_bound, getattr(r, "boxes", None), [float(v) for v in point]]
print(json.dumps(out))
"""


def run(checkout: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", CASES], env=env, capture_output=True, text=True, check=True,
                          cwd=checkout)         # (python -c puts the working folder first on sys.path)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, required=True, help="a checkout whose lp runs linprog")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    here = Path(__file__).resolve().parent.parent
    best: dict = {"new": {}, "old": {}}
    answers: dict = {"new": {}, "old": {}}
    for _ in range(args.rounds):                      # interleaved: old, new, old, new, ...
        for label, checkout in (("old", args.baseline), ("new", here)):
            for name, (seconds, *answer) in run(checkout).items():
                best[label][name] = min(best[label].get(name, float("inf")), seconds)
                answers[label][name] = answer
    print(f"| case | {args.baseline.name} (s) | this checkout (s) | ratio | same answer |")
    print("|---|---|---|---|---|")
    for name in best["new"]:
        old, new = best["old"][name], best["new"][name]
        same = answers["old"][name] == answers["new"][name]
        print(f"| {name} | {old:.2f} | {new:.2f} | {old / new:.1f}x | {'yes' if same else 'NO'} |")


if __name__ == "__main__":
    main()
