"""The exact UDP-like minimum under a Gilbert–Elliott channel: the augmented recursion against the dense route,
side by side in one run (docs/performance.md, "Other benchmarks").

    OPENBLAS_NUM_THREADS=1 python benchmarks/markov_recursion.py [--quick] [--json]

1. pendulum_bursty as shipped (rho(A) = 1.0615) at N = 80, 250, 500, 1000: ``exact_closed_form`` with
   method="recursion" and method="dense", CPU time (time.process_time) and tracemalloc peak, the runs interleaved
   (best of 3), and the relative difference of the two minima. Beyond N of about 5000 its exact cost (growing as
   rho^(2N)) leaves the double range: both routes raise NumericalError there.
2. Its stabilised twin (A scaled to rho(A) = 0.99, the same B, weights and channel) at N = 1e3, 1e4, 1e5: the
   recursion's CPU time and memory peak, the fitted time exponent (log-log slope over the three horizons) and
   bytes per step; the dense route beside it where it fits the memory budget (N = 1e3; refused above).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import packetloss_cvx as pl  # noqa: E402
from packetloss_cvx.errors import NumericalError, ResourceError  # noqa: E402
from packetloss_cvx.lq.markov_cost import exact_closed_form  # noqa: E402


def at_horizon(system, horizon, A=None):
    return pl.System(A=system.A if A is None else A, B=system.B, horizon=horizon,
                     state_weight=np.diag(system.state_weights[0]), input_weight=system.input_weights[0],
                     x0=system.x0, channel=system.channel)


def run(system, method):
    try:
        return exact_closed_form(system, "udp", method=method).cost
    except (NumericalError, ResourceError) as err:
        return type(err).__name__


def measure(build, method):
    """(CPU seconds, tracemalloc peak bytes, cost) of exact_closed_form on a fresh system (nothing kept on it from
    an earlier run): the time of a run without tracing (tracemalloc slows every allocation), the peak of a
    second, traced run."""
    system = build()
    start = time.process_time()
    cost = run(system, method)
    seconds = time.process_time() - start
    system = build()
    tracemalloc.start()
    run(system, method)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return seconds, peak, cost


def best_of(build, methods, repeats):
    """Interleaved runs (method by method, repeat by repeat); the least CPU time of each, its peak and cost."""
    out = {m: None for m in methods}
    for _ in range(repeats):
        for m in methods:
            r = measure(build, m)
            out[m] = r if out[m] is None or r[0] < out[m][0] else out[m]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="section 1 to N = 500, section 2 to N = 1e4, 1 run")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    base = pl.load_example("pendulum_bursty")
    report = {"shipped": [], "stabilised": []}
    print(f"1. pendulum_bursty as shipped (rho(A) = {max(abs(np.linalg.eigvals(base.A))):.4f}): recursion | dense")
    print(f"{'N':>6} {'rec s':>8} {'rec MB':>8} {'dense s':>8} {'dense MB':>9} {'ratio':>7} {'rel diff':>9}")
    for N in (80, 250, 500) if args.quick else (80, 250, 500, 1000):
        r = best_of(lambda N=N: at_horizon(base, N), ("recursion", "dense"), repeats)
        (ts, ms, cs), (td, md, cd) = r["recursion"], r["dense"]
        diff = abs(cs - cd) / abs(cd)
        print(f"{N:>6} {ts:8.3f} {ms / 1e6:8.2f} {td:8.3f} {md / 1e6:9.1f} {td / ts:7.1f} {diff:9.1e}")
        report["shipped"].append({"N": N, "recursion_s": ts, "recursion_bytes": ms, "dense_s": td, "dense_bytes": md,
                                  "cost": cs, "relative_difference": diff})
    A = base.A / max(abs(np.linalg.eigvals(base.A))) * 0.99
    print("2. its stabilised twin (rho(A) = 0.99): recursion, dense where it fits")
    print(f"{'N':>7} {'rec s':>8} {'rec MB':>8} {'B/step':>7} {'dense':>26} {'cost':>14}")
    horizons = (1000, 10000) if args.quick else (1000, 10000, 100000)
    for N in horizons:
        s = at_horizon(base, N, A)
        methods = ("recursion", "dense") if N <= 1000 else ("recursion",)
        r = best_of(lambda N=N: at_horizon(base, N, A), methods, repeats if N < 100000 else 1)
        ts, ms, cs = r["recursion"]
        if "dense" in r:
            td, md, cd = r["dense"]
            dense = f"{td:.2f} s {md / 1e6:.0f} MB {abs(cs - cd) / cd:.0e}"
        else:
            try:
                exact_closed_form(s, method="dense")
                dense = "ran"
            except ResourceError as err:
                dense = f"refused ({err.needed_bytes / 2**30:.0f} GiB)"
        print(f"{N:>7} {ts:8.3f} {ms / 1e6:8.2f} {ms / N:7.0f} {dense:>26} {cs:14.8g}")
        report["stabilised"].append({"N": N, "recursion_s": ts, "recursion_bytes": ms, "cost": cs, "dense": dense})
    Ns = np.array([row["N"] for row in report["stabilised"]], float)
    ts = np.array([row["recursion_s"] for row in report["stabilised"]])
    ms = np.array([row["recursion_bytes"] for row in report["stabilised"]], float)
    report["time_exponent"] = float(np.polyfit(np.log(Ns), np.log(ts), 1)[0])
    report["memory_exponent"] = float(np.polyfit(np.log(Ns), np.log(ms), 1)[0])
    print(f"time exponent {report['time_exponent']:.3f}, memory exponent {report['memory_exponent']:.3f}")
    if args.json:
        print(json.dumps(report))


if __name__ == "__main__":
    main()
