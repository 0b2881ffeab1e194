"""``packetloss-cvx reproduce`` CPU time against older checkouts, side by side in one run (issue 19 item 6: under
10 s CPU on two cores; docs/performance.md, "Other benchmarks").

    OPENBLAS_NUM_THREADS=1 python benchmarks/reproduce_speed.py [--rounds 3] [--baseline DIR ...] [--steps]
    OPENBLAS_NUM_THREADS=1 python benchmarks/reproduce_speed.py --crossover
    OPENBLAS_NUM_THREADS=1 python benchmarks/reproduce_speed.py --parts [--rounds 3] [--baseline DIR ...]

1. Default: the full ``reproduce`` in a fresh interpreter per run, this checkout and each ``--baseline`` checkout
   (default /work/base/f7d69cd and /work/base/cfb251d when present) interleaved round by round (every checkout once a
   round, so a busy spell of the shared machine hits all of them), CPU seconds = user + sys of the child
   (``os.times`` of the reaped child), one BLAS thread. Prints each run, the medians and the ratios to this checkout.
   ``--steps``: also each step's CPU seconds in this checkout (the command's own step timer read on
   ``time.process_time``), one extra run.
2. ``--crossover``: ``lq.markov_cost.exact_closed_form`` by ``method="recursion"`` and ``method="dense"`` on Gilbert twins
   (lambda = 0.9) of pendulum, two_actuator and two random plants over N, CPU ms (best of 3), the ratio and the
   relative difference of J*: the measurement behind ``lq.markov_cost.AUTO_DENSE_MAX``.
3. ``--parts``: the parts of ``reproduce`` that session 29 made faster, each in a fresh interpreter per checkout
   (imports paid before the clock starts), the checkouts interleaved round by round, CPU seconds (process_time):
   the 33 UDP-like allocations of the two-actuator system (reproduce's step), the sensing Monte Carlo of the
   audit's cost-split-sensor on the paper systems (with each one's exact split), the expected-Riccati upper
   bounds of the 129 sensed twins of the full audit's cases, the QP twin's claims (theorem-1-laws and
   theorem-1-costs of the full audit: 404 condensed solves), the eight figures of the full run (drawn and saved;
   the answers are the PNGs' digests) and the full audit (``audit --random 200 --seed 1``);
   ``--only NAME`` (repeatable) runs the parts named.
   Each part also prints a digest of its answers: equal digests, the same numbers (repr of every float).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BASELINES = [Path("/work/base/f7d69cd"), Path("/work/base/cfb251d")]

STEP_TIMER = """
import sys, time, types
import packetloss_cvx.cli.reproduce as r
r.time = types.SimpleNamespace(perf_counter=time.process_time)    # the step timer on CPU time
from packetloss_cvx.cli import main
main(["reproduce", "-q", "--out", sys.argv[1]])
"""


def timed(checkout: Path, out: Path, steps: bool = False) -> tuple[float, str]:
    """CPU seconds (user + sys of the reaped child) of one fresh ``reproduce`` of ``checkout`` into ``out``, and
    its stdout."""
    shutil.rmtree(out, ignore_errors=True)
    env = {**os.environ, "PYTHONPATH": str(checkout), "OPENBLAS_NUM_THREADS": "1"}
    cmd = [sys.executable, "-c", STEP_TIMER, str(out)] if steps else \
        [sys.executable, "-m", "packetloss_cvx", "reproduce", "-q", "--out", str(out)]
    before = os.times()
    done = subprocess.run(cmd, env=env, cwd=tempfile.gettempdir(), capture_output=True, text=True, check=False)
    after = os.times()
    if done.returncode != 0:
        raise SystemExit(f"reproduce failed in {checkout}: {done.stderr.strip().splitlines()[-1:]}")
    return (after.children_user - before.children_user) + (after.children_system - before.children_system), \
        done.stdout


def compare(rounds: int, baselines: list[Path], steps: bool) -> None:
    checkouts = [ROOT, *[b for b in baselines if b.exists()]]
    times: dict[Path, list[float]] = {c: [] for c in checkouts}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(rounds):
            for c in checkouts:
                cpu, _ = timed(c, Path(tmp) / f"out-{c.name}")
                times[c].append(cpu)
                print(f"round {k + 1}: {c.name:12s} {cpu:6.2f} s CPU (load {os.getloadavg()[0]:.1f})", flush=True)
        mine = statistics.median(times[ROOT])
        print("\ncheckout       median CPU s   runs                      / this checkout")
        for c in checkouts:
            med = statistics.median(times[c])
            print(f"{c.name:14s} {med:8.2f}      {', '.join(f'{t:.2f}' for t in times[c]):26s} {med / mine:.2f}")
        if steps:
            _, stdout = timed(ROOT, Path(tmp) / "steps", steps=True)
            print("\nsteps of this checkout (CPU s):", next(line.strip() for line in stdout.splitlines()
                                                          if "seconds:" in line))


def crossover() -> None:
    sys.path.insert(0, str(ROOT))
    import numpy as np

    import packetloss_cvx as pl
    from packetloss_cvx.lq.markov_cost import exact_closed_form
    from packetloss_cvx.model.files import system_from_dict
    from packetloss_cvx.model.twins import bursty_twin
    from packetloss_cvx.threads import blas_limited

    def best(f, k):
        out = []
        for _ in range(3):
            start = time.process_time()
            for _ in range(k):
                f()
            out.append((time.process_time() - start) / k)
        return min(out)

    rng = np.random.default_rng(3)
    A4 = rng.standard_normal((4, 4))
    A4 *= 0.95 / max(abs(np.linalg.eigvals(A4)))
    A3 = rng.standard_normal((3, 3))
    A3 *= 0.9 / max(abs(np.linalg.eigvals(A3)))
    cases = {"pendulum (n 4, m 1)": pl.load_example("pendulum"),
             "two_actuator (n 2, m 2)": pl.load_example("two_actuator"),
             "random (n 4, m 2)": pl.System(A=A4, B=rng.standard_normal((4, 2)), horizon=10, state_weight=np.ones(4),
                                            input_weight=np.ones(2), mu=[0.6, 0.8], x0=np.ones(4)),
             "random (n 3, m 3)": pl.System(A=A3, B=rng.standard_normal((3, 3)), horizon=10, state_weight=np.ones(3),
                                            input_weight=np.ones(3), mu=[0.6, 0.8, 0.7], x0=np.ones(3))}

    @blas_limited
    def go():
        print("system                    N   N m   recursion ms   dense ms   dense/rec   J* rel. diff")
        for name, base in cases.items():
            for N in (2, 8, 20, 40, 80, 160, 240, 320):
                data = base.to_dict()
                data["cost"]["horizon"] = N
                s = bursty_twin(system_from_dict(data), 0.9)
                k = max(1, 200 // N)
                rec = best(lambda s=s: exact_closed_form(s, "udp", method="recursion"), k)
                dense = best(lambda s=s: exact_closed_form(s, "udp", method="dense"), k)
                a = exact_closed_form(s, "udp", method="recursion").cost
                b = exact_closed_form(s, "udp", method="dense").cost
                print(f"{name:24s} {N:4d} {N * s.m:4d}   {rec * 1e3:10.2f}   {dense * 1e3:8.2f}   {dense / rec:8.2f}"
                      f"   {abs(a - b) / abs(a):.1e}", flush=True)
    go()


PARTS = {
    "udp allocations": """
from packetloss_cvx.model.files import load_example
from packetloss_cvx.studies import paper_figures as pf
from packetloss_cvx.claims.paper import ALLOCATION_BETAS
from packetloss_cvx.cli.reproduce import ALPHAS
mixed = load_example("two_actuator")
def part():
    return pf.mixed_allocations(mixed, "udp", ALPHAS, ALLOCATION_BETAS, progress=False)
""",
    "sensing monte carlo": """
from packetloss_cvx.claims.context import paper_systems
from packetloss_cvx.claims.sensing import simulated_z
systems = paper_systems()
def part():
    return {name: simulated_z(s, 1) for name, s in systems.items()}
""",
    "expected riccati bounds": """
import numpy as np
from packetloss_cvx.claims.context import paper_systems
from packetloss_cvx.claims.sensing import sensed
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.sensing.bounds import upper_bound_covariance
rng = np.random.default_rng(1)
twins = [t for t in (sensed(s) for s in [*paper_systems().values(), *(random_system(rng) for _ in range(200))])
         if t is not None]
def part():
    return [upper_bound_covariance(t.A, t.noise_cov, t.sensor) for t in twins]
""",
    "qp twin": """
import cvxpy  # noqa: F401  (imported before the clock, as reproduce has it by then)
from packetloss_cvx.claims import audit, markdown_report
def part():
    results = audit(random=200, seed=1, only=["theorem-1-laws", "theorem-1-costs"], progress=False)
    return markdown_report(results) + repr([r.to_dict() for r in results])
""",
    "figures": """
import tempfile
from pathlib import Path
from packetloss_cvx.cli import reproduce as r
from packetloss_cvx.runfolder import RunFolder
from packetloss_cvx.safeio import file_digest
settings = {**r.SETTINGS["full"], "audit_skips": tuple(r.CLAIMS)}     # the full run's data, no audit
compute = getattr(r, "compute", None) or getattr(r, "_compute")          # so named before session 30
draw_figures = getattr(r, "draw_figures", None) or getattr(r, "_figures")
data = compute(settings, False, {})
def part():
    with tempfile.TemporaryDirectory() as tmp, RunFolder(Path(tmp) / "out", command="bench") as folder:
        return sorted((p.name, file_digest(p)) for p in draw_figures(data, folder).values())
""",
    "audit": """
import cvxpy  # noqa: F401  (imported before the clock, as reproduce has it by then)
from packetloss_cvx.claims import audit, markdown_report
def part():
    results = audit(random=200, seed=1, progress=False)
    return markdown_report(results) + repr([r.to_dict() for r in results])
""",
}

PART_RUNNER = """
import hashlib, pickle, sys, time
from packetloss_cvx.threads import blas_limited
exec(sys.argv[1])
run = blas_limited(part)
start = time.process_time()
answer = run()
cpu = time.process_time() - start
print(cpu, hashlib.sha256(repr(answer).encode()).hexdigest()[:12])
"""


def parts(rounds: int, baselines: list[Path], only: list[str] | None = None) -> None:
    """Each of :data:`PARTS` (or those named in ``only``) in a fresh interpreter per checkout, interleaved; CPU s
    and answer digests."""
    checkouts = [ROOT, *[b for b in baselines if b.exists()]]
    for name, code in PARTS.items():
        if only and name not in only:
            continue
        times: dict[Path, list[float]] = {c: [] for c in checkouts}
        digests: dict[Path, set[str]] = {c: set() for c in checkouts}
        for _ in range(rounds):
            for c in checkouts:
                env = {**os.environ, "PYTHONPATH": str(c), "OPENBLAS_NUM_THREADS": "1"}
                done = subprocess.run([sys.executable, "-c", PART_RUNNER, code], env=env, cwd=tempfile.gettempdir(),
                                      capture_output=True, text=True, check=True)
                cpu, digest = done.stdout.split()[-2:]
                times[c].append(float(cpu))
                digests[c].add(digest)
        mine = statistics.median(times[ROOT])
        print(f"\n{name} (load {os.getloadavg()[0]:.1f})")
        for c in checkouts:
            med = statistics.median(times[c])
            print(f"  {c.name:14s} {med:7.3f} s  runs {', '.join(f'{t:.3f}' for t in times[c]):28s} "
                  f"/ this {med / mine:5.2f}  answers {','.join(sorted(digests[c]))}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--baseline", type=Path, action="append", help="another checkout (repeatable)")
    parser.add_argument("--steps", action="store_true", help="also this checkout's steps, one more run")
    parser.add_argument("--crossover", action="store_true", help="the Markov closed form's two routes over N")
    parser.add_argument("--parts", action="store_true", help="the parts session 29 made faster, with answer digests")
    parser.add_argument("--only", action="append", choices=list(PARTS),
                        help="with --parts: only this part (repeatable)")
    args = parser.parse_args()
    if args.crossover:
        crossover()
    elif args.parts:
        parts(args.rounds, args.baseline or BASELINES, args.only)
    else:
        compare(args.rounds, args.baseline or BASELINES, args.steps)


if __name__ == "__main__":
    main()
