"""Section 22 of benchmarks/run.py: what one solve of the constrained receding-horizon loop costs, against the
``mpc_solves`` budget's formula (packetloss_cvx.budgets.mpc_solve_size), over a grid of horizons, plant sizes and
constraint rows.

    OPENBLAS_NUM_THREADS=1 python benchmarks/mpc_solve_time.py [--quick] [--json]

What the loop (montecarlo/mpc.py) does at each run and step: ``ConstrainedQP(system, "tcp", constraints,
u_prev=True).solve(x0=..., u_prev=...)``, Clarabel on the compiled program (qp/convex.py's ClarabelProgram) and the
solution's checks (KKT residual, forward cost). The plants: ``random_system`` (seeded, rho(A) = 0.95, noise,
stationary mu) with N in (10, 20, 50, 100, 200) and (n, m) in ((2, 1), (4, 2), (8, 3)); the constraints: an input
box at 0.6 times the unconstrained plan's peak ("box"), with a rate bound at half of it ("+rate"), with state limits
on every state ("+x"), or with one chance row on the first state ("+chance"; the rows of the program are counted by
``Constraints.program_rows``, the chance row apart). Per case: one solve to warm up, then eight from x0 scaled by
seeded factors in [0.5, 1.5], each timed in CPU time (time.process_time), the median; in a fresh interpreter with
one BLAS thread. The table prints the measured and the formula's time and their ratio, under the package's Clarabel
settings (tolerances.CLARABEL_LINEAR_SOLVER: QDLDL), and beside them the same cases in a second process with
Clarabel's own default ``direct_solve_method = "auto"`` forced, and which linear solver it picked (faer's supernodal
LDL, on all cores, for some large KKT systems).
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

SCRIPT = r"""
import json, statistics, sys, time
import numpy as np
import clarabel
import packetloss_cvx.qp.convex as convex
from packetloss_cvx.errors import BudgetError
from packetloss_cvx.lq.costs import closed_form
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.constrained import ConstrainedQP

cases, method = json.loads(sys.argv[1]), sys.argv[2]
made, used = clarabel.DefaultSolver, set()
def built(P, q, A, b, cones, settings):  # "package": the package's settings; else Clarabel's linear solver forced
    if method != "package":
        settings.direct_solve_method = method
    solver = made(P, q, A, b, cones, settings)
    used.add(solver.get_info().linsolver.name)
    return solver
convex.clarabel = type("Clarabel", (), {"DefaultSolver": staticmethod(built),
                                        "DefaultSettings": clarabel.DefaultSettings})

def case(N, n, m, kind):
    s = random_system(np.random.default_rng(7), n=n, m=m, horizon=N, spectral_radius=0.95, full_weights=False,
                      time_varying=False, non_stationary=False, noise=True, edge_mu=False)
    peak = 0.6 * np.abs(closed_form(s, "tcp").inputs).max(axis=0)
    rows = dict(u_min=-peak, u_max=peak)
    parts = kind.split("+")
    if "rate" in parts:
        rows["du_max"] = 0.5 * peak
    far = 10 * np.abs(s.x0).max() + 1.0
    if "x" in parts:
        rows["x_max"], rows["x_min"] = np.full(n, far), np.full(n, -far)
    if "chance" in parts:
        rows["chance"] = [(np.eye(n)[0], far, 0.2)]
    c = Constraints(**rows)
    out = {"N": N, "n": n, "m": m, "kind": kind, "rows": c.program_rows(N), "chance": len(c.chance)}
    try:
        qp = ConstrainedQP(s, "tcp", c, u_prev=True)
    except BudgetError as refused:
        return {**out, "refused": str(refused).split(" is over")[0]}
    used.clear()
    qp.solve(u_prev=np.zeros(m))
    rng, times = np.random.default_rng(1), []
    for _ in range(8):
        x0 = s.x0 * rng.uniform(0.5, 1.5, n)
        start = time.process_time()
        qp.solve(x0=x0, u_prev=np.zeros(m))
        times.append(time.process_time() - start)
    return {**out, "formulation": qp.formulation, "seconds": statistics.median(times), "linsolver": sorted(used)}

print(json.dumps([case(*c) for c in cases]))
"""

FULL = [(N, n, m, kind) for n, m in ((2, 1), (4, 2), (8, 3)) for N in (10, 20, 50, 100, 200)
        for kind in ("box", "box+rate", "box+x", "box+chance")]
QUICK = [(N, n, m, kind) for n, m in ((2, 1), (8, 3)) for N in (10, 50, 200) for kind in ("box", "box+x", "box+chance")]


def measure(cases: list, method: str = "package") -> list[dict]:
    """The cases timed in a fresh interpreter (this checkout, one BLAS thread): "package" under the package's Clarabel
    settings, else with Clarabel's ``direct_solve_method`` forced to ``method``."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", SCRIPT, json.dumps(cases), method], env=env, cwd=ROOT,
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def mpc_solve_time(rows: list, quick: bool = False) -> None:
    """Section 22: the table, one row per case (appended to ``rows``)."""
    from packetloss_cvx.budgets import BUDGETS, mpc_solve_size

    reference = BUDGETS["mpc_solves"].seconds_per_unit
    print("\n22. one solve of the constrained loop (ConstrainedQP.solve from a new x0, one BLAS thread, CPU ms) "
          "against the mpc_solves budget's formula; beside it, Clarabel's own default linear solver choice (auto)")
    print(f"{'N':>5} {'n':>3} {'m':>3} {'limits':>10} {'rows':>6} {'form':>10} {'measured':>9} {'formula':>8} "
          f"{'ratio':>6}  {'auto':>8} {'ratio':>6} {'auto picks':>10}")
    cases = QUICK if quick else FULL
    found, auto = measure(cases), measure(cases, "auto")
    for r, a in zip(found, auto, strict=True):
        head = f"{r['N']:>5} {r['n']:>3} {r['m']:>3} {r['kind']:>10} {r['rows']:>6}"
        if "refused" in r:
            print(f"{head}  refused: {r['refused']}")
            rows.append({"bench": "mpc_solve_time", **r})
            continue
        formula = reference * mpc_solve_size(r["N"], r["n"], r["m"], r["rows"], r["chance"])
        print(f"{head} {r['formulation']:>10} {1e3 * r['seconds']:>9.2f} {1e3 * formula:>8.2f} "
              f"{r['seconds'] / formula:>6.2f}  {1e3 * a['seconds']:>8.2f} {a['seconds'] / formula:>6.2f} "
              f"{'/'.join(a['linsolver']):>10}")
        rows.append({"bench": "mpc_solve_time", **r, "formula_s": formula, "ratio": r["seconds"] / formula,
                     "auto_s": a["seconds"], "auto_linsolver": a["linsolver"]})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a smaller grid (about a minute)")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON at the end")
    args = parser.parse_args()
    rows: list[dict] = []
    mpc_solve_time(rows, args.quick)
    if args.json:
        print(json.dumps(rows))


if __name__ == "__main__":
    main()
