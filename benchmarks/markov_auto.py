"""Which route `method="auto"` should take for the exact UDP-like minimum under Markov losses: the dense
stacked solve against the augmented recursion, side by side in one run (docs/performance.md,
"Other benchmarks"; docs/mathematics.md §4, "Which route").

    OPENBLAS_NUM_THREADS=1 python benchmarks/markov_auto.py [--quick] [--fit] [--json]

For plants of n = 1..8 states behind m = 1..2 chains of k = 2..50 states (augmented size D = n (1 + m (k - 1)))
and horizons N = 10..640, ``exact_closed_form`` with method="dense" and method="recursion", CPU time
(time.process_time), runs interleaved, best of 3 (1 with --quick). Printed per case: both times, their ratio,
the two estimates ``lq.markov_cost.route_seconds`` gives, the route ``auto`` takes and the time it loses
against the faster route. ``--fit`` prints the least-squares coefficients of the two time models
(dense: a + b (N m)^3 + c (N n)^2 N m; recursion: N (e + f D^3)) from the measured cases.
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
from packetloss_cvx.lq.markov_cost import (  # noqa: E402
    auto_route,
    exact_closed_form,  # noqa: E402
    route_seconds,
)
from packetloss_cvx.model.channel import MarkovChannel  # noqa: E402

SHAPES = [(1, 1, 2), (2, 1, 2), (4, 1, 2), (2, 2, 2), (4, 2, 2), (4, 2, 3), (8, 2, 3), (2, 1, 20), (1, 1, 50),
          (4, 1, 20), (2, 2, 20)]
HORIZONS = [10, 20, 40, 80, 160, 320, 640]


def build(n: int, m: int, k: int, N: int) -> pl.System:
    """A seeded stable plant (rho(A) = 0.95) behind m random k-state chains with fractional deliveries."""
    rng = np.random.default_rng(1000 * n + 100 * m + k)
    A = rng.normal(size=(n, n))
    A *= 0.95 / max(abs(np.linalg.eigvals(A)))
    Ts, ds = [], []
    for _ in range(m):
        T = rng.uniform(size=(k, k)) + 3 * np.eye(k)
        Ts.append(T / T.sum(axis=1, keepdims=True))
        ds.append(rng.uniform(size=k))
    return pl.System(A=A, B=rng.normal(size=(n, m)), horizon=N, state_weight=np.ones(n), input_weight=np.ones(m),
                     x0=np.ones(n), channel=MarkovChannel(transition=Ts, delivery=ds))


def seconds(system: pl.System, method: str) -> float:
    start = time.process_time()
    exact_closed_form(system, "udp", method=method)
    return time.process_time() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="one run each, N up to 320")
    parser.add_argument("--fit", action="store_true", help="print the fitted coefficients of both time models")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    horizons = [N for N in HORIZONS if not args.quick or N <= 320]
    exact_closed_form(build(2, 1, 2, 10), "udp", method="dense")          # imports and first-call set-up
    exact_closed_form(build(2, 1, 2, 10), "udp", method="recursion")
    rows = []
    for n, m, k in SHAPES:
        D = n * (1 + m * (k - 1))
        for N in horizons:
            if (N * m) ** 3 > 3e9 or N * D ** 3 > 3e9:                    # keep each run under a few seconds
                continue
            best = {"dense": np.inf, "recursion": np.inf}
            for _ in range(repeats):
                for method in best:
                    best[method] = min(best[method], seconds(build(n, m, k, N), method))
            system = build(n, m, k, N)
            dense_est, rec_est = route_seconds(system)
            chosen = auto_route(system)
            rows.append({"n": n, "m": m, "k": k, "D": D, "N": N, "dense": best["dense"],
                         "recursion": best["recursion"], "dense_estimate": dense_est, "recursion_estimate": rec_est,
                         "auto": chosen, "lost": best[chosen] - min(best.values())})
            r = rows[-1]
            if not args.json:
                print(f"n={n} m={m} k={k:>2} D={D:>3} N={N:>3}: dense {1e3 * r['dense']:7.2f} ms (est "
                      f"{1e3 * dense_est:7.2f}), recursion {1e3 * r['recursion']:7.2f} ms (est {1e3 * rec_est:7.2f}), "
                      f"dense/recursion {r['dense'] / r['recursion']:5.2f}, auto {chosen:9s} lost "
                      f"{1e3 * r['lost']:.2f} ms", flush=True)
    wrong = [r for r in rows if r["lost"] > 0]
    summary = {"cases": len(rows), "auto_slower": len(wrong),
               "worst_loss_ratio": max((r[r["auto"]] / min(r["dense"], r["recursion"]) for r in rows), default=1.0),
               "time_auto": sum(r[r["auto"]] for r in rows), "time_best": sum(min(r["dense"], r["recursion"])
                                                                               for r in rows),
               "time_recursion": sum(r["recursion"] for r in rows), "time_dense": sum(r["dense"] for r in rows)}
    if args.fit:
        X = np.array([[1.0, (r["N"] * r["m"]) ** 3, (r["N"] * r["n"]) ** 2 * r["N"] * r["m"]] for r in rows])
        y = np.array([r["dense"] for r in rows])
        summary["dense_fit"] = np.linalg.lstsq(X / y[:, None], np.ones(len(y)), rcond=None)[0].tolist()
        X = np.array([[r["N"], r["N"] * r["D"] ** 3] for r in rows])
        y = np.array([r["recursion"] for r in rows])
        summary["recursion_fit"] = np.linalg.lstsq(X / y[:, None], np.ones(len(y)), rcond=None)[0].tolist()
    if args.json:
        print(json.dumps({"rows": rows, "summary": summary}, indent=1))
    else:
        print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
