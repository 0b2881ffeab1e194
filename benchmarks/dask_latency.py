"""The latency a Dask sweep adds on an already running cluster when its chunks are quick: the engine's poll
(``studies.engine``) first looks POLL_FIRST_SECONDS after a batch and doubles its wait up to POLL_SECONDS; before
(e520261) it slept POLL_SECONDS (0.5 s) whenever nothing had finished. The old loop is this one with
``POLL_FIRST_SECONDS = POLL_SECONDS``, so both run side by side in one process, interleaved, on one cluster.

    OPENBLAS_NUM_THREADS=1 python benchmarks/dask_latency.py [--repeats 5]

Wall-clock seconds (the wait is idle time, not CPU; the calling process's CPU is printed too), the sweeps of
tests/studies/test_dask.py (pendulum over x0 scales, horizons, a 7 x 7 grid; two-actuator 13 x 13), arrays compared bit for
bit between the two settings and against the in-process sweep.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import packetloss_cvx as pl  # noqa: E402
from packetloss_cvx.studies import engine, sweep  # noqa: E402

CASES = [("pendulum", {"x0_scales": [0.5, 1.0, 2.0], "chunk_size": 2}),
         ("pendulum", {"horizons": [5, 20, 40], "chunk_size": 2}),
         ("pendulum", {"mu_grid": 7, "chunk_size": 2}),
         ("two_actuator", {"mu_grid": 13, "chunk_size": 20})]


def main() -> None:
    from distributed import Client, LocalCluster

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    print(f"{os.cpu_count()} cores, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}, "
          f"{time.strftime('%Y-%m-%d %H:%M %Z')}, load average {os.getloadavg()[0]:.1f}")
    first = engine.POLL_FIRST_SECONDS
    settings = {"fixed 0.5 s (e520261)": engine.POLL_SECONDS, "doubling from 5 ms": first}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        for name, kwargs in CASES:
            system = pl.load_example(name)
            here = sweep(system, progress=False, **kwargs)
            walls = {label: [] for label in settings}
            for _ in range(args.repeats):
                for label, value in settings.items():
                    engine.POLL_FIRST_SECONDS = value
                    wall, cpu = time.perf_counter(), time.process_time()
                    there = sweep(system, dask=client, progress=False, **kwargs)
                    walls[label].append((time.perf_counter() - wall, time.process_time() - cpu))
                    assert all(np.array_equal(v, there.arrays()[k]) for k, v in here.arrays().items()), (name, kwargs)
            engine.POLL_FIRST_SECONDS = first
            text = "; ".join(f"{label} {np.median([w for w, _ in v]):.3f} s wall "
                             f"(cpu {np.median([c for _, c in v]):.3f})" for label, v in walls.items())
            print(f"{name} {kwargs}: {text}; identical")


if __name__ == "__main__":
    main()
