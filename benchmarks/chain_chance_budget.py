"""What a chance row exact under a Markov chain costs beside its plug-in twin, against the budgets' formulas
(packetloss_cvx.budgets: `constrained_work`, `mpc_solve_size`, `constrained_bytes` with ``states``).

    OPENBLAS_NUM_THREADS=1 python benchmarks/chain_chance_budget.py [--quick] [--json]

Per case, in a fresh interpreter each (the peak resident memory is the process's): ``ConstrainedQP(system, "tcp",
limits, u_prev=True)`` and its first solve (CPU time, "compile"), then three solves from new x0 (scaled by seeded
factors in [0.5, 1.5]) and, behind the chain, a new belief each (the TCP-like loop's case), the median ("re-solve"),
and the peak resident memory less that before the program ("peak"). The limits: an input box |u| <= 2 and one chance
row on the second state (the first for a scalar plant), b = 1.75, eps = 0.2. The plants: a scalar a = 0.95 behind a
Gilbert channel (p = 0.02, r = 0.18) and behind a 3-state chain; a 2-state, 2-input plant behind two Gilbert
channels; pendulum_bursty (its chance row binds at most steps). The plug-in twin is the same system at the chain's
predicted mu_t (Bernoulli losses). A solve that fails is marked; its time is not a solve's.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

CHANNELS = {
    "gilbert": {"model": "gilbert-elliott", "p": [0.02], "r": [0.18], "h_good": [1.0], "h_bad": [0.0]},
    "three": {"model": "markov", "transition": [[[0.9, 0.08, 0.02], [0.2, 0.6, 0.2], [0.3, 0.1, 0.6]]],
              "delivery": [[1.0, 0.5, 0.0]]},
    "two": {"model": "gilbert-elliott", "p": [0.02, 0.05], "r": [0.18, 0.2], "h_good": [1.0, 1.0],
            "h_bad": [0.0, 0.0]},
}
PLANTS = {
    "scalar": {"plant": {"A": [[0.95]], "B": [[1.0]]}, "cost": {"state_weight": [1.0], "input_weight": [1.0]},
               "state": {"x0": [1.0]}},
    "two": {"plant": {"A": [[0.9, 0.1], [0.05, 0.8]], "B": [[1.0, 0.0], [0.0, 1.0]]},
            "cost": {"state_weight": [1.0, 1.0], "input_weight": [1.0, 1.0]}, "state": {"x0": [1.0, 1.0]}},
}

SCRIPT = r"""
import json, resource, statistics, sys, time
import numpy as np
from importlib import resources
from packetloss_cvx.model.files import load_table, system_from_dict
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.qp.constrained import ConstrainedQP

table, N, exact = json.loads(sys.argv[1]), int(sys.argv[2]), sys.argv[3] == "exact"
data = (load_table(resources.files("packetloss_cvx.model.examples") / "pendulum_bursty.toml")
        if table == "pendulum_bursty" else table)
data["cost"]["horizon"] = N
s = system_from_dict(data)
n, m = s.n, s.m
if not exact:
    s = s.with_mu(s.mu_schedule)
a = np.zeros(n); a[1 if n > 1 else 0] = 1.0
limits = Constraints(u_min=np.full(m, -2.0), u_max=np.full(m, 2.0), chance=[(a, 1.75, 0.2)])
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
err = ""
start = time.process_time()
qp = ConstrainedQP(s, "tcp", limits, u_prev=True)
try:
    qp.solve(u_prev=np.zeros(m))
except Exception as e:
    err = type(e).__name__
compile_s = time.process_time() - start
rng, times = np.random.default_rng(1), []
for _ in range(3):
    kw = {}
    if exact:
        b = s.channel.initial_belief * rng.uniform(0.8, 1.2, s.channel.initial_belief.shape)
        kw["belief"] = b / b.sum(axis=-1, keepdims=True)
    t = time.process_time()
    try:
        qp.solve(x0=s.x0 * rng.uniform(0.5, 1.5, n), u_prev=np.zeros(m), **kw)
    except Exception as e:
        err = err or type(e).__name__
    times.append(time.process_time() - t)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - base
print(json.dumps({"n": n, "m": m, "compile": compile_s, "resolve": statistics.median(times), "peak": peak,
                  "err": err}))
"""

FULL = [("scalar", "gilbert", N) for N in (50, 100, 200)] + [("scalar", "three", N) for N in (50, 100)] + [
    ("two", "two", N) for N in (50, 100, 200)] + [("pendulum_bursty", "gilbert", N) for N in (60, 80, 100)]
QUICK = [("scalar", "gilbert", 50), ("scalar", "three", 50), ("two", "two", 50), ("pendulum_bursty", "gilbert", 60)]


def measure(plant: str, channel: str, N: int, exact: bool) -> dict:
    """One case in a fresh interpreter (this checkout, one BLAS thread, the budgets lifted)."""
    table = "pendulum_bursty" if plant == "pendulum_bursty" else {**PLANTS[plant], "channel": CHANNELS[channel]}
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1",
           "PACKETLOSS_CVX_BUDGET_SOLVE_WORK": "inf", "PACKETLOSS_CVX_BUDGET_MEMORY_BYTES": "inf"}
    done = subprocess.run([sys.executable, "-c", SCRIPT, json.dumps(table), str(N), "exact" if exact else "plug"],
                          env=env, cwd=ROOT, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    from packetloss_cvx.budgets import constrained_bytes, constrained_work, mpc_solve_size

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="N = 50 and 60 only (about half a minute)")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON at the end")
    args = parser.parse_args()
    print(f"{'plant':>16} {'chain':>8} {'N':>4} {'K':>2} | compile s: plug-in exact (predicted) | re-solve s: plug-in "
          f"exact (predicted) | peak MB: plug-in exact (predicted)")
    rows = []
    for plant, channel, N in QUICK if args.quick else FULL:
        plug, exact = measure(plant, channel, N, False), measure(plant, channel, N, True)
        n, m, K = exact["n"], exact["m"], 3 if channel == "three" else 2
        work = constrained_work(N, n, m, 1, K) * 1e-6
        solve = mpc_solve_size(N, n, m, 2 * N * m, 1, K) * 5e-3
        size = constrained_bytes(N, n, m, 2 * N * m, 1, K)
        failed = " failed" if plug["err"] or exact["err"] else ""
        print(f"{plant:>16} {channel:>8} {N:>4} {K:>2} | {plug['compile']:8.3g} {exact['compile']:8.3g} ({work:8.3g}) "
              "| "
              f"{plug['resolve']:8.3g} {exact['resolve']:8.3g} ({solve:8.3g}) | {plug['peak'] / 1e6:7.0f} "
              f"{exact['peak'] / 1e6:7.0f} ({size / 1e6:7.0f}){failed}")
        rows.append({"plant": plant, "chain": channel, "N": N, "K": K, "plug_in": plug, "exact": exact,
                     "predicted": {"compile": work, "resolve": solve, "peak": size}})
    if args.json:
        print(json.dumps(rows))


if __name__ == "__main__":
    main()
