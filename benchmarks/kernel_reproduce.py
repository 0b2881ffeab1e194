"""The full ``reproduce`` under two BLAS kernels, compared within the tolerance registry (tests/kernels.py).

    python benchmarks/kernel_reproduce.py [KERNEL_A KERNEL_B]     (default: Prescott and this process's kernel)

Prints each run's CPU time and every number that differs beyond its tolerance; exits 1 if any does. The suite runs
the same comparison on ``reproduce --quick`` (tests/cli/test_reproduce_kernels.py).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.kernels import compare_results  # noqa: E402


def run(kernel: str | None, out: Path) -> dict:
    env = dict(os.environ)
    if kernel:
        env["OPENBLAS_CORETYPE"] = kernel
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-m", "packetloss_cvx", "reproduce", "--out", str(out), "--quiet"],
                   env=env, check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    print(f"reproduce under {kernel or 'the default kernel'}: {cpu:.1f} s CPU")
    return json.loads((out / "results.json").read_text())


def main(argv: list[str]) -> int:
    kernels = argv if argv else ["Prescott", os.environ.get("OPENBLAS_CORETYPE")]
    with tempfile.TemporaryDirectory() as tmp:
        a, b = (run(k, Path(tmp) / f"run{i}") for i, k in enumerate(kernels[:2]))
    problems = compare_results(a, b)
    for line in problems:
        print(line)
    print(f"{len(problems)} numbers or texts differ beyond their tolerance")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
