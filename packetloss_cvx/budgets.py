"""Work budgets: every count and size a caller can type, bounded before any work starts.

Each :class:`Budget` names what it counts, its default and what that default costs on the reference
machine (docs/design.md §4, "Work budgets", is the one place they are documented). A request beyond a
budget raises :class:`~packetloss_cvx.errors.BudgetError` (a ResourceError and an InputError: the command
line exits 2 with one line naming the option, the work asked for, the budget and how to raise it) before
any array is allocated. The one way to raise a budget on purpose is its environment variable,
``PACKETLOSS_CVX_BUDGET_<NAME>`` (a positive number, or ``inf`` for no bound), read when the check runs,
so it works the same for the command line and the API.

The work formulas (:func:`simulate_work`, :func:`sweep_work`, :func:`burstiness_work`) live here once;
the API and the command line's preflight both call them. Imports nothing numerical.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass

from .errors import BudgetError, InputError

__all__ = ["BUDGETS", "ENV_PREFIX", "Budget", "burstiness_work", "check", "count_text", "duration_text",
           "estimated_seconds", "limit", "markov_recursion_work", "simulate_work", "sweep_work"]

#: Prefix of the environment variable that raises a budget: ``PACKETLOSS_CVX_BUDGET_SIMULATE_WORK=1e12``.
ENV_PREFIX = "PACKETLOSS_CVX_BUDGET_"


@dataclass(frozen=True)
class Budget:
    """One budget: its ``name`` (the environment variable's suffix), ``default``, the ``unit`` it counts
    and what the default ``costs`` (measured on the reference machine, one BLAS thread; the measurements
    behind each are in docs/design.md §4, "Work budgets")."""

    name: str
    default: float
    unit: str
    costs: str
    seconds_per_unit: float = 0.0     # measured, where the unit is work (0: not a work budget)

    @property
    def env(self) -> str:
        """The environment variable that raises it: ``PACKETLOSS_CVX_BUDGET_<NAME>``."""
        return ENV_PREFIX + self.name.upper()


BUDGETS: dict[str, Budget] = {b.name: b for b in (
    Budget("file_bytes", 16 * 2**20, "bytes of an input file", "a system file is a few kB"),
    Budget("simulate_work", 5e10, "work units of a Monte Carlo (simulate_work)", "about 10 min", 1.2e-8),
    Budget("sweep_points", 1e6, "points of a sweep", "about 10 s of a 2x2 system"),
    Budget("sweep_work", 3e10, "work units of a sweep (sweep_work, burstiness_work)", "about 12 min", 2.5e-8),
    Budget("audit_cases", 1e4, "random systems of an audit", "about 5 min"),
    Budget("dask_workers", 32, "local Dask workers", "about 5 GB"),
    Budget("allocation_boxes", 1e6, "boxes of the branch and bound", "about 15 min"),
    Budget("region_points", 1.2e5, "law-points of a stability-region map (grid^2 x laws)", "about 10 min", 5.2e-3),
    Budget("markov_recursion_work", 5e12, "work units of one exact Markov recursion (markov_recursion_work)",
           "about 10 min", 1.2e-10),
)}


def limit(name: str) -> float:
    """The budget ``name`` now: its environment variable if set (a positive number or ``inf``), else its default.

    Raises
    ------
    InputError
        An environment variable that is not a positive number (named by the variable).

    Examples
    --------
    >>> limit("sweep_points")
    1000000.0
    >>> os.environ["PACKETLOSS_CVX_BUDGET_SWEEP_POINTS"] = "4e6"
    >>> limit("sweep_points")
    4000000.0
    >>> del os.environ["PACKETLOSS_CVX_BUDGET_SWEEP_POINTS"]
    """
    budget = BUDGETS[name]
    text = os.environ.get(budget.env)
    if text is None or not text.strip():
        return float(budget.default)
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not value > 0:       # NaN too
        raise InputError(budget.env, f"expected a positive number (or inf), found {text[:40]!r}")
    return value


def check(name: str, needed: float, field: str, what: str) -> None:
    """Refuse ``needed`` (in the budget's unit) beyond the budget ``name``, naming ``field``. O(1).

    Raises
    ------
    BudgetError
        With the work asked for, the budget, what the default costs and the variable that raises it.

    Examples
    --------
    >>> check("audit_cases", 50, "--random", "50 random systems")                    # within: silent
    >>> check("audit_cases", 10**12, "--random", "1e12 random systems")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.BudgetError: --random: 1e12 random systems is over the budget of 1e+04 random systems \
of an audit (about 5 min); to run it on purpose set PACKETLOSS_CVX_BUDGET_AUDIT_CASES=1e+12
    """
    bound = limit(name)
    needed = _float(needed)
    if needed <= bound:
        return
    budget = BUDGETS[name]
    shown = _rounded_up(needed) if math.isfinite(needed) else "inf"
    raise BudgetError(field, f"{what} is over the budget of {bound:.3g} {budget.unit} ({budget.costs}); "
                             f"to run it on purpose set {budget.env}={shown}", needed, bound, budget.env)


def count_text(value: int | float) -> str:
    """A count as an error line shows it: as typed up to 15 digits, else by its size (an integer of 400 digits
    is not echoed). O(digits).

    Examples
    --------
    >>> count_text(1_000_000), count_text(10 ** 400), count_text(2.5e20)
    ('1000000', 'a 401-digit number', '2.5e+20')
    """
    if isinstance(value, int) and abs(value) >= 10 ** 15:
        return f"a {len(str(abs(value)))}-digit number"
    return str(value) if isinstance(value, int) else f"{value:.3g}"


def duration_text(seconds: float) -> str:
    """An estimated time as an error line shows it: seconds below a minute, else minutes, else hours. O(1).

    Examples
    --------
    >>> duration_text(0.384), duration_text(150.0), duration_text(7200.0)
    ('0.38 s', '2.5 min', '2 h')
    """
    if seconds < 60:
        return f"{seconds:.2g} s"
    return f"{seconds / 60:.2g} min" if seconds < 3600 else f"{seconds / 3600:.2g} h"


def _float(value: float) -> float:
    """``float(value)``; an integer beyond the double range is infinite work, not an OverflowError."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def estimated_seconds(name: str, work: float) -> float:
    """The time ``work`` units of the work budget ``name`` take on the reference machine (one BLAS thread),
    from the measured seconds per unit (0 for a budget that does not count work). O(1).

    Examples
    --------
    >>> round(estimated_seconds("sweep_work", 3e10) / 60, 1)         # the default sweep budget, in minutes
    12.5
    """
    return work * BUDGETS[name].seconds_per_unit


def simulate_work(samples: int, steps: int, horizon: int, n: int, m: int, plans: int, laws: int) -> float:
    """Work units of a Monte Carlo: ``samples (N plans + T laws) n (n + m)`` (``laws`` 0 for the open loop).

    Examples
    --------
    >>> simulate_work(10_000, 50, 10, 2, 2, plans=2, laws=0)        # simulate two_actuator (open loop)
    1600000.0
    >>> simulate_work(10 ** 400, 50, 10, 2, 2, plans=2, laws=0)     # beyond the double range: unbounded
    inf
    """
    return _float(samples) * (float(horizon) * plans + _float(steps) * laws) * n * (n + m)


def sweep_work(horizons: Iterable[int], n: int, m: int, protocols: int, stability: bool = False,
               chunk: int = 2048) -> float:
    """Work units of a sweep (2.5e-8 s each, within a factor 3 on the measured cases): per protocol, every point's N steps of the batched
    recursion at ``n^3 + m^3 + 40`` each, plus 1000 for each step of each batch (a chunk of ``chunk``
    points of one horizon: the per-step overhead of NumPy calls, which dominates a sweep over long horizons);
    with ``stability`` also ``n^3 min(n^3, 1000)`` per point (Kronecker eigenvalues for small n, Arnoldi
    beyond). O(number of points).

    Examples
    --------
    >>> sweep_work([10] * 40_000, 2, 2, protocols=2)      # a 200 x 200 grid: 1.1 s predicted, 0.40 s measured
    45200000.0
    >>> sweep_work([10_000] * 200, 2, 2, protocols=2)     # 200 equal horizons: 6.1 s predicted, 5.6 s measured
    244000000.0
    >>> sweep_work(range(10_000, 10_200), 2, 2, protocols=2)   # 200 different ones: 107 s predicted, 105 s measured
    4266028800.0
    """
    counts: dict[int, int] = {}
    for N in horizons:
        counts[int(N)] = counts.get(int(N), 0) + 1
    points = sum(counts.values())
    steps = sum(N * c for N, c in counts.items())
    batch_steps = sum(N * -(-c // chunk) for N, c in counts.items())
    work = protocols * (float(steps) * (n ** 3 + m ** 3 + 40) + 1000.0 * batch_steps)
    if stability:
        work += points * protocols * float(n) ** 3 * min(float(n) ** 3, 1000.0)
    return work


def burstiness_work(values: int, horizon: int, m: int, protocols: int = 2, *, n: int, states: int | None = None
                    ) -> float:
    """Work units of a burstiness sweep or map: per value (grid point), protocol and step one step of the exact
    minimum's augmented recursion and of the referee on its state of size D = n (1 + ``states``), ``2 D^3``, plus
    2500 for the per-step Python work (measured: 148 us a step and value for pendulum_bursty's twin, D = 8, both
    protocols; this formula says 176). ``states`` is sum_i (k_i - 1) over the channels' chains (default ``m``:
    two-state chains). ``n`` is keyword-only: a call written for the older formula (values, N, m) fails loudly
    rather than count with the wrong sizes. O(1).

    Examples
    --------
    >>> burstiness_work(20, 80, 1, n=4)   # pendulum_bursty, 20 values: measured 0.21 s, predicted 0.28 s
    11276800.0
    >>> burstiness_work(20, 80, 2, n=2, states=1)   # one two-state chain beside an i.i.d. channel: D = 4
    8409600.0
    """
    D = float(n) * (1 + (m if states is None else states))
    return _float(values) * protocols * float(horizon) * (2.0 * D ** 3 + 2500.0)


def markov_recursion_work(horizon: int, size: int) -> float:
    """Work units of one exact UDP-like minimum under Markov losses by the augmented recursion
    (markov/augmented.py): per step ``D^3`` for the Riccati step on the augmented state of size D (its products
    and solve), plus 6e5 for the step's Python and small-matrix work; 1.2e-10 s a unit (benchmarks/markov_auto.py
    --fit: D from 2 to 200, N from 10 to 640). The budget check of :func:`~packetloss_cvx.markov.exact_closed_form`
    and its ``method="auto"`` chooser both read it. O(1).

    Examples
    --------
    >>> markov_recursion_work(80, 8)       # pendulum_bursty: 48 ms predicted
    48040960.0
    >>> work = markov_recursion_work(100, 800)      # a 200-state chain behind a plant of n = 4, N = 100
    >>> round(estimated_seconds("markov_recursion_work", work), 1)      # measured: 5 s
    6.2
    """
    return _float(horizon) * (float(size) ** 3 + 6e5)


def _rounded_up(value: float) -> str:
    """``value`` shown with three significant digits, rounded up (a budget set to it admits the request).

    >>> _rounded_up(16777217), _rounded_up(2e7), _rounded_up(0.5)
    ('1.68e+07', '2e+07', '0.5')
    """
    if value <= 0:
        return "0"
    step = 10.0 ** (math.floor(math.log10(value)) - 2)
    up = math.ceil(value / step - 1e-9) * step
    return f"{up:.3g}" if float(f"{up:.3g}") >= value else f"{up * 1.001:.3g}"
