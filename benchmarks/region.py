"""Issue 21, item 8: the stabilisable set. (1) a 101 x 101 region map of two_actuator, all laws, CPU time;
(2) the LMI form against the Riccati forms at every grid point where both decide (agreement, time per point);
(3) critical_mu(system, "dp") on the issue's scalar case at this commit and at a baseline commit (the issue's
error and time), run interleaved in subprocesses. CPU seconds (time.process_time), OPENBLAS_NUM_THREADS=1.

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD python benchmarks/region.py [--grid 101] [--baseline /work/base/cfb251d]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

from packetloss_cvx import load_example
from packetloss_cvx.closedloop.region import LazyLmi, membership
from packetloss_cvx.studies.region_map import region_map

SCALAR = """
import time, json
from packetloss_cvx import System
from packetloss_cvx.closedloop.critical import critical_mu
s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[0.1], mu=[1.0], x0=[1.0])
t0 = time.process_time(); t = critical_mu(s, "dp"); print(json.dumps([t, time.process_time() - t0]))
"""


def scalar_case(root: str) -> tuple[float, float]:
    env = {**os.environ, "PYTHONPATH": root, "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", SCALAR], env=env, capture_output=True, text=True, check=True, cwd=root)
    return tuple(json.loads(out.stdout.strip().splitlines()[-1]))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--grid", type=int, default=101)
    parser.add_argument("--baseline", default="/work/base/cfb251d")
    parser.add_argument("--skip-lmi", action="store_true")
    args = parser.parse_args()
    here = os.getcwd()

    print("(3) critical_mu(A=2, B=1, Psi=0.1, 'dp'): exact 0.75, tol 1e-6 (interleaved, 3 runs each)")
    for _ in range(3):
        for label, root in (("baseline", args.baseline), ("this", here)):
            t, cpu = scalar_case(root)
            print(f"    {label:<8} t = {t:.9f}  error {t - 0.75:+.2e}  {cpu:.3f} s")

    s = load_example("two_actuator")
    t0 = time.process_time()
    r = region_map(s, grid=args.grid)
    cpu = time.process_time() - t0
    print(f"(1) region_map(two_actuator, all laws, grid={args.grid}): {cpu:.1f} s CPU "
          f"({1e3 * cpu / args.grid ** 2:.2f} ms a point, 4 laws)")
    print("    critical t along (1, 1): " + ", ".join(f"{p.law} {p.t:.6f}" for p in r.critical))
    print("    stable share: " + ", ".join(f"{law} {100 * r.area(law):.2f} %" for law in r.laws)
          + f"; undecided points: {int(np.isnan(r.stable).sum())}")
    if args.skip_lmi:
        return
    lmi = LazyLmi(s.A, s.B)
    counts = {"both": 0, "agree": 0, "riccati only": 0, "lmi only": 0, "neither": 0}
    times = {"riccati": 0.0, "lmi": 0.0}
    for mu_j in r.axis:
        for mu_i in r.axis:
            mu = np.array([mu_i, mu_j])
            t0 = time.process_time()
            a = membership(s, mu, forms=("riccati",)).verdict
            t1 = time.process_time()
            b = membership(s, mu, forms=("lmi",), lmi=lmi).verdict
            t2 = time.process_time()
            times["riccati"] += t1 - t0
            times["lmi"] += t2 - t1
            if a != "undecided" and b != "undecided":
                counts["both"] += 1
                counts["agree"] += a == b
            elif a != "undecided":
                counts["riccati only"] += 1
            elif b != "undecided":
                counts["lmi only"] += 1
            else:
                counts["neither"] += 1
    points = args.grid ** 2
    print(f"(2) LMI against the homogeneous Riccati form at {points} points: {counts}")
    print(f"    CPU: riccati {times['riccati']:.1f} s ({1e3 * times['riccati'] / points:.2f} ms a point), "
          f"lmi {times['lmi']:.1f} s ({1e3 * times['lmi'] / points:.2f} ms a point)")


if __name__ == "__main__":
    main()
