"""Sweeps and reproduce, side by side in one run (docs/performance.md, "Other benchmarks").

    OPENBLAS_NUM_THREADS=1 python benchmarks/sweeps.py [--quick] [--json] [--only 1,2,3] [--baseline DIR]

1. the batched evaluator (CostEvaluator.costs) against a per-point loop of closed_form on a K x K grid
   of the two-actuator system's channels (K = 201; 51 with --quick), both protocols;
2. ``sweep`` in process against ``sweep --dask local`` (2 worker processes) on the same grid, with and
   without the cluster's start-up, and whether the arrays are identical;
3. ``packetloss-cvx reproduce`` end to end in a fresh process (``--quick`` with --quick).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import packetloss_cvx as pl  # noqa: E402
from packetloss_cvx.lq.evaluator import CostEvaluator  # noqa: E402
from packetloss_cvx.studies import sweep  # noqa: E402


def timed(fn):
    start = time.perf_counter()
    value = fn()
    return time.perf_counter() - start, value


BASELINE_BATCH = """
import sys, time
import numpy as np
import packetloss_cvx as pl
from packetloss_cvx.lq.evaluator import CostEvaluator
K, protocol, repeats = int(sys.argv[1]), sys.argv[2], int(sys.argv[3])
axis = np.linspace(0.0, 1.0, K)
mu1, mu2 = np.meshgrid(axis, axis)
points = np.column_stack([mu1.ravel(), mu2.ravel()])
system = pl.load_example("two_actuator")
times = []
for _ in range(repeats):
    start = time.perf_counter()
    CostEvaluator(system, protocol).costs(points)
    times.append(time.perf_counter() - start)
print(float(np.median(times)))
"""


def baseline_batch(baseline: str, K: int, protocol: str, repeats: int) -> float:
    """The median batched time of another checkout (a fresh process with that checkout first on the path)."""
    env = {**os.environ, "PYTHONPATH": str(Path(baseline).resolve())}
    out = subprocess.run([sys.executable, "-c", BASELINE_BATCH, str(K), protocol, str(repeats)], env=env,
                         check=True, capture_output=True, text=True, cwd=baseline).stdout
    return float(out.split()[-1])


def batched_vs_loop(K: int, rows: list, baseline: str | None = None, repeats: int = 5) -> None:
    system = pl.load_example("two_actuator")
    axis = np.linspace(0.0, 1.0, K)
    mu1, mu2 = np.meshgrid(axis, axis)
    points = np.column_stack([mu1.ravel(), mu2.ravel()])
    print(f"\n1. batched evaluator vs per-point closed_form, two-actuator, {K} x {K} = {len(points)} points "
          f"(batched: median of {repeats}{'; baseline: ' + baseline if baseline else ''})")
    print(f"{'protocol':>8} {'loop s':>9} {'batched s':>10} {'ratio':>7} {'max rel diff':>13}"
          + (f" {'baseline s':>11} {'ratio':>7}" if baseline else ""))
    for protocol in ("tcp", "udp"):
        loop_s, loop = timed(lambda p=protocol: np.array([pl.closed_form(system.with_mu(mu), p).cost
                                                          for mu in points]))
        times = [timed(lambda p=protocol: CostEvaluator(system, p).costs(points)) for _ in range(repeats)]
        batch_s, batch = float(np.median([s for s, _ in times])), times[0][1]
        rel = float(np.max(np.abs(batch - loop) / np.abs(loop)))
        line = f"{protocol:>8} {loop_s:9.2f} {batch_s:10.3f} {loop_s / batch_s:6.0f}x {rel:13.1e}"
        row = {"bench": "batched", "K": K, "protocol": protocol, "loop_s": loop_s, "batched_s": batch_s,
               "ratio": loop_s / batch_s, "max_rel_diff": rel}
        if baseline:
            before = baseline_batch(baseline, K, protocol, repeats)
            line += f" {before:11.3f} {loop_s / before:6.0f}x"
            row.update(baseline_batched_s=before, baseline_ratio=loop_s / before)
        print(line)
        rows.append(row)


def dask_vs_in_process(K: int, chunk: int, rows: list) -> None:
    from distributed import Client, LocalCluster

    system = pl.load_example("two_actuator")
    print(f"\n2. sweep in process vs --dask local (2 workers, 1 thread each), {K} x {K}, chunk {chunk}")
    here_s, here = timed(lambda: sweep(system, mu_grid=K, chunk_size=chunk, progress=False))
    local_s, local = timed(lambda: sweep(system, mu_grid=K, chunk_size=chunk, dask="local", progress=False))
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None, silence_logs=logging.ERROR) as c, \
            Client(c) as client:
        sweep(system, mu_grid=5, dask=client, progress=False)             # warm the workers' imports
        warm_s, warm = timed(lambda: sweep(system, mu_grid=K, chunk_size=chunk, dask=client, progress=False))
    same = all(np.array_equal(v, local.arrays()[k]) and np.array_equal(v, warm.arrays()[k])
               for k, v in here.arrays().items())
    print(f"   in process {here_s:.2f} s; --dask local {local_s:.2f} s (cluster start-up included, "
          f"{local_s / here_s:.1f}x); on a running 2-worker cluster {warm_s:.2f} s ({warm_s / here_s:.2f}x); "
          f"arrays identical: {same}")
    rows.append({"bench": "dask", "K": K, "chunk": chunk, "in_process_s": here_s, "dask_local_s": local_s,
                 "dask_running_s": warm_s, "identical": same})


def reproduce(quick: bool, rows: list) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")}
    with tempfile.TemporaryDirectory() as out:
        argv = [sys.executable, "-m", "packetloss_cvx", "reproduce", "--out", out, "--quiet"] + (["--quick"] * quick)
        seconds, proc = timed(lambda: subprocess.run(argv, env=env, capture_output=True, text=True, check=False))
    print(f"\n3. reproduce{' --quick' if quick else ''} end to end: {seconds:.1f} s (exit {proc.returncode})")
    rows.append({"bench": "reproduce", "quick": quick, "seconds": seconds, "exit": proc.returncode})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a 51 x 51 grid and reproduce --quick")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON at the end")
    parser.add_argument("--only", help="comma-separated section numbers to run (default: all)")
    parser.add_argument("--baseline", help="a checkout of the previous version (section 1: its batched time too)")
    args = parser.parse_args()
    chosen = {1, 2, 3} if not args.only else {int(k) for k in args.only.split(",")}
    print(f"python {platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} cores, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}, {time.strftime('%Y-%m-%d')}")
    rows: list[dict] = []
    K = 51 if args.quick else 201
    if 1 in chosen:
        batched_vs_loop(K, rows, args.baseline)
    if 2 in chosen:
        dask_vs_in_process(K, 2048, rows)
    if 3 in chosen:
        reproduce(args.quick, rows)
    if args.json:
        print(json.dumps(rows))


if __name__ == "__main__":
    main()
