"""Issue 21, item 5: design for stability (`allocate --target stable|dp-cost`) on the issue's systems. For each
case: the channel found, its beta'mu and proved lower bound, the gap, the boxes and the CPU seconds
(time.process_time, OPENBLAS_NUM_THREADS=1). A new capability: no baseline to compare against; the reference
points are the hand value (one state: 1 - rho / a^2) and the critical point along an axis (critical_mu).

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD python benchmarks/stability_design.py
"""

from __future__ import annotations

import time

import numpy as np

from packetloss_cvx import System, load_example
from packetloss_cvx.allocation.stability import stability_allocate
from packetloss_cvx.closedloop.critical import critical_mu

CASES = (
    ("scalar a=2", "stable", (1.0,), {"margin": 0.5}),
    ("two_actuator", "stable", (1.0, 1.0), {}),
    ("two_actuator", "stable", (1.0, 1.0), {"margin": 0.9}),
    ("two_actuator", "stable", (1.0, 0.05), {}),
    ("two_actuator", "dp-cost", (1.0, 0.05), {"alpha": 10.0}),
    ("two_actuator", "dp-cost", (1.0, 1.0), {"alpha": 10.0}),
    ("pendulum", "stable", (1.0,), {}),
)


def system_of(name: str) -> System:
    if name.startswith("scalar"):
        return System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    return load_example(name)


def main() -> None:
    print("| system | target | beta | options | mu | beta'mu | lower bound | gap | boxes | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, target, beta, options in CASES:
        system = system_of(name)
        start = time.process_time()
        got = stability_allocate(system, target, beta, progress=False, **options)
        seconds = time.process_time() - start
        mu = ", ".join(f"{v:.6g}" for v in got.mu)
        print(f"| {name} | {target} | {beta} | {options or '-'} | ({mu}) | {got.cost:.6g} | {got.lower_bound:.6g} "
              f"| {got.gap:.1e} | {got.boxes} | {seconds:.2f} |")
    ta = load_example("two_actuator")
    print(f"\nreferences: critical_mu(two_actuator, dp, direction (1, 0)) = "
          f"{critical_mu(ta, 'dp', direction=np.array([1.0, 0.0])):.6f}; one state a = 2, rho = 0.5: 1 - rho/a^2 = "
          f"{1 - 0.5 / 4:.6f}; pendulum: critical mu (dp, along mu = t) = "
          f"{critical_mu(load_example('pendulum'), 'dp', direction=np.ones(1)):.6f}")


if __name__ == "__main__":
    main()
