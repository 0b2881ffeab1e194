"""Margins, verdicts and shrinking: how a check on many cases becomes one ClaimResult.

A check computes a *margin* per case: >= 0 where the claim holds for that case,
< 0 where it fails (for equalities, tolerance minus error), None where the claim
does not apply. A violation is shrunk to the smallest simple system that still
violates: small n, m, N and integers or halves, checkable by hand.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence

import numpy as np

from ..errors import InputError, SolverError
from ..model import System
from ..results import ClaimResult
from .context import Context
from .paper import STATEMENTS

__all__ = ["Z", "evaluate", "shrink", "simple_system", "z_margin"]

#: Monte Carlo checks allow Z standard errors (two-sided 99.994 % per case).
Z = 4.0

Margin = Callable[[System], float | None]


def simple_system(rng: np.random.Generator, n: int, m: int, N: int) -> System:
    """Small integers and halves: the kind of example a reader can check by hand."""
    A = rng.integers(-2, 3, (n, n)) / 2
    B = rng.integers(-2, 3, (n, m)) / 2
    B[:, ~B.any(axis=0)] = 1.0
    x0 = rng.integers(-2, 3, n).astype(float)
    if not x0.any():
        x0[0] = 1.0
    return System(A=A, B=B, horizon=N, state_weight=np.ones(n), input_weight=np.ones(m),
                  mu=rng.integers(1, 10, m) / 10, x0=x0)


def _sizes(max_total: int = 9) -> Iterator[tuple[int, int, int]]:
    for total in range(3, max_total + 1):
        for n in range(1, 4):
            for m in range(1, 4):
                N = total - n - m
                if 1 <= N <= 6:
                    yield n, m, N


def _safe(margin: Margin, system: System) -> float | None:
    try:
        return margin(system)
    except (InputError, ArithmeticError, SolverError, np.linalg.LinAlgError):
        return None


def shrink(margin: Margin, seed: int, tries: int = 12, fallback: Sequence[System] = ()) -> System | None:
    """The first violating simple system in order of size n + m + N, else the smallest
    violating one among ``fallback``.

    Parameters
    ----------
    margin : callable
        The check's margin; < 0 is a violation.
    seed : int
        Seeds the simple systems tried, so the counterexample is reproducible.
    tries : int
        Simple systems tried per size (n, m, N).
    fallback : sequence of System
        Where to look when no simple system violates.

    Returns
    -------
    System or None
    """
    rng = np.random.default_rng(seed)
    for n, m, N in _sizes():
        for _ in range(tries):
            system = simple_system(rng, n, m, N)
            value = _safe(margin, system)
            if value is not None and value < 0:
                return system
    bad = [s for s in fallback if (v := _safe(margin, s)) is not None and v < 0]
    return min(bad, key=lambda s: (s.n + s.m + s.horizon, s.n, s.m)) if bad else None


def evaluate(claim_id: str, ctx: Context, cases: Sequence[System], margin: Margin, note: str,
             shrinkable: bool = True) -> ClaimResult:
    """Run ``margin`` on every case and turn the margins into a verdict.

    Parameters
    ----------
    claim_id : str
        A key of :data:`STATEMENTS`.
    ctx : Context
    cases : sequence of System
    margin : callable
        System -> margin (>= 0 holds, < 0 violated, None not applicable).
    note : str
        How the margin is defined, and what the check found.
    shrinkable : bool
        Whether to look for a small counterexample when a case violates.

    Returns
    -------
    ClaimResult
    """
    values = [v for s in cases if (v := _safe(margin, s)) is not None]
    violations = sum(v < 0 for v in values)
    counterexample = None
    if violations and shrinkable:
        found = shrink(margin, ctx.seed, fallback=cases)
        counterexample = found.to_dict() if found is not None else None
    return ClaimResult(
        id=claim_id, statement=STATEMENTS[claim_id], verdict="fails" if violations else "holds",
        checked=len(values), violations=int(violations), worst=float(min(values)) if values else None,
        counterexample=counterexample, note=note,
    )


def z_margin(samples: np.ndarray, expect: float) -> float:
    """Z - |z| of the sample mean against ``expect``; a degenerate sample must match to 1e-9."""
    se = samples.std(ddof=1) / np.sqrt(samples.size)
    err = abs(samples.mean() - expect)
    if se <= 1e-12 * max(1.0, abs(expect)):
        return Z if err <= 1e-9 * max(1.0, abs(expect)) else -np.inf
    return Z - err / se
