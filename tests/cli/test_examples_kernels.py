"""Every shipped example answers every command it answers under this kernel under another one too: the same exit
codes, and JSON that agrees within the tolerance registry (tests/kernels.py)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ..kernels import compare_results, other_kernel, run_examples

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def two_kernels():
    kernel = other_kernel()
    if kernel is None:
        pytest.skip("OpenBLAS kernels are chosen by name on x86-64 only")
    here = run_examples()
    code = (f"import json, sys; sys.path.insert(0, {str(ROOT)!r}); from tests.kernels import run_examples; "
            "sys.stdout.write(json.dumps(run_examples()))")
    run = subprocess.run([sys.executable, "-c", code], env={**os.environ, "OPENBLAS_CORETYPE": kernel},
                         capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-2000:]
    return here, json.loads(run.stdout), kernel


def test_every_example_gets_the_same_exit_code_under_another_kernel(two_kernels):
    here, there, kernel = two_kernels
    assert {k: v["code"] for k, v in here.items()} == {k: v["code"] for k, v in there.items()}, kernel
    assert all(v["code"] in (0, 2) for v in here.values()), {k: v["stderr"] for k, v in here.items() if v["code"]}


def test_every_example_prints_the_same_numbers_under_another_kernel(two_kernels):
    here, there, kernel = two_kernels
    problems = {k: compare_results(v["json"], there[k]["json"]) for k, v in here.items()
                if v["json"] is not None and there[k]["json"] is not None}
    assert {k: p for k, p in problems.items() if p} == {}, kernel
