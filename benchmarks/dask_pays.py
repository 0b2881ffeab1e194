"""When Dask pays for a sweep: in process against ``dask="local"`` and an already running LocalCluster, on the
two-actuator system's K x K channel grid (both protocols), for several K (docs/dask.md, "When it pays").

    OPENBLAS_NUM_THREADS=1 python benchmarks/dask_pays.py [--grids 41,201,401] [--workers 2] [--repeats 1] [--json]

Wall-clock seconds, because the work of a Dask path runs in the worker processes (the calling process's CPU
time, also printed, is only its own share); the three paths run interleaved per grid and repeat, and their
arrays are compared bit for bit. A script that starts ``dask="local"`` needs the ``if __name__ ==
"__main__":`` guard this file ends with: the workers are new processes that import the script again.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import packetloss_cvx as pl  # noqa: E402
from packetloss_cvx.studies import sweep  # noqa: E402


def timed(fn):
    wall, cpu = time.perf_counter(), time.process_time()
    value = fn()
    return time.perf_counter() - wall, time.process_time() - cpu, value


def main() -> None:
    from distributed import Client, LocalCluster

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grids", default="41,201,401", help="comma-separated K (K x K points)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    system = pl.load_example("two_actuator")
    print(f"python {platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} cores, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}, {time.strftime('%Y-%m-%d %H:%M %Z')}, "
          f"load average {os.getloadavg()[0]:.1f}, {args.workers} workers of 1 thread")
    rows = []
    for K in (int(k) for k in args.grids.split(",")):
        for _ in range(args.repeats):
            here_s, here_cpu, here = timed(partial(sweep, system, mu_grid=K, progress=False))
            local_s, _, local = timed(partial(sweep, system, mu_grid=K, dask="local", workers=args.workers,
                                              progress=False))
            with LocalCluster(n_workers=args.workers, threads_per_worker=1, dashboard_address=None,
                              silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
                sweep(system, mu_grid=5, dask=client, progress=False)          # warm the workers' imports
                warm_s, _, warm = timed(partial(sweep, system, mu_grid=K, dask=client, progress=False))
            same = all(np.array_equal(v, local.arrays()[k]) and np.array_equal(v, warm.arrays()[k])
                       for k, v in here.arrays().items())
            print(f"{K} x {K} ({K * K} points): in process {here_s:.2f} s (cpu {here_cpu:.2f}); dask='local' "
                  f"{local_s:.2f} s ({local_s / here_s:.1f}x, start-up included); running cluster {warm_s:.2f} s "
                  f"({warm_s / here_s:.2f}x); identical {same}", flush=True)
            rows.append({"K": K, "in_process_s": here_s, "in_process_cpu_s": here_cpu, "dask_local_s": local_s,
                         "dask_running_s": warm_s, "identical": same, "load": os.getloadavg()[0]})
    if args.json:
        print(json.dumps(rows))


if __name__ == "__main__":     # dask="local" starts worker processes that import this file again
    main()
