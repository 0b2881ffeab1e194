"""Running the program under another BLAS kernel, and comparing what a user sees within the tolerance registry.

OpenBLAS picks its kernels at start-up from ``OPENBLAS_CORETYPE``; two kernels round sums in other orders, so one
computation gives floats that differ in their last bits and every derived number moves by what it is trusted to
(tolerances.KERNEL_*). :func:`compare_results` says, for two ``results.json`` of ``reproduce``, where they differ by
more: verdicts, counts, statuses and texts must be identical; numbers agree within their tolerance.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import platform
import re

from packetloss_cvx.tolerances import (
    ALLOCATION_GAP_DEFAULT,
    CROSS_CHECK_COST_RTOL,
    CROSS_CHECK_INPUT_ATOL,
    KERNEL_MARGIN_RTOL,
    KERNEL_POINT_RTOL,
    KERNEL_VALUE_RTOL,
    KERNEL_ZERO_ATOL,
)

#: the kernels every x86-64 OpenBLAS offers (Prescott is the generic SSE3 one); others need AVX2 / AVX-512
PORTABLE_KERNELS = ("Prescott", "Nehalem", "Sandybridge")


def other_kernel() -> str | None:
    """A kernel other than the one this process runs (None where OpenBLAS kernels cannot be chosen by name)."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return None
    current = os.environ.get("OPENBLAS_CORETYPE", "")
    return next(k for k in PORTABLE_KERNELS if k.lower() != current.lower())


def _tolerance(path: str, data: dict) -> tuple[float, float] | None:
    """(rtol, atol) for the number at ``path``; None where it is compared through another number."""
    if re.fullmatch(r"/allocations/\w+/[^/]+\[\d+\]/mu\[\d+\]", path):
        return None                                 # a flat optimum's point: compared through its cost (registry)
    if re.fullmatch(r"/(cost|lower_bound)", path) and "target" in data:
        return ALLOCATION_GAP_DEFAULT, 0.0          # a stability allocation: within the certified gap
    if re.fullmatch(r"/allocations/\w+/[^/]+\[\d+\]/(communication_cost|lower_bound)", path):
        return ALLOCATION_GAP_DEFAULT, 0.0          # each run is within the certified gap of one optimum
    if m := re.fullmatch(r"/ack/\[([^\]]*)\]/break_even\[\d+\]", path):
        beta = [float(b) for b in m.group(1).split(",")]
        return 0.0, ALLOCATION_GAP_DEFAULT * sum(beta)   # a difference of two totals, each within gap * beta'1
    if re.fullmatch(r"/ack_attainable/mu\[\d+\]\[\d+\]", path):
        return None                                 # a design's point, certified to a gap: compared through its cost
    if m := re.fullmatch(r"/ack_attainable/(tcp_design|break_even|paper_design_attains)\[(\d+)\]", path):
        gap, k = data["ack_attainable"]["gap"], int(m.group(2))
        if m.group(1) == "tcp_design":
            return gap, 0.0                             # each run within its certified gap of one optimum
        if m.group(1) == "break_even":                  # the TCP-like design's gap plus the UDP-like one's, beta = 1'
            return 0.0, gap * data["ack_attainable"]["tcp_design"][k] + 2 * ALLOCATION_GAP_DEFAULT
        return None                                     # the DP at a paper design's mu: compared through its cost
    if m := re.fullmatch(r"/(audit|claims)\[(\d+)\]/worst", path):
        if data[m.group(1)][int(m.group(2))]["verdict"] == "holds":
            return KERNEL_MARGIN_RTOL, KERNEL_ZERO_ATOL   # a tolerance less a rounding-level error
        return KERNEL_POINT_RTOL, KERNEL_ZERO_ATOL      # a failing claim's margin (maximisers' locations among them)
    if re.search(r"/maximiser/(mu|nu)", path):
        return KERNEL_POINT_RTOL, KERNEL_ZERO_ATOL  # maximisers' locations
    return KERNEL_VALUE_RTOL, KERNEL_ZERO_ATOL


#: what is not a result: wall times, and the work a search did (its branch-and-bound boxes: the answer's status and
#: gap are compared, not how many boxes rounding made it open)
NOT_RESULTS = re.compile(r".*/(solve_time|boxes)")
#: differences between two computations of one quantity (a cross-check's measure) and an allocation's certified gap
#: (a difference of its cost and its bound): rounding, compared by staying within the band they are checked against
CERTIFIED_MEASURES = re.compile(r".*/(max_input_diff|cost_rel_diff)|/gap")


#: a number's own accuracy estimate (``lambda_error``: a chain's lambda against the radius of its own gains), an error's
#: size, not a value: rounding on both kernels where both are within the kernel band, else the same size to a factor
#: of ACCURACY_FACTOR (3.96e-12 under Haswell, 3.97e-13 under Prescott for pendulum_bursty's lambda; 6.2e-6 and
#: 1.8e-6 under Haswell and Sandybridge for the defective chain of tests/closedloop/test_markov_region.py)
ACCURACY_ESTIMATES = re.compile(r".*_error(\[\d+\])*")
ACCURACY_FACTOR = 10.0


def compare_results(a: dict, b: dict) -> list[str]:
    """Every place where two results.json (or two commands' JSON) differ beyond tolerance (empty when they agree)."""
    problems: list[str] = []

    def walk(x, y, path: str) -> None:
        if isinstance(x, dict) and isinstance(y, dict):
            if x.keys() != y.keys():
                problems.append(f"{path}: keys {sorted(x)} != {sorted(y)}")
                return
            for key in x:
                walk(x[key], y[key], f"{path}/{key}")
        elif isinstance(x, list) and isinstance(y, list):
            if len(x) != len(y):
                problems.append(f"{path}: lengths {len(x)} != {len(y)}")
                return
            for i, (u, v) in enumerate(zip(x, y, strict=True)):
                walk(u, v, f"{path}[{i}]")
        elif NOT_RESULTS.fullmatch(path):
            return
        elif CERTIFIED_MEASURES.fullmatch(path) and isinstance(x, float) and isinstance(y, float):
            band = (CROSS_CHECK_INPUT_ATOL if path.endswith("max_input_diff") else
                    CROSS_CHECK_COST_RTOL if path.endswith("cost_rel_diff") else ALLOCATION_GAP_DEFAULT)
            if not (x <= band and y <= band):
                problems.append(f"{path}: {x!r}, {y!r} (both must stay within the cross-check's {band:g})")
        elif ACCURACY_ESTIMATES.fullmatch(path) and isinstance(x, float) and isinstance(y, float):
            if not ((x <= KERNEL_VALUE_RTOL and y <= KERNEL_VALUE_RTOL)
                    or max(x, y) <= ACCURACY_FACTOR * min(x, y)):
                problems.append(f"{path}: {x!r}, {y!r} (an accuracy estimate: both within {KERNEL_VALUE_RTOL:g}, "
                                f"or within a factor {ACCURACY_FACTOR:g})")
        elif isinstance(x, float) and isinstance(y, float) and not isinstance(x, bool):
            band = _tolerance(path, a)
            if band is None or x == y:
                return
            rtol, atol = band
            if not (math.isfinite(x) and math.isfinite(y)) or abs(x - y) > rtol * max(abs(x), abs(y)) + atol:
                problems.append(f"{path}: {x!r} != {y!r} (rtol {rtol:g}, atol {atol:g})")
        elif x != y or type(x) is not type(y):
            problems.append(f"{path}: {x!r} != {y!r}")

    walk(a, b, "")
    return problems


#: every shipped example through every command it answers, with JSON out (what tests/cli/test_examples_kernels.py runs
#: under two kernels): a Gilbert–Elliott file gets its burstiness sweep and region map; one-channel files their
#: critical mu; files the stability allocation refuses are kept for their refusal (exit 2 under every kernel)
EXAMPLES = ("pendulum", "two_actuator", "pendulum_bursty", "pendulum_sensor")


def example_commands(example: str) -> dict[str, list[str]]:
    two = example in ("two_actuator", "pendulum_bursty")
    return {
        "solve": ["solve", example, "--json", "-q"],
        "simulate": ["simulate", example, "--samples", "200", "--steps", "10", "--seed", "0", "--closed-loop",
                     "--json", "-q"],
        "region": ["region", example, *(["--grid", "3"] if two else []), "--json", "-q"],
        "region dp": ["region", example, "--law", "dp", *(["--grid", "3"] if two else []), "--json", "-q"],
        "sweep": ["sweep", example, *(["--burstiness", "0:0.9:3"] if example == "pendulum_bursty"
                                      else ["--mu-grid", "3"]), "--json", "-q"],
        "allocate": ["allocate", example, "--target", "stable", "--beta", "1,1" if two else "1", "--json", "-q"],
        **({"audit": ["audit", example, "--json", "-q"]} if example in ("pendulum_bursty", "pendulum_sensor")
           else {}),
    }


def run_examples() -> dict[str, dict]:
    """Each (example, command): its exit code, its JSON (None if it printed none) and its last stderr line."""
    from packetloss_cvx.cli import main

    out = {}
    for example in EXAMPLES:
        for name, argv in example_commands(example).items():
            stdout, stderr = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
                code = main(argv)
            try:
                data = json.loads(stdout.getvalue())
            except ValueError:
                data = None
            lines = stderr.getvalue().strip().splitlines()
            out[f"{example} {name}"] = {"code": code, "json": data, "stderr": lines[-1] if lines else ""}
    return out
