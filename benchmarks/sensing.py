"""Issue 22's lossy-sensor computations: CPU seconds (time.process_time, one BLAS thread) of each part on the
pendulum_sensor example, beside the full-state ``solve --no-qp`` of the same plant in the same run, so that the
ratio says what a [sensor] section adds to ``solve``. Runs are interleaved and repeated.

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=. python benchmarks/sensing.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def cpu(fn) -> float:
    start = time.process_time()
    fn()
    return time.process_time() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    from packetloss_cvx.cli.parser import build_parser
    from packetloss_cvx.cli.solve import run as solve_run
    from packetloss_cvx.closedloop.riccati import dp_riccati
    from packetloss_cvx.model.files import load_example
    from packetloss_cvx.model.sensor import Sensor
    from packetloss_cvx.sensing.bounds import covariance_bounds, critical_gamma
    from packetloss_cvx.sensing.loop import estimated_loop, loop_map
    from packetloss_cvx.sensing.markov_bounds import filter_stability, markov_covariance_bounds
    from packetloss_cvx.sensing.montecarlo import sampled_covariance, simulate_estimated

    s = load_example("pendulum_sensor")
    gain = dp_riccati(s).gain
    # the same link made bursty (a Gilbert channel, long-run rate 0.8): the Markov analyses of the session-28 gaps
    ge = Sensor(C=s.sensor.C, noise_cov=s.sensor.noise_cov, P0=s.sensor.P0,
                channel={"model": "gilbert-elliott", "p": [0.05], "r": [0.2]})
    s_ge = s.with_sensor(ge)
    cases = {
        "solve pendulum --no-qp (full state)": lambda: solve_run(build_parser().parse_args(
            ["solve", "pendulum", "--no-qp", "-q"])),
        "solve pendulum_sensor --no-qp": lambda: solve_run(build_parser().parse_args(
            ["solve", "pendulum_sensor", "--no-qp", "-q"])),
        "critical_gamma (one channel)": lambda: critical_gamma(s.A, s.sensor),
        "covariance_bounds": lambda: covariance_bounds(s.A, s.noise_cov, s.sensor),
        "estimated_loop (dp, tcp)": lambda: estimated_loop(s, gain, "tcp", "dp"),
        "simulate_estimated kalman 1000 x 100": lambda: simulate_estimated(s, gain, "tcp", "kalman", 1000, 100),
        "loop_map 5 x 5": lambda: loop_map(s, np.linspace(0.2, 1.0, 5), np.linspace(0.2, 1.0, 5)),
        "filter_stability (Gilbert-Elliott)": lambda: filter_stability(s.A, s.noise_cov, ge),
        "markov_covariance_bounds (Gilbert-Elliott)": lambda: markov_covariance_bounds(s.A, s.noise_cov, ge),
        "sampled_covariance GE 1000 x 100": lambda: sampled_covariance(s.A, s.noise_cov, ge, 100, 1000),
        "simulate_estimated kalman GE 1000 x 100": lambda: simulate_estimated(s_ge, gain, "tcp", "kalman", 1000,
                                                                            100),
    }
    times: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(args.repeat):
        for name, fn in cases.items():           # interleaved
            times[name].append(cpu(fn))
    base = min(times["solve pendulum --no-qp (full state)"])
    print(f"{'case':<42} {'CPU s (min)':>12} {'x full-state solve':>20}")
    for name, t in times.items():
        print(f"{name:<42} {min(t):>12.3f} {min(t) / base:>20.2f}")


if __name__ == "__main__":
    main()
