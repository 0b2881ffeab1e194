"""The UDP-like searches (allocation/): this checkout against another (e.g. e520261), CPU seconds
(time.process_time, OPENBLAS_NUM_THREADS=1) of each case in a fresh process per checkout, the checkouts
interleaved, the best of ``--rounds``, ratios side by side, and the answers compared: the relative difference of
the objectives (cost or power, at most the requested gap where both are certified) and whether both are
certified. Session 29: the LPs through scipy's HiGHS called directly (boxes.highs_optimum, bit for bit
linprog's answer) and the line search's end game (boxes.bracket) without its creep by tol / 4.

Cases: the UDP-like power problems of issue 24 on two_actuator (exponential, c = (1, 2)): least cost within
B = 3 (least_cost_within_power's docstring, 766 boxes) and least power at alpha = 8; the UDP-like mu
allocation with the row mu1 >= mu2 (alpha = 6, beta = (1, 1)); the UDP-like least cost within beta'mu <= 1; the
UDP-like allocation behind Gilbert chains (issue 23 item 5, tests/allocation/test_allocation_chains.py's plant: lambda =
(0.6, 0.3), alpha 1.05 times the cost at the file's rates, beta = (1, 0.6), gap 1e-5); ``reproduce``'s 33 UDP-like
allocations of the two-actuator system (its step "allocations udp"; the objective column is then the largest move
of any coordinate of any allocation's mu, absolute, and "both certified" means all 33). Session 30: the checked
values remembered by allocation.udp.MonotoneCost (the searches check the same point again).

    OPENBLAS_NUM_THREADS=1 python benchmarks/allocation_search.py --baseline /work/base/e520261 [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

#: run in each checkout: every case once, one JSON line of [seconds, objective, certified] per case
CASES = """
import json, time
import packetloss_cvx as pl
from packetloss_cvx import load_example
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.lq.markov_cost import exact_closed_form
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
chain = pl.System(A=[[1.05, 0.2], [0.0, 0.9]], B=[[0.0, 1.0], [1.0, 0.3]], horizon=4, state_weight=[1.0, 1.0],
                  input_weight=[0.5, 0.5], x0=[1.0, 1.0], channel=GilbertElliott(p=[0.08, 0.35], r=[0.32, 0.35]))
cases["allocate behind Gilbert chains, gap 1e-5 (udp)"] = lambda: allocate(
    chain, "udp", 1.05 * exact_closed_form(chain).cost, (1.0, 0.6), gap=1e-5)
from packetloss_cvx.studies import paper_figures as pf
from packetloss_cvx.claims.paper import ALLOCATION_BETAS
from packetloss_cvx.cli.reproduce import ALPHAS
cases["reproduce's 33 allocations (udp)"] = lambda: pf.mixed_allocations(t, "udp", ALPHAS, ALLOCATION_BETAS,
                                                                          progress=False)
least_cost_within_power(t, "udp", model, 0.5)        # imports and first-call work outside the clock
out = {}
for name, run in cases.items():
    start = time.process_time()
    r = run()
    seconds = time.process_time() - start
    if isinstance(r, dict):                   # the 33 allocations: every mu, and whether all are certified
        out[name] = [seconds, [x for rows in r.values() for row in rows for x in row["mu"]],
                     all(row["status"] == "optimal" for rows in r.values() for row in rows)]
        continue
    if hasattr(r, "total_power"):
        value = r.total_power if r.problem == "least-power" else r.cost
    else:
        value = getattr(r, "communication_cost", r.cost)
    out[name] = [seconds, value, r.status == "optimal"]
print(json.dumps(out))
"""


def run(checkout: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", CASES], env=env, capture_output=True, text=True, check=True,
                          cwd=checkout)         # (python -c puts the working folder first on sys.path)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, required=True, help="the checkout to compare with")
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
    print(f"| case | {args.baseline.name} (s) | this checkout (s) | ratio | objective, relative difference "
          f"| both certified |")
    print("|---|---|---|---|---|---|")
    for name in best["new"]:
        old, new = best["old"][name], best["new"][name]
        (a, a_ok), (b, b_ok) = answers["old"][name], answers["new"][name]
        moved = max(abs(x - y) for x, y in zip(a, b, strict=True)) if isinstance(a, list) else abs(b - a) / abs(a)
        print(f"| {name} | {old:.2f} | {new:.2f} | {old / new:.1f}x | {moved:.1e} "
              f"| {'yes' if a_ok and b_ok else 'NO'} |")


if __name__ == "__main__":
    main()
