"""A constrained QP re-solved in a loop against a direct Clarabel call on the same data, this tree and a baseline
checkout side by side in one run.

    OPENBLAS_NUM_THREADS=1 python benchmarks/constrained_resolve.py --baseline /path/to/main/checkout [--repeats 5]

The receding-horizon loop's cost: one `ConstrainedQP` per controller, ``solve(mu, x0)`` for a new x0 and mu each
step, checks on (the default). Two cases: a stable random plant with n = 4, m = 2, N = 20 (seeded), and the packaged
two_actuator (n = 2, m = 2, N = 10); each with an input box and a rate bound at 0.7 and 1.2 times the unconstrained
plan's peak input, and one chance constraint P(a'x_k <= b) >= 1 - 0.2 on the first direction (+-e_i, else seeded
random ones) where it binds and is feasible: b halfway between the values of the plan U = 0 and of the plan under
the input and rate bounds alone where the latter is larger, else 5 % of their difference below the latter's. Sixteen
re-solves per case and protocol, x0 and mu drawn around the system's (seeded): eight where x0 alone moves (the
receding-horizon loop under a fixed channel), eight where mu moves too; a draw that raises (InfeasibleError,
SolverError) is counted, not timed, and the ratios are over the draws both trees solved.

The reference, per re-solve: Clarabel on the data cvxpy compiles for those Parameter values
(``problem.get_problem_data``, not this package's compiled program), called directly with the settings of each
attempt the solve made (the status policy's loop, wrapped to record them: ``CONSTRAINED_ATTEMPTS`` on the compiled
program, ``CLARABEL_TIGHT`` then ``CLARABEL_DEFAULT`` through ``problem.solve``): a new solver built and solved per
attempt ("direct"), and kept solvers given the data (``update``) and solved ("direct, updated"). Every timing is CPU
time (time.process_time), the best of ``--repeats`` interleaved rounds; each tree runs in a fresh interpreter
(PYTHONPATH = the tree). The table prints, per case and protocol, the median and the largest over the re-solves of
each time and of the ratio solve / direct, how many re-solves needed a second and a third attempt ("2nd/3rd"), and
the plans' largest difference between the trees (relative to max(1, max|U|); they must agree within
CONSTRAINED_AGREEMENT_RTOL).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

SCRIPT = r"""
import json, sys, time, warnings
import numpy as np, cvxpy as cp, clarabel
import packetloss_cvx as pl
from cvxpy.reductions.solvers.conic_solvers.clarabel_conif import dims_to_solver_cones
from packetloss_cvx.lq.costs import closed_form
from packetloss_cvx.lq.moments import plan_moments
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.constrained import ConstrainedQP
import packetloss_cvx.qp.convex as convex

counted = []                 # the settings of each Clarabel attempt of a solve (the status policy's loop, wrapped)
policy = convex.first_answer
def first_answer(attempt, attempts):
    def noted(settings):
        counted.append(settings)
        return attempt(settings)
    return policy(noted, attempts)
convex.first_answer = first_answer

repeats = int(sys.argv[1])

def constraints(system, protocol, eps=0.2):
    free = closed_form(system, protocol).inputs
    peak = 0.7 * np.abs(free).max(axis=0)
    kappa = np.sqrt((1 - eps) / eps)
    def top(U, a):
        mom = plan_moments(system, U)
        return max(a @ mom.mean[k] + kappa * np.sqrt(a @ mom.cov[k] @ a) for k in range(1, system.horizon + 1))
    boxed = ConstrainedQP(system, protocol, Constraints(u_min=-peak, u_max=peak, du_max=1.2 * peak)).solve().inputs
    directions = np.random.default_rng(0).normal(size=(40, system.n))
    for a in [*(sign * e for e in np.eye(system.n) for sign in (1.0, -1.0)), *directions]:
        low, high = top(np.zeros_like(free), a), top(boxed, a)
        b = (low + high) / 2 if high > low else high - 0.05 * (low - high)
        c = Constraints(u_min=-peak, u_max=peak, du_max=1.2 * peak, chance=[(a, b, eps)])
        try:
            sol = ConstrainedQP(system, protocol, c).solve()
        except pl.InfeasibleError:
            continue
        if any(label.startswith("chance") for label in sol.binding):
            return c
    raise RuntimeError("no binding chance direction")

def cases():
    yield "n=4 m=2 N=20", random_system(np.random.default_rng(3), n=4, m=2, horizon=20, spectral_radius=0.9,
                                         non_stationary=False, noise=True, time_varying=False, edge_mu=False)
    yield "two_actuator", pl.load_system("two_actuator")

def cpu(f):
    start = time.process_time()
    f()
    return time.process_time() - start

out = []
for name, system in cases():
    for protocol in ("tcp", "udp"):
        qp = ConstrainedQP(system, protocol, constraints(system, protocol))
        rng = np.random.default_rng(7)
        points = [(np.clip(system.mu_schedule[0] * (1 + 0.05 * rng.normal(size=system.m)), 0.05, 1.0),
                   system.x0 * (1 + 0.1 * rng.normal(size=system.n))) for _ in range(16)]
        points = [(None, x0) for _, x0 in points[:8]] + points[8:]      # x0 alone moves, then x0 and mu
        rows = []
        for mu, x0 in points:
            counted.clear()
            try:
                sol = qp.solve(mu, x0)          # the Parameters now hold this point's values
            except (pl.InfeasibleError, pl.SolverError) as err:
                rows.append({"failed": type(err).__name__, "moves": "x0" if mu is None else "x0, mu"})
                continue
            attempts = list(counted)                                                 # what this solve ran
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                data, _, _ = qp.problem.get_problem_data(cp.CLARABEL)
            P, q, A, b = data["P"], data["c"], data["A"], data["b"]
            P = P.tocsc() if P is not None else None
            cones = dims_to_solver_cones(data["dims"])
            settings = []
            for attempt in attempts:
                options = clarabel.DefaultSettings()
                options.verbose = False
                for key, value in attempt.items():
                    setattr(options, key, value)
                settings.append(options)
            kept = [clarabel.DefaultSolver(P, q, A, b, cones, options) for options in settings]
            for solver in kept:
                solver.solve()
            def direct():
                for options in settings:
                    clarabel.DefaultSolver(P, q, A, b, cones, options).solve()
            def updated():
                for solver in kept:
                    solver.update(P=P, q=q, A=A, b=b)
                    solver.solve()
            best = {"solve": np.inf, "direct": np.inf, "updated": np.inf}
            for _ in range(repeats):
                best["direct"] = min(best["direct"], cpu(direct))
                best["solve"] = min(best["solve"], cpu(lambda: qp.solve(mu, x0)))
                best["updated"] = min(best["updated"], cpu(updated))
            rows.append({**{k: 1e3 * v for k, v in best.items()}, "inputs": sol.inputs.tolist(),
                         "polished": sol.polished, "binding": len(sol.binding), "attempts": len(attempts),
                         "moves": "x0" if mu is None else "x0, mu"})
        out.append({"case": name, "protocol": protocol, "rows": rows})
print(json.dumps({"file": pl.__file__, "cases": out}))
"""


def run(tree: Path, repeats: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", SCRIPT, str(repeats)], env=env, cwd=tree, capture_output=True,
                          text=True)     # cwd: "-c" puts the working directory first on sys.path
    if done.returncode:
        raise RuntimeError(f"the run in {tree} failed:\n{done.stderr[-3000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    if not result["file"].startswith(str(tree)):
        raise RuntimeError(f"{tree} imported packetloss_cvx from {result['file']}")
    return result


def main() -> None:
    import numpy as np

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", type=Path, help="a checkout of the baseline commit (omit: this tree only)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    here = run(ROOT, args.repeats)
    base = run(args.baseline.resolve(), args.repeats) if args.baseline else None
    print(f"CPU ms per re-solve (median / max over {len(here['cases'][0]['rows']) // 2} re-solves, best of "
          f"{args.repeats}); ratio = ConstrainedQP.solve / direct Clarabel on the same data")
    header = (f"{'case':14} {'proto':5} {'moves':7} {'direct':>13} {'direct,upd':>13} {'solve':>13} {'ratio':>11} "
              f"{'2nd/3rd':>7}"
              + (f" {'base solve':>13} {'base ratio':>11} {'2nd/3rd':>7} {'plans differ':>12}" if base else ""))
    print(header)
    for k, case in enumerate(here["cases"]):
        for moves in ("x0", "x0, mu"):
            mine = [r for r in case["rows"] if r["moves"] == moves]
            theirs = [r for r in base["cases"][k]["rows"] if r["moves"] == moves] if base else mine
            both = [i for i, (a, b) in enumerate(zip(mine, theirs, strict=True)) if "failed" not in a
                    and "failed" not in b]
            failed = sum("failed" in r for r in mine), sum("failed" in r for r in theirs)
            rows, other = [mine[i] for i in both], [theirs[i] for i in both]

            def stat(values, fmt="7.2f"):
                return f"{np.median(values):{fmt}}/{np.max(values):<{fmt[0]}.{fmt[2]}f}".rstrip()

            line = (f"{case['case']:14} {case['protocol']:5} {moves:7} {stat([r['direct'] for r in rows], '5.2f'):>13} "
                    f"{stat([r['updated'] for r in rows], '5.2f'):>13} {stat([r['solve'] for r in rows], '5.2f'):>13} "
                    f"{stat([r['solve'] / r['direct'] for r in rows], '4.2f'):>11} "
                    f"{sum(r['attempts'] > 1 for r in rows):5d}/{sum(r['attempts'] > 2 for r in rows)}")
            if base:
                differ = max(float(np.abs(np.subtract(a["inputs"], b["inputs"])).max()
                                   / max(1.0, np.abs(a["inputs"]).max())) for a, b in zip(rows, other, strict=True))
                line += (f" {stat([r['solve'] for r in other], '5.2f'):>13} "
                         f"{stat([r['solve'] / r['direct'] for r in other], '4.2f'):>11} "
                         f"{sum(r['attempts'] > 1 for r in other):5d}/{sum(r['attempts'] > 2 for r in other)} "
                         f"{differ:12.1e}")
            print(line + f"  (raised: {failed[0]} here" + (f", {failed[1]} in the baseline)" if base else ")"))


if __name__ == "__main__":
    main()
