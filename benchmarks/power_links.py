"""Issue 24's power problems: (1) the unit of power, every model x protocol x problem at scales 1e-12 .. 1e12
against the answer at scale 1 (status and relative difference; P = s P' maps the problems exactly); (2) TCP-like
rayleigh on two_actuator (c = (1, 2), gap 1e-4): CPU seconds (time.process_time, OPENBLAS_NUM_THREADS=1) and
boxes, and with --baseline the same problems run by that checkout in a subprocess, interleaved, ratios side by
side (a checkout before allocation/delivery.py takes power_model from allocation/power.py).

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD python benchmarks/power_links.py [--baseline /work/base/f7d69cd]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from packetloss_cvx import System, load_example  # noqa: E402
from packetloss_cvx.allocation.delivery import power_model  # noqa: E402
from packetloss_cvx.allocation.power import least_cost_within_power, least_power  # noqa: E402

SCALES = (1e-12, 1e-6, 1e6, 1e12)
TABLE = np.array([[0.0, 0.0], [1.0, 0.3], [2.0, 0.5], [5.0, 0.9]])
RAYLEIGH = (("least power", 3.0), ("least power", 5.0), ("least power", 8.0),
            ("least cost", 3.0), ("least cost", 6.0), ("least cost", 12.0))

#: run by the baseline checkout: the rayleigh cases, one JSON line of (seconds, value, lower bound, boxes)
BASELINE = """
import json, sys, time
from packetloss_cvx import load_example
from packetloss_cvx.allocation import power as pw
try:
    from packetloss_cvx.allocation.delivery import power_model
except ImportError:
    power_model = pw.power_model
t, m = load_example("two_actuator"), power_model("rayleigh", 2, scale=[1.0, 2.0])
out = []
for kind, v in json.loads(sys.argv[1]):
    start = time.process_time()
    r = pw.least_power(t, "tcp", m, v) if kind == "least power" else pw.least_cost_within_power(t, "tcp", m, v)
    out.append([time.process_time() - start, r.total_power if kind == "least power" else r.cost, r.lower_bound,
                r.boxes])
print(json.dumps(out))
"""


def scalar() -> System:
    return System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])


def model(kind: str, m: int, s: float):
    if kind == "table":
        table = TABLE.copy()
        table[:, 0] *= s
        return power_model("table", m, table=table)
    return power_model(kind, m, scale=np.array([1.0, 2.0][:m]) * s)


def units() -> None:
    """The sweep over the unit of power."""
    print("| model | protocol | system | problem | statuses at 1e-12, 1e-6, 1e6, 1e12 "
          "| worst relative difference to s = 1 |")
    print("|---|---|---|---|---|---|")
    for kind in ("exponential", "rayleigh", "table"):
        for protocol in ("tcp", "udp"):
            for name, system, alpha, budget in (("one step", scalar(), 0.8, 1.7),
                                                ("two_actuator", load_example("two_actuator"), 8.0, 3.0)):
                for problem in ("least power", "least cost"):
                    def value(s, kind=kind, protocol=protocol, system=system, alpha=alpha, budget=budget,
                              problem=problem):
                        if problem == "least power":
                            r = least_power(system, protocol, model(kind, system.m, s), alpha)
                            return r.status, r.total_power / s
                        r = least_cost_within_power(system, protocol, model(kind, system.m, s), budget * s)
                        return r.status, r.cost
                    _, ref = value(1.0)
                    got = [value(s) for s in SCALES]
                    worst = max(abs(v / ref - 1) for _, v in got)
                    print(f"| {kind} | {protocol} | {name} | {problem} | {', '.join(st for st, _ in got)} "
                          f"| {worst:.1e} |")


def rayleigh(baseline: str | None, rounds: int) -> None:
    """The rayleigh cases, the least CPU time of ``rounds`` interleaved runs."""
    t, m = load_example("two_actuator"), power_model("rayleigh", 2, scale=[1.0, 2.0])
    env = {**os.environ, "PYTHONPATH": str(Path(baseline).resolve()) if baseline else "", "OPENBLAS_NUM_THREADS": "1"}
    mine, theirs = [], []
    for _ in range(rounds):
        row = []
        for kind, v in RAYLEIGH:
            start = time.process_time()
            r = least_power(t, "tcp", m, v) if kind == "least power" else least_cost_within_power(t, "tcp", m, v)
            row.append((time.process_time() - start, r.boxes))
        mine.append(row)
        if baseline:
            out = subprocess.run([sys.executable, "-c", BASELINE, json.dumps(RAYLEIGH)], env=env, cwd="/",
                                 capture_output=True, text=True, check=True)
            theirs.append(json.loads(out.stdout))
    print("\n| TCP-like rayleigh, two_actuator | CPU s (this) | boxes | CPU s (baseline) | boxes | ratio |")
    print("|---|---|---|---|---|---|")
    for k, (kind, v) in enumerate(RAYLEIGH):
        ours = min(r[k][0] for r in mine)
        line = f"| {kind} {'alpha' if kind == 'least power' else 'B'} = {v:g} | {ours:.2f} | {mine[0][k][1]} "
        if baseline:
            base = min(r[k][0] for r in theirs)
            line += f"| {base:.2f} | {theirs[0][k][3]} | {base / ours:.1f}x |"
        else:
            line += "| - | - | - |"
        print(line)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", help="a checkout to run the rayleigh cases with, interleaved")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--rayleigh-only", action="store_true")
    args = parser.parse_args()
    if not args.rayleigh_only:
        units()
    rayleigh(args.baseline, args.rounds)


if __name__ == "__main__":
    main()
