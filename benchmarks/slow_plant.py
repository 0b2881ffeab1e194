"""Section 20 of benchmarks/run.py: closed_form on a slowly converging plant against scipy's DARE, this checkout beside
a baseline checkout, and whether both give the same numbers.

    OPENBLAS_NUM_THREADS=1 python benchmarks/slow_plant.py [--baseline ../main] [--rounds 5] [--N 10000] [--stages]

The plant: the paper's pendulum A (packetloss_cvx/model/examples/pendulum.toml, rho(A) = 1.06) with two inputs,
B = [[0.001, 0.2], [0.540, 0.0], [-0.002, 0.1], [-1.066, 0.3]], weights diag(5, 1, 1, 1) and (2, 1),
x0 = (0.1, 0, 0.1, 0), mu = 1: its Riccati pass contracts by about 0.98 a step (about 1,600 steps before its tail
settles) and its plan is rolled out through an unstable A. Each round runs one fresh process per checkout
(interleaved, one BLAS thread): closed_form(method="recursion") on one System, TCP-like and UDP-like, against
scipy's solve_discrete_are on the same (A, B, Q, R) called back to back (the second call timed: a warm DARE),
alternating, CPU time (``time.process_time``), medians over the repeats; the ratio closed_form / DARE per round, its
median and range. The same processes return the cost, plan and gain at N and at N = 2000 and 300, also with mu =
(0.9, 0.6) and (1, 0): the largest difference between the checkouts relative to each array's largest entry. Last,
the same figures as the Markdown table of docs/performance.md's section 20 (each checkout named by its commit).

``--stages``: where one TCP-like call's time goes in this checkout, in fresh processes (one per round, medians of
the per-round medians): building the System (not part of the call), the backward pass (``backward_pass``), the
rollout (``optimal_plan`` less the pass), the self-check's referee (``recursion_cost`` on the law's states), the
Solution, the mean-square verdict (``with_stability``), against the whole call and a warm DARE. Each stage is
timed alone through the public functions, so the parts add up to the call only roughly.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import textwrap
from collections.abc import Mapping
from pathlib import Path

import numpy as np

A = [[1.001, 0.005, 0.000, 0.000], [0.35, 1.001, -0.135, 0.000], [-0.001, 0.000, 1.001, 0.005],
     [-0.375, -0.001, 0.590, 1.001]]
B = [[0.001, 0.2], [0.540, 0.0], [-0.002, 0.1], [-1.066, 0.3]]

#: One process: the timings at N and the numbers of every case, as JSON on the last line of stdout.
RUN_CODE = """
import json, statistics, sys, time
import numpy as np
from scipy.linalg import solve_discrete_are
import packetloss_cvx as pl
data = json.loads(sys.argv[1])
A, B = np.array(data["A"]), np.array(data["B"])
Q, R = np.diag([5.0, 1.0, 1.0, 1.0]), np.diag([2.0, 1.0])
def system(N, mu=(1.0, 1.0)):
    return pl.System(A=A, B=B, horizon=N, state_weight=[5, 1, 1, 1], input_weight=[2, 1], mu=list(mu),
                     x0=[0.1, 0, 0.1, 0])
out = {"times": {}, "numbers": {}}
s = system(data["N"])
for protocol in ("tcp", "udp"):
    pl.closed_form(s, protocol, "recursion")
    dare, closed = [], []
    for _ in range(data["repeats"]):
        solve_discrete_are(A, B, Q, R)
        start = time.process_time()
        solve_discrete_are(A, B, Q, R)
        dare.append(time.process_time() - start)
        start = time.process_time()
        pl.closed_form(s, protocol, "recursion")
        closed.append(time.process_time() - start)
    out["times"][protocol] = {"dare": statistics.median(dare), "closed": statistics.median(closed)}
for N in sorted({300, 2000, data["N"]}):
    for mu in ((1.0, 1.0), (0.9, 0.6), (1.0, 0.0)):
        for protocol in ("tcp", "udp"):
            key = f"N={N} mu={mu} {protocol}"
            try:
                sol = pl.closed_form(system(N, mu), protocol, "recursion")
                out["numbers"][key] = {"cost": sol.cost, "inputs": sol.inputs.tolist(), "gain": sol.gain.tolist()}
            except pl.NumericalError as exc:
                out["numbers"][key] = {"error": type(exc).__name__}
print(json.dumps(out))
"""


def _run(checkout: Path, N: int, repeats: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
    arg = json.dumps({"A": A, "B": B, "N": N, "repeats": repeats})
    text = subprocess.run([sys.executable, "-c", RUN_CODE, arg], env=env, check=True, capture_output=True, text=True,
                          cwd=checkout).stdout
    return json.loads(text.strip().splitlines()[-1])


#: One process: each stage of a TCP-like call timed alone (medians in ms), as JSON on the last line of stdout.
STAGES_CODE = """
import json, statistics, sys, time
import numpy as np
from scipy.linalg import solve_discrete_are
import packetloss_cvx as pl
from packetloss_cvx.closedloop.law_stability import with_stability
from packetloss_cvx.lq import costs
from packetloss_cvx.lq.recursion import backward_pass, optimal_plan, recursion_cost
from packetloss_cvx.results import Solution
data = json.loads(sys.argv[1])
A, B = np.array(data["A"]), np.array(data["B"])
Q, R = np.diag([5.0, 1.0, 1.0, 1.0]), np.diag([2.0, 1.0])
def system():
    return pl.System(A=A, B=B, horizon=data["N"], state_weight=[5, 1, 1, 1], input_weight=[2, 1], mu=[1.0, 1.0],
                     x0=[0.1, 0, 0.1, 0])
s = system()
sol = costs.closed_form(s, "tcp", "recursion")
K0, P0, noise, U, X = optimal_plan(s, "tcp")
stages = {
    "warm DARE": lambda: solve_discrete_are(A, B, Q, R),
    "System construction (outside the call)": system,
    "closed_form, the whole call": lambda: pl.closed_form(s, "tcp", "recursion"),
    "backward pass (doubling, powers, batched steps)": lambda: backward_pass(s, "tcp"),
    "backward pass and rollout (optimal_plan)": lambda: optimal_plan(s, "tcp"),
    "self-check's referee (forward cost of the law's states)": lambda: recursion_cost(s, U, "tcp", None, X[1:]),
    "Solution (eigenvalues, read-only copies)": lambda: Solution(
        protocol="tcp", cost=sol.cost, inputs=U, gain=K0, closed_loop_eigenvalues=np.linalg.eigvals(A - B @ K0),
        method="recursion"),
    "mean-square verdict (with_stability)": lambda: with_stability(s, sol),
}
out = {}
for name, fn in stages.items():
    fn()
    times = []
    for _ in range(data["repeats"]):
        start = time.process_time()
        fn()
        times.append(time.process_time() - start)
    out[name] = statistics.median(times) * 1e3
print(json.dumps(out))
"""


def stages(rounds: int = 5, N: int = 10_000, repeats: int = 41) -> dict[str, float]:
    """``--stages`` (module docstring): the median over rounds of each stage's CPU ms, printed as a Markdown table."""
    checkout = Path(__file__).resolve().parent.parent
    env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
    arg = json.dumps({"A": A, "B": B, "N": N, "repeats": repeats})
    runs = [json.loads(subprocess.run([sys.executable, "-c", STAGES_CODE, arg], env=env, check=True,
                                      capture_output=True, text=True, cwd=checkout).stdout.strip().splitlines()[-1])
            for _ in range(rounds)]
    medians = {name: statistics.median(r[name] for r in runs) for name in runs[0]}
    print(f"\n| stage of one TCP-like call, N = {N}, {_commit(checkout)} ({rounds} rounds) | CPU ms | / warm DARE |")
    print("|---|---|---|")
    for name, ms in medians.items():
        print(f"| {name} | {ms:.3f} | {ms / medians['warm DARE']:.1f}x |")
    return medians


def _differences(new: dict, base: dict) -> tuple[float, list[str]]:
    """The largest difference of cost, plan and gain over the cases, relative to each array's largest entry; the
    cases whose outcome (a value or an error) differs."""
    worst, differ = 0.0, []
    for key, b in base.items():
        a = new.get(key, {"error": "missing"})
        if ("error" in a) != ("error" in b) or a.get("error") != b.get("error"):
            differ.append(key)
            continue
        for name in ("cost", "inputs", "gain") if "error" not in b else ():
            x, y = np.asarray(a[name], dtype=float), np.asarray(b[name], dtype=float)
            scale = float(np.max(np.abs(y)))
            worst = max(worst, float(np.max(np.abs(x - y))) / scale if scale > 0 else float(np.max(np.abs(x))))
    return worst, differ


def slow_plant(baseline: str | None, rows: list, rounds: int = 5, N: int = 10_000, repeats: int = 9) -> None:
    """Section 20: see the module docstring."""
    checkouts = {"this": Path(__file__).resolve().parent.parent}
    if baseline:
        checkouts = {"baseline": Path(baseline).resolve(), **checkouts}
    print(f"\n20. closed_form on the slowly converging plant (rho(A) = 1.06), N = {N}, mu = 1, against a warm DARE on "
          f"the same (A, B, Q, R): CPU ms, {rounds} interleaved rounds of fresh processes, one BLAS thread")
    runs: dict[str, list[dict]] = {k: [] for k in checkouts}
    for _ in range(rounds):
        for name, checkout in checkouts.items():
            runs[name].append(_run(checkout, N, repeats))
    print(f"   {'checkout':<34} {'proto':>5} {'warm dare ms':>12} {'closed_form ms':>15} "
          f"{'/ dare, median (range)':>24}")
    table = []
    for name, checkout in checkouts.items():
        for protocol in ("tcp", "udp"):
            times = [r["times"][protocol] for r in runs[name]]
            ratios = [t["closed"] / t["dare"] for t in times]
            dare = statistics.median(t["dare"] for t in times) * 1e3
            closed = statistics.median(t["closed"] for t in times) * 1e3
            print(f"   {str(checkout):<34} {protocol:>5} {dare:>12.3f} {closed:>15.3f} "
                  f"{statistics.median(ratios):>10.1f}x ({min(ratios):.1f}-{max(ratios):.1f})")
            table.append(f"| {_commit(checkout)}, {protocol} | {dare:.3f} | {closed:.2f} | "
                         f"{statistics.median(ratios):.1f}x ({min(ratios):.1f}–{max(ratios):.1f}) |")
            rows.append({"bench": "slow_plant", "checkout": str(checkout), "N": N, "protocol": protocol,
                         "warm_dare_ms": dare, "closed_ms": closed, "ratio_to_dare": statistics.median(ratios),
                         "ratio_range": [min(ratios), max(ratios)]})
    if baseline:
        for protocol in ("tcp", "udp"):
            speedups = [b["times"][protocol]["closed"] / t["times"][protocol]["closed"]
                        for b, t in zip(runs["baseline"], runs["this"], strict=True)]
            print(f"   {protocol}: baseline / this {statistics.median(speedups):.2f}x "
                  f"({min(speedups):.2f}-{max(speedups):.2f})")
        worst, differ = _differences(runs["this"][0]["numbers"], runs["baseline"][0]["numbers"])
        print(f"   numbers (cost, plan, gain) of {len(runs['this'][0]['numbers'])} cases (N = 300, 2000, {N}; mu = 1, "
              f"(0.9, 0.6), (1, 0); both protocols): worst relative difference {worst:.1e}; outcomes that differ: "
              f"{differ or 'none'}")
        rows.append({"bench": "slow_plant_agreement", "worst_relative": worst, "outcomes_differ": differ})
    _markdown(table, rounds, N, {name: _commit(path) for name, path in checkouts.items()},
              (worst, differ, len(runs["this"][0]["numbers"])) if baseline else None)


def _commit(checkout: Path) -> str:
    """The checkout's commit (short hash, "+" when its tracked files differ from it), or its path outside git."""
    try:
        head = subprocess.run(["git", "-C", str(checkout), "rev-parse", "--short", "HEAD"], check=True,
                              capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(checkout), "diff", "--quiet", "HEAD", "--"], check=False).returncode
    except (OSError, subprocess.CalledProcessError):
        return str(checkout)
    return head + ("+" if dirty else "")


def _markdown(table: list[str], rounds: int, N: int, commits: Mapping[str, str],
              agreement: tuple[float, list[str], int] | None) -> None:
    """The figures as docs/performance.md's section 20 table (pasted there as printed)."""
    print(f"\n| closed_form, N = {N}, checkout and protocol | warm DARE ms | closed_form ms | / DARE, median "
          f"(range), {rounds} rounds |")
    print("|---|---|---|---|")
    print("\n".join(table))
    if agreement is not None:
        worst, differ, cases = agreement
        print("\n" + textwrap.fill(
            f"Costs, plans and gains of the {cases} cases (N = 300, 2000, {N}; mu = 1, (0.9, 0.6), (1, 0); both "
            f"protocols): {commits['this']} against {commits['baseline']} within {worst:.1e} of each array's "
            f"largest entry; outcomes that differ: {', '.join(differ) or 'none'}.", 120))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="a checkout to compare with (before/after and the numbers)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--N", type=int, default=10_000)
    parser.add_argument("--stages", action="store_true", help="where one call's time goes (this checkout only)")
    args = parser.parse_args()
    if args.stages:
        stages(args.rounds, args.N)
        return
    slow_plant(args.baseline, [], args.rounds, args.N)


if __name__ == "__main__":
    main()
