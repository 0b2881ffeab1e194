"""``lq.recursion.riccati_step`` on one point, a batch of one, a small stack and a flattened stack, this checkout
beside a baseline checkout, interleaved in one process (issue 19 item 1: the one-point fast path is the kernel
itself on 2-D arrays; it must not be slower than the copy it replaced).

    OPENBLAS_NUM_THREADS=1 python benchmarks/riccati_step_shapes.py [--baseline /work/base/e520261] [--rounds 7]
    OPENBLAS_NUM_THREADS=1 python benchmarks/riccati_step_shapes.py --udp [--baseline DIR] [--rounds 5]

Each round times every case with the baseline's function and this checkout's, one after the other (CPU time,
``time.process_time``); prints the medians in microseconds per call, the ratio this/baseline (median and range of
the per-round ratios) and whether both return the same floats. The baseline may not take a 2-D point (before
session 29 only a stack): there the point's row reads "-" for it.

``--udp``: the issue's UDP-like cases in a fresh interpreter per checkout, interleaved round by round: ``reproduce``'s
UDP-like allocations of two_actuator (``paper_figures.mixed_allocations`` over its alphas and betas) and
``benchmarks/run.py``'s allocation seeds 1-3 (m = 3, N = 40); CPU seconds, the medians, the per-round ratio
baseline / this, and whether both checkouts answer the same.
"""

from __future__ import annotations

import argparse
import importlib
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _load(root: Path):
    """The recursion module of the checkout at ``root`` (every packetloss_cvx module reloaded from there)."""
    for name in [k for k in sys.modules if k == "packetloss_cvx" or k.startswith("packetloss_cvx.")]:
        del sys.modules[name]
    sys.path.insert(0, str(root))
    try:
        return importlib.import_module("packetloss_cvx.lq.recursion")
    finally:
        sys.path.pop(0)


def _cases(rng: np.random.Generator, flat: int) -> list[tuple[str, tuple, bool]]:
    out = []
    for n, m, k in ((4, 2, 0), (4, 2, 1), (20, 3, 0), (20, 3, 1), (4, 2, 3), (4, 2, flat + 36)):
        A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
        F = rng.normal(size=(max(k, 1), n, n))
        P = F @ F.transpose(0, 2, 1) + np.eye(n)
        mu, added = rng.uniform(0.1, 1.0, (max(k, 1), m)), rng.uniform(0.5, 2.0, (max(k, 1), m))
        args = (P[0], A, B, mu[0], added[0], np.eye(n)) if k == 0 else (P, A, B, mu, added, np.eye(n))
        label = f"n={n} m={m} " + ("one point (2-D)" if k == 0 else f"stack of {k}")
        out.append((label, args, k == 0))
    return out


UDP_CASE = """
import json, sys, time
sys.path.insert(0, {bench!r})
from packetloss_cvx.cli import reproduce
from packetloss_cvx.model.files import load_example
from packetloss_cvx.studies import paper_figures
from packetloss_cvx.allocation import allocate
from run import allocation_alpha, allocation_system
case = sys.argv[1]
if case == "reproduce":
    system = load_example("two_actuator")
    start = time.process_time()
    answer = paper_figures.mixed_allocations(system, "udp", reproduce.ALPHAS, reproduce.ALLOCATION_BETAS,
                                             progress=False)
else:
    system = allocation_system(int(case))
    alpha = allocation_alpha(system)
    start = time.process_time()
    answer = allocate(system, "udp", alpha, [1.0, 1.0, 1.0]).mu
print(json.dumps({{"time": time.process_time() - start, "answer": repr(answer)}}))
"""


def udp_cases(baseline: Path, rounds: int) -> None:
    """The issue's UDP-like cases, this checkout beside ``baseline`` (module docstring, ``--udp``)."""
    import os
    import subprocess

    checkouts = {"baseline": baseline, "this": ROOT}
    cases = ("reproduce", "1", "2", "3")
    times = {(c, k): [] for c in cases for k in checkouts}
    answers: dict[tuple[str, str], set] = {(c, k): set() for c in cases for k in checkouts}
    code = UDP_CASE.format(bench=str(ROOT / "benchmarks"))
    for _ in range(rounds):
        for case in cases:
            for key, root in checkouts.items():
                env = {**os.environ, "PYTHONPATH": str(root), "OPENBLAS_NUM_THREADS": "1"}
                out = subprocess.run([sys.executable, "-c", code, case], env=env, capture_output=True, text=True,
                                     check=True, cwd=str(root)).stdout
                result = json.loads(out.strip().splitlines()[-1])
                times[(case, key)].append(result["time"])
                answers[(case, key)].add(result["answer"])
    print(f"UDP-like allocations, CPU s, {rounds} interleaved rounds of fresh processes; baseline {baseline}")
    print(f"{'case':>22} {'baseline':>9} {'this':>7} {'base/this':>10} {'(range)':>12}  same answers")
    for case in cases:
        base, mine = times[(case, "baseline")], times[(case, "this")]
        ratios = [b / t for b, t in zip(base, mine, strict=True)]
        same = answers[(case, "baseline")] == answers[(case, "this")] and len(answers[(case, "this")]) == 1
        label = "reproduce two_actuator" if case == "reproduce" else f"m = 3, N = 40, seed {case}"
        print(f"{label:>22} {statistics.median(base):9.3f} {statistics.median(mine):7.3f} "
              f"{statistics.median(ratios):9.2f}x ({min(ratios):.2f}-{max(ratios):.2f})  {same}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", default="/work/base/e520261")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--udp", action="store_true", help="the issue's UDP-like cases instead of the step")
    args = parser.parse_args()
    if args.udp:
        udp_cases(Path(args.baseline), args.rounds)
        return
    old, new = _load(Path(args.baseline)), _load(ROOT)
    cases = _cases(np.random.default_rng(0), new.FLAT_MIN)
    print(f"riccati_step, us per call (CPU), {args.rounds} interleaved rounds; baseline {args.baseline}")
    print(f"{'case':>28} {'baseline':>9} {'this':>8} {'this/base':>10} {'(range)':>13}  same floats")
    for label, call, point in cases:
        reps = 2000 if call[0].ndim == 3 and call[0].shape[0] > 10 else 20000
        kernels = {"new": new.riccati_step}
        try:
            pairs = zip(old.riccati_step(*call), new.riccati_step(*call), strict=True)
            same = all(np.array_equal(a, b) for a, b in pairs)
            kernels["old"] = old.riccati_step
        except Exception:  # noqa: BLE001 - the baseline takes stacks only
            same = None
        times: dict[str, list[float]] = {key: [] for key in kernels}
        for _ in range(args.rounds):
            for key, fn in kernels.items():
                start = time.process_time()
                for _ in range(reps):
                    fn(*call)
                times[key].append((time.process_time() - start) / reps * 1e6)
        this = statistics.median(times["new"])
        if "old" in times:
            ratios = [b / a for a, b in zip(times["old"], times["new"], strict=True)]
            print(f"{label:>28} {statistics.median(times['old']):9.2f} {this:8.2f} {statistics.median(ratios):9.3f}x "
                  f"({min(ratios):.2f}-{max(ratios):.2f})  {same}")
        else:
            print(f"{label:>28} {'-':>9} {this:8.2f} {'-':>10} {'':>13}  {'-' if point else same}")


if __name__ == "__main__":
    main()
