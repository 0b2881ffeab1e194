"""The (mean rate × burstiness) map of one channel: ``studies.burstiness.burstiness_map`` (the augmented recursion at every
point) against the same grid by the dense route, side by side in one run (docs/performance.md,
"Other benchmarks").

    OPENBLAS_NUM_THREADS=1 python benchmarks/burstiness_map.py [--quick] [--json]

pendulum_bursty (N = 80 as shipped, and N = 500) on a 6 x 6 grid (mean rate 0.5..1, lambda 0..0.95): the map's CPU
time (time.process_time), and the dense route on the same points (``channel_twin`` then
``exact_closed_form(method="dense")`` and the dense exact cost of the plug-in plan, UDP-like only: the TCP-like
numbers need no chain algebra), the runs interleaved (best of 3; 1 with --quick), and the largest relative
difference of the two routes' minima over the grid, where the dense route gives one (at N = 500 its self-check
refuses the rate-1 row, where the map's value is the paper's J* at mu = 1).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import packetloss_cvx as pl  # noqa: E402
from packetloss_cvx.errors import NumericalError  # noqa: E402
from packetloss_cvx.lq.markov_cost import (
    exact_closed_form,
    exact_cost,  # noqa: E402
)
from packetloss_cvx.model.twins import channel_twin
from packetloss_cvx.studies.burstiness import burstiness_map

RATES = np.linspace(0.5, 1.0, 6)
LAMBDAS = np.linspace(0.0, 0.95, 6)


def at_horizon(system, horizon):
    return pl.System(A=system.A, B=system.B, horizon=horizon, state_weight=np.diag(system.state_weights[0]),
                     input_weight=system.input_weights[0], x0=system.x0, channel=system.channel)


def dense_map(system):
    out = np.empty((RATES.size, LAMBDAS.size))
    for a, rate in enumerate(RATES):
        for b, lam in enumerate(LAMBDAS):
            twin = channel_twin(system, 0, float(rate), float(lam))
            try:
                out[a, b] = exact_closed_form(twin, "udp", method="dense").cost
            except NumericalError:        # the dense solve's self-check fails (N = 500, rate 1): not a number
                out[a, b] = np.nan
                continue
            plugin = pl.closed_form(twin.with_mu(twin.mu_schedule), "udp").inputs
            exact_cost(twin, plugin, method="dense")
    return out


def timed(fn):
    start = time.process_time()
    value = fn()
    return time.process_time() - start, value


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    repeats = 1 if args.quick else 3
    base = pl.load_example("pendulum_bursty")
    rows = []
    for horizon in (80, 500):
        system = at_horizon(base, horizon)
        best = {"map": np.inf, "dense": np.inf}
        for _ in range(repeats):                          # interleaved: map, dense, map, dense, ...
            seconds, grid = timed(lambda s=system: burstiness_map(s, RATES, LAMBDAS, progress=False))
            best["map"] = min(best["map"], seconds)
            seconds, dense = timed(lambda s=system: dense_map(s))
            best["dense"] = min(best["dense"], seconds)
        ok = np.isfinite(dense)
        diff = float(np.max(np.abs(grid.exact["udp"][ok] - dense[ok]) / dense[ok]))
        rows.append({"horizon": horizon, "points": RATES.size * LAMBDAS.size, "map_s": best["map"],
                     "dense_udp_s": best["dense"], "ratio": best["dense"] / best["map"], "max_rel_diff": diff,
                     "dense_refused": int(np.sum(~ok))})
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    print("pendulum_bursty, 6 x 6 grid; map = both protocols by the recursion, dense = UDP-like only")
    for r in rows:
        print(f"  N = {r['horizon']:4d}: map {r['map_s']:.2f} s, dense route {r['dense_udp_s']:.2f} s "
              f"(x{r['ratio']:.1f}), max relative difference {r['max_rel_diff']:.1e}; the dense route raised "
              f"NumericalError at {r['dense_refused']} points")


if __name__ == "__main__":
    main()
