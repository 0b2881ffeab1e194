"""Margins, verdicts and shrinking: how a check on many cases becomes one ClaimResult.

A check computes a *margin* per case: >= 0 where the claim holds for that case,
< 0 where it fails (for equalities, tolerance minus error), None where the claim
does not apply (an explicit skip, which the check's note explains). A case whose
check raises one of `CASE_ERRORS` (a numerical or solver failure, or input
the check cannot take) has *errored*: it is counted, named in the note, and never
read as agreement. A NaN margin counts as an error too.

Verdict (`verdict`): "fails" when some case violates (a proven violation,
whatever else errored); otherwise "inconclusive" when a case errored or none was
checked; otherwise "holds". A violation is shrunk to the smallest simple system
that still violates: small n, m, N and integers or halves, checkable by hand.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError, NumericalError, SolverError
from ..model.system import System
from ..results import ClaimResult
from ..tolerances import RESOLVED_MIN
from .context import Context
from .paper import STATEMENTS

__all__ = ["CASE_ERRORS", "SimpleSystems", "Tally", "Z", "cost_scale", "evaluate", "relative_error", "resolved",
           "shrink", "simple_system", "simple_systems", "verdict", "z_margin"]

#: Monte Carlo checks allow Z standard errors (two-sided 99.994 % per case).
Z = 4.0

#: The exceptions that make a case *errored* (counted and reported) rather than crash the audit.
#: Anything else (TypeError, KeyError, ...) is a bug in the audit and propagates.
CASE_ERRORS = (InputError, ArithmeticError, SolverError, np.linalg.LinAlgError)

Margin = Callable[[Any], float | None]


def verdict(checked: int, violations: int, errors: int) -> str:
    """"fails" if any violation; else "inconclusive" if any error or nothing checked; else "holds".

    Examples
    --------
    >>> verdict(3, 0, 0), verdict(3, 1, 2), verdict(3, 0, 1), verdict(0, 0, 0)
    ('holds', 'fails', 'inconclusive', 'inconclusive')
    """
    if violations:
        return "fails"
    if errors or not checked:
        return "inconclusive"
    return "holds"


@dataclass
class Tally:
    """What happened to each case of one check, in case order.

    Attributes
    ----------
    outcomes : list of str
        ``"+"`` holds, ``"-"`` violated, ``"."`` not applicable, ``"E"`` errored.
    margins : list of float
        The margins of the checked cases.
    failures : list of str
        ``"label: ErrorType: message"`` for each errored case.

    Examples
    --------
    >>> t = Tally()
    >>> [t.run(lambda x: x, v, f"case {v}") for v in (0.5, -1.0, None)]
    [0.5, -1.0, None]
    >>> "".join(t.outcomes), t.checked, t.violations
    ('+-.', 2, 1)
    """

    outcomes: list[str] = field(default_factory=list)
    margins: list[float] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)

    def run(self, margin: Margin, case: Any, label: str) -> float | None:
        """Run ``margin`` on ``case`` and record the outcome; returns the margin (None if skipped
        or errored)."""
        try:
            value = margin(case)
            if value is not None and np.isnan(value):
                raise ArithmeticError("the margin is NaN")
        except CASE_ERRORS as err:
            self.outcomes.append("E")
            self.failures.append(f"{label}: {type(err).__name__}: {_brief(str(err))}")
            return None
        if value is None:
            self.outcomes.append(".")
            return None
        value = float(value)
        self.outcomes.append("-" if value < 0 else "+")
        self.margins.append(value)
        return value

    @property
    def checked(self) -> int:
        return len(self.margins)

    @property
    def violations(self) -> int:
        return sum(v < 0 for v in self.margins)

    @property
    def errors(self) -> int:
        return len(self.failures)

    @property
    def worst(self) -> float | None:
        return min(self.margins) if self.margins else None

    def verdict(self) -> str:
        """`verdict` of the counts."""
        return verdict(self.checked, self.violations, self.errors)

    def error_note(self) -> str:
        """One sentence naming the errored cases (at most three), or "" if none errored."""
        if not self.failures:
            return ""
        shown = "; ".join(self.failures[:3])
        more = f"; and {len(self.failures) - 3} more" if len(self.failures) > 3 else ""
        return f" Errored ({self.errors}, not counted as checked): {shown}{more}."

    def result(self, claim_id: str, statement: str, note: str, counterexample: dict | None = None) -> ClaimResult:
        """The claim's result from this tally: its verdict, counts, worst margin and outcomes, ``note`` followed by
        `error_note`."""
        return ClaimResult(id=claim_id, statement=statement, verdict=self.verdict(), checked=self.checked,
                           violations=int(self.violations), worst=self.worst, counterexample=counterexample,
                           note=note + self.error_note(), errors=self.errors, outcomes="".join(self.outcomes))


def _brief(text: str, limit: int = 100) -> str:
    line = text.splitlines()[0] if text else ""
    return line if len(line) <= limit else line[: limit - 3] + "..."


def simple_system(rng: np.random.Generator, n: int, m: int, N: int) -> System:
    """Small integers and halves: the kind of example a reader can check by hand.

    Examples
    --------
    >>> s = simple_system(np.random.default_rng(0), 2, 1, 3)
    >>> (s.n, s.m, s.horizon), bool(np.all(4 * s.A == np.round(4 * s.A)) and np.all(s.B == np.round(2 * s.B) / 2))
    ((2, 1, 3), True)
    """
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


class SimpleSystems:
    """The simple systems `shrink` tries for one seed, in its order: ``tries`` per size (n, m, N), sizes by
    n + m + N; each drawn once, when first asked for (the same draws in the same order as drawing them afresh).
    An audit keeps one per seed (`simple_systems`), so every claim's shrinking tries the same System
    objects and their cached structure (prediction, evaluator data) is built once, not once per claim.
    O(1) per system after its first draw.

    Examples
    --------
    >>> first = SimpleSystems(0)
    >>> a = [s.to_dict() for s, _ in zip(first, range(3))]
    >>> b = [simple_system(np.random.default_rng(0), 1, 1, 1).to_dict()]     # the first draw of seed 0
    >>> a[0] == b[0], [s for s, _ in zip(first, range(3))] == first.made[:3]   # drawn once, then reused
    (True, True)
    """

    def __init__(self, seed: int, tries: int = 12) -> None:
        self.rng = np.random.default_rng(seed)
        self.sizes = [size for size in _sizes() for _ in range(tries)]
        self.made: list[System] = []

    def __iter__(self) -> Iterator[System]:
        for k, (n, m, N) in enumerate(self.sizes):
            if k == len(self.made):
                self.made.append(simple_system(self.rng, n, m, N))
            yield self.made[k]


def simple_systems(ctx: Context) -> SimpleSystems:
    """The audit's `SimpleSystems` of its seed (made on the first shrink, kept in ``ctx.simple``). O(1).

    Examples
    --------
    >>> ctx = Context(paper={}, random=[], seed=3)
    >>> simple_systems(ctx) is simple_systems(ctx), list(ctx.simple)      # one per audit and seed
    (True, [3])
    """
    if ctx.seed not in ctx.simple:
        ctx.simple[ctx.seed] = SimpleSystems(ctx.seed)
    return ctx.simple[ctx.seed]


def _violates(margin: Margin, system: System) -> bool:
    """Whether ``system`` is a proven violation; a candidate whose check errors is not one."""
    try:
        value = margin(system)
    except CASE_ERRORS:
        return False
    return value is not None and value < 0


def shrink(margin: Margin, seed: int, tries: int = 12, fallback: Sequence[System] = (),
           candidates: SimpleSystems | None = None) -> System | None:
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
    candidates : SimpleSystems, optional
        The simple systems of ``seed`` and ``tries`` already drawn (an audit's, `simple_systems`);
        default: drawn afresh.

    Returns
    -------
    System or None

    Examples
    --------
    >>> found = shrink(lambda s: -1.0 if s.horizon >= 2 else 1.0, seed=0)   # violated once N >= 2
    >>> (found.n, found.m, found.horizon)            # sizes n + m + N = 3 hold; the first of size 4 is (1, 1, 2)
    (1, 1, 2)
    """
    for system in SimpleSystems(seed, tries) if candidates is None else candidates:
        if _violates(margin, system):
            return system
    bad = [s for s in fallback if _violates(margin, s)]
    return min(bad, key=lambda s: (s.n + s.m + s.horizon, s.n, s.m)) if bad else None


def evaluate(claim_id: str, ctx: Context, cases: Sequence[System], margin: Margin, note: str,
             shrinkable: bool = True) -> ClaimResult:
    """Run ``margin`` on every case and turn the outcomes into a verdict (`verdict`).

    Parameters
    ----------
    claim_id : str
        A key of `STATEMENTS`.
    ctx : Context
        Names the cases in the note (`Context.label`) and seeds the shrinking.
    cases : sequence of System
    margin : callable
        System -> margin (>= 0 holds, < 0 violated, None not applicable); may raise one of
        `CASE_ERRORS`, which counts the case as errored.
    note : str
        How the margin is defined, and what the check found.
    shrinkable : bool
        Whether to look for a small counterexample when a case violates.

    Returns
    -------
    ClaimResult

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> ctx = Context(paper={}, random=[s], seed=0)
    >>> r = evaluate("theorem-2", ctx, [s, s], lambda c: 0.5 if c is s else None, "")
    >>> r.verdict, r.checked, r.outcomes
    ('holds', 2, '++')
    >>> evaluate("theorem-2", ctx, [s], lambda c: -1.0, "", shrinkable=False).verdict
    'fails'
    """
    tally = Tally()
    for s in cases:
        tally.run(margin, s, ctx.label(s))
    counterexample = None
    if tally.violations and shrinkable:
        found = shrink(margin, ctx.seed, fallback=cases, candidates=simple_systems(ctx))
        counterexample = found.to_dict() if found is not None else None
    return tally.result(claim_id, STATEMENTS[claim_id], note, counterexample)


#: A Monte Carlo case needs the rarer outcome of every random channel entry this many times on
#: average, or the normal approximation behind the 4-standard-error margin does not hold
#: (mu = 1e-4 with 20000 samples sees 2 deliveries and "failed" 2 seeds of 3).
MIN_EXPECTED_OUTCOMES = 30


def enough_deliveries(system: System, samples: int) -> bool:
    """True when ``samples * min(mu, 1 - mu) >= MIN_EXPECTED_OUTCOMES`` for every channel entry with
    0 < mu < 1 (entries at 0 or 1 are deterministic)."""
    mu = system.mu_schedule
    random = (mu > 0) & (mu < 1)
    return bool(np.all(samples * np.minimum(mu, 1 - mu)[random] >= MIN_EXPECTED_OUTCOMES))


def cost_scale(system: System) -> float:
    """The size of ``system``'s costs: its largest weight (state, initial or input) times ``max|x0|^2 + N ||Sigma_W||``
    (what the state contributes, from x0 and from the noise over the horizon). Scaling the weights by c scales it by
    c, x0 (and Sigma_W by its square) by c scales it by c^2: a comparison floored at a fraction of it means the same
    at every scale. 0 only when nothing costs anything (x0 = 0 without noise). O(N n^3).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=2, state_weight=[3], input_weight=[1], mu=[0.5], x0=[2])
    >>> cost_scale(s), cost_scale(s.with_x0([0.5])), cost_scale(s.with_x0([0.0]))
    (12.0, 0.75, 0.0)
    """
    weight = max(float(np.linalg.eigvalsh(system.state_weights).max(initial=0.0)),
                 float(np.linalg.eigvalsh(system.initial_weight).max(initial=0.0)),
                 float(system.input_weights.max(initial=0.0)))
    x = float(np.abs(system.x0).max(initial=0.0))
    return weight * (x * x + system.horizon * float(np.linalg.norm(system.noise_cov, 2)))


def relative_error(value: float, reference: float, floor: float) -> float:
    """``|value - reference| / max(|reference|, floor)``: relative, with an absolute floor (a fraction of the problem's
    own scale, never a fixed number) where the reference is near zero; 0 for two exact zeros, inf for a difference
    against a zero scale.

    Examples
    --------
    >>> relative_error(1.5, 1.0, 1e-9), relative_error(0.25, 0.0, 0.5), relative_error(0.0, 0.0, 0.0)
    (0.5, 0.5, 0.0)
    """
    scale = max(abs(reference), floor)
    difference = abs(value - reference)
    if scale > 0:
        return difference / scale
    return 0.0 if difference == 0 else float("inf")


def resolved(value: float, what: str) -> float:
    """``value``, or NumericalError when it is nonzero and below ``RESOLVED_MIN`` (about 1e-292) in size: its
    rounding-level parts are subnormal, so a comparison of it decides nothing (the case is undecided, not a
    violation and not a pass).

    Examples
    --------
    >>> resolved(1e-200, "the cost"), resolved(0.0, "the cost")
    (1e-200, 0.0)
    >>> resolved(3e-300, "the cost")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.NumericalError: the cost is 3e-300, within 2^52 of double precision's subnormal range ...
    """
    if 0 < abs(value) < RESOLVED_MIN:
        raise NumericalError(f"{what} is {value:.3g}, within 2^52 of double precision's subnormal range (below "
                             f"{RESOLVED_MIN:.1e}): the computation lost digits at this scale, so the case is "
                             "undecided")
    return value


def z_margin(samples: np.ndarray, expect: float) -> float:
    """Z - |z| of the sample mean against ``expect``; a degenerate sample must match to 1e-9 relative. Computed on the
    samples divided by their scale ``max(|expect|, max|samples|)`` rounded to a power of two (exact: the same floats
    as unscaled), so the margin is the same at every scale and the standard deviation's squares do not underflow; a
    scale below ``RESOLVED_MIN`` raises NumericalError (`resolved`).

    Examples
    --------
    >>> [float(z_margin(np.array([0.0, 2.0]), e)) for e in (1.0, 3.0)]   # mean 1, standard error 1
    [4.0, 2.0]
    >>> [float(z_margin(np.array([1.0, 1.0]), e)) for e in (1.0, 1.1)]   # degenerate: exact or -inf
    [4.0, -inf]
    >>> tiny = 2.0 ** -660                        # about 2e-199: its square underflows to 0.0, the margin does not
    >>> float(z_margin(np.array([0.0, 2 * tiny]), 3 * tiny)), float(z_margin(np.array([0.0, 2.0]), 3.0))
    (2.0, 2.0)
    """
    scale = resolved(max(abs(float(expect)), float(np.abs(samples).max(initial=0.0))), "the sampled quantity's scale")
    if scale == 0:
        return Z                                   # every sample and the expectation are exactly zero
    exponent = int(np.frexp(scale)[1])            # divided by a power of two: exact, the same z as unscaled
    x, e = np.ldexp(samples, -exponent), float(np.ldexp(expect, -exponent))
    se = x.std(ddof=1) / np.sqrt(x.size)
    err = abs(x.mean() - e)
    if se <= 1e-12:
        return Z if err <= 1e-9 else -np.inf
    return Z - err / se
