"""Running the program under another BLAS kernel, and comparing what a user sees within the tolerance registry.

OpenBLAS picks its kernels at start-up from ``OPENBLAS_CORETYPE``; two kernels round sums in other orders, so one
computation gives floats that differ in their last bits and every derived number moves by what it is trusted to
(tolerances.KERNEL_*). :func:`compare_results` says, for two ``results.json`` of ``reproduce``, where they differ by
more: verdicts, counts, statuses and texts must be identical; numbers agree within their tolerance.
"""

from __future__ import annotations

import math
import os
import platform
import re

from packetloss_cvx.tolerances import (
    ALLOCATION_GAP_DEFAULT,
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
    if re.fullmatch(r"/allocations/\w+/[^/]+\[\d+\]/(communication_cost|lower_bound)", path):
        return ALLOCATION_GAP_DEFAULT, 0.0          # each run is within the certified gap of one optimum
    if m := re.fullmatch(r"/ack/\[([^\]]*)\]/break_even\[\d+\]", path):
        beta = [float(b) for b in m.group(1).split(",")]
        return 0.0, ALLOCATION_GAP_DEFAULT * sum(beta)   # a difference of two totals, each within gap * beta'1
    if m := re.fullmatch(r"/audit\[(\d+)\]/worst", path):
        if data["audit"][int(m.group(1))]["verdict"] == "holds":
            return KERNEL_MARGIN_RTOL, KERNEL_ZERO_ATOL   # a tolerance less a rounding-level error
        return KERNEL_POINT_RTOL, KERNEL_ZERO_ATOL      # a failing claim's margin (maximisers' locations among them)
    if re.search(r"/maximiser/(mu|nu)", path):
        return KERNEL_POINT_RTOL, KERNEL_ZERO_ATOL  # maximisers' locations
    return KERNEL_VALUE_RTOL, KERNEL_ZERO_ATOL


def compare_results(a: dict, b: dict) -> list[str]:
    """Every place where two results.json differ beyond tolerance (an empty list when they agree)."""
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
