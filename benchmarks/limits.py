"""Issue 20's unbounded and long cases, old commit against this tree, side by side in one run.

Each case runs as ``python -m packetloss_cvx ...`` with ``PYTHONPATH`` set to a checkout, one BLAS
thread, at most ``--cap`` seconds of wall time and 3 GB of address space (an old run past either is
stopped and reported as such); old and new runs are interleaved. Reported: exit code, wall and CPU
seconds (the child's user + system time), and the first line of stderr.

    python benchmarks/limits.py --old /work/base/cfb251d [--cap 60] [--only solve-n200]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

NEW = str(Path(__file__).resolve().parent.parent)


def orthogonal_system(path: Path, n: int = 200) -> str:
    """An n-state plant with an orthogonal A and two actuators: ARPACK's hard case for the stability radius."""
    sys.path.insert(0, NEW)
    from packetloss_cvx import System, save_system
    rng = np.random.default_rng(1)
    A, _ = np.linalg.qr(rng.standard_normal((n, n)))
    B = rng.standard_normal((n, 2))
    s = System(A=A, B=B, horizon=10, state_weight=np.ones(n), input_weight=np.ones(2), mu=[0.9, 0.5], x0=np.ones(n))
    return str(save_system(s, path))


def cases(folder: Path) -> dict[str, list[str]]:
    big = orthogonal_system(folder / "orth200.toml")
    return {
        "solve-n200": ["solve", big, "--no-qp"],
        "simulate-1e12": ["simulate", "two_actuator", "--samples", "1000000000000", "-q"],
        "mu-list-dev-zero": ["sweep", "two_actuator", "--mu-list", "/dev/zero", "-q"],
        "audit-1e12": ["audit", "--random", "1000000000000", "-q"],
        "burstiness-1e6": ["sweep", "pendulum_bursty", "--burstiness", "0:0.9:1000000", "-q"],
        "dask-unreachable": ["sweep", "two_actuator", "--mu-grid", "3", "--dask", "http://example.invalid:8786"],
    }


def run(tree: str, argv: list[str], cap: float, cwd: str) -> tuple[str, float, float, str]:
    def limits() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, 3 * 2**30))

    env = {**os.environ, "PYTHONPATH": tree, "OPENBLAS_NUM_THREADS": "1"}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-m", "packetloss_cvx", *argv], capture_output=True, text=True,
                              env=env, timeout=cap, preexec_fn=limits, check=False,
                              cwd=cwd)    # not a checkout: python -m puts the working folder first
        code, err = str(proc.returncode), (proc.stderr.splitlines() or [""])[0]
        lines = len(proc.stderr.splitlines())
        err = f"{err[:90]}" + (f" (+{lines - 1} lines)" if lines > 1 else "")
    except subprocess.TimeoutExpired:
        code, err = "stopped", f"still running after {cap:g} s"
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return code, wall, cpu, err


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", required=True, help="a checkout of the commit to compare with")
    parser.add_argument("--cap", type=float, default=60.0, help="seconds of wall time per run")
    parser.add_argument("--only", action="append", help="run only this case (repeatable)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for name, argv in cases(Path(tmp)).items():
            if args.only and name not in args.only:
                continue
            for label, tree in (("new", NEW), ("old", args.old), ("new", NEW)):
                code, wall, cpu, err = run(tree, argv, args.cap, tmp)
                print(f"{name:18s} {label}  exit {code:7s} wall {wall:7.2f} s  cpu {cpu:7.2f} s  {err}", flush=True)


if __name__ == "__main__":
    main()
