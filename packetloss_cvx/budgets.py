"""Work budgets: every count and size a caller can type, bounded before any work starts.

Each `Budget` names what it counts, its default and what that default costs on the reference
machine (docs/design.md §4, "Work budgets", is the one place they are documented). A request beyond a
budget raises [`BudgetError`][packetloss_cvx.errors.BudgetError] (a ResourceError and an InputError: the command
line exits 2 with one line naming the option, the work asked for, the budget and how to raise it) before
any array is allocated. The one way to raise a budget on purpose is its environment variable,
``PACKETLOSS_CVX_BUDGET_<NAME>`` (a positive number, or ``inf`` for no bound), read when the check runs,
so it works the same for the command line and the API.

The work formulas (`simulate_work`, `sweep_work`, `burstiness_work`, `solve_work`,
`qp_work`, `markov_recursion_work`, `markov_dense_seconds`, `udp_box_work`) and the memory
formulas (`solve_bytes`, `dense_bytes`, `markov_dense_bytes`, `qp_bytes`,
`operator_bytes`, `krylov_bytes`, `loop_bytes`, `mpc_bytes`, `constraint_bytes`, checked against the
``memory_bytes`` budget; `program_bytes`, what a cache is charged) live here once; the API and the command
line's preflight both call them. Every refusal is one line made by `refusal_text` (what was asked, the budget, what
to use instead, the variable and the value that admits it): raised by `check` before any work as a BudgetError (a
ValueError: the command line exits 2), and for the one count known only as the work runs, the beliefs a
receding-horizon law plans at (``belief_plans``), as a plain ResourceError when met, offering the most the run can
meet. Imports nothing
numerical.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass

from .errors import BudgetError, InputError
from .tolerances import MEMORY_BUDGET_BYTES

__all__ = ["BUDGETS", "CHAIN_BYTES_N3", "CHAIN_COMPILE_N3", "CHAIN_RESOLVE_N4", "CLIPPED_SOLVE_SHARE", "ENV_PREFIX",
           "MARKOV_DENSE_SECONDS", "OVERRIDE_REACH", "PROGRAM_BYTES_PER_ENTRY", "Budget", "burstiness_work",
           "chain_states", "check", "check_constrained", "constrained_bytes", "constrained_work", "constraint_bytes",
           "count_text", "dense_bytes", "duration_text", "estimated_seconds", "gib_text", "krylov_bytes", "limit",
           "loop_bytes", "markov_dense_bytes", "markov_dense_seconds", "markov_recursion_work", "mpc_bytes",
           "mpc_loop_solves", "mpc_solve_size", "mpc_solves", "operator_bytes", "program_bytes", "qp_bytes",
           "qp_work", "refusal_text", "simulate_work", "solve_bytes", "solve_work", "sweep_work", "udp_box_work"]

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
    Budget("solve_work", 6e7, "work units of one solve (solve_work)", "about 1 min", 1e-6),
    Budget("allocation_work", 9e8, "work units of a UDP-like branch and bound (boxes x udp_box_work)", "about 15 min",
           1e-6),
    Budget("memory_bytes", MEMORY_BUDGET_BYTES, "bytes of memory for one computation of a size the caller gave",
           "a quarter of this machine's memory"),
    Budget("chain_dp_nodes", 2e5, "node-outcomes of the TCP-like DP behind a chain (beliefs x outcomes, summed "
           "over the steps)", "about 3 s at n = 4 (8.2 s measured at 5.2e5): `solve` on a chain file computes it by "
           "default, so a hidden chain beyond it gets labelled bounds in seconds"),
    Budget("mpc_solves", 2e5, "solves of 5 ms of the constrained receding-horizon loop's programs (runs x steps x "
           "programs, each solve weighed by its program's size: mpc_solve_size)", "about 17 min", 5e-3),
    Budget("actuator_rows", 25000, "rows of an actuator strategy's second-moment operator behind its optimal law "
           "(engine modes x N^2: information modes x delivery patterns x (n + m (L - 1))^2 for buffer:L)",
           "about 2 s (two_actuator: buffer:6, 20736 rows, 2.0 s; buffer:7, 38416 rows, 23 s, its mean-square radius "
           "by ARPACK on a loaded 2-core machine)"),
    Budget("operator_rows", 2048, "rows of a dense second-moment operator (modes x n^2)",
           "64 MiB and a few seconds for its eigenvalues"),
    Budget("belief_plans", 2000, "distinct beliefs one receding-horizon law plans at in a simulation (a plan each)",
           "about 3 s at pendulum_bursty's N = 80, 1.2-1.8 ms a plan"),
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


#: an override of a budget is offered only up to this factor beyond it where the work grows exponentially (the chain
#: DP's 2^t beliefs): 2.42e24 node-outcomes at 2e5 a few seconds would take ~1e12 years
OVERRIDE_REACH = 100.0


def check(name: str, needed: float, field: str, what: str, instead: str = "", reach: float = math.inf) -> None:
    """Refuse ``needed`` (in the budget's unit) beyond the budget ``name``, naming ``field``; ``instead``, what to
    use instead (a cheaper method, a smaller size), goes before the variable that raises the budget. The one shape
    of every refusal: ``field: what is over the budget of B unit (costs); instead, or to run it on purpose set
    VARIABLE=needed``. Where ``needed`` is more than ``reach`` times the budget (work that grows exponentially, whose
    override could not finish: `OVERRIDE_REACH`), no variable is offered: ``field: what is N times the budget of
    B unit (costs): out of reach; instead``. O(1).

    Raises
    ------
    BudgetError
        With the work asked for, the budget, what the default costs, what to use instead and the variable that
        raises it.

    Examples
    --------
    >>> check("audit_cases", 50, "--random", "50 random systems")                    # within: silent
    >>> check("audit_cases", 10**12, "--random", "1e12 random systems")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.BudgetError: --random: 1e12 random systems is over the budget of 1e+04 random systems \
of an audit (about 5 min); to run it on purpose set PACKETLOSS_CVX_BUDGET_AUDIT_CASES=1e+12
    >>> check("audit_cases", 10**5, "--random", "1e5 random systems", instead="use --random 1000")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.BudgetError: --random: 1e5 random systems is over the budget of 1e+04 random systems \
of an audit (about 5 min); use --random 1000, or to run it on purpose set PACKETLOSS_CVX_BUDGET_AUDIT_CASES=1e+05
    >>> check("chain_dp_nodes", 2.42e24, "horizon", "the DP", instead="use the bounds", reach=OVERRIDE_REACH)
    ... # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.BudgetError: horizon: the DP is 1.2e+19 times the budget of 2e+05 node-outcomes ... \
out of reach (no override of the budget could finish it); use the bounds
    """
    bound = limit(name)
    needed = _float(needed)
    if needed <= bound:
        return
    budget = BUDGETS[name]
    raise BudgetError(field, refusal_text(name, needed, bound, what, instead, reach), needed, bound, budget.env)


def refusal_text(name: str, needed: float, bound: float, what: str, instead: str = "",
                 reach: float = math.inf) -> str:
    """The one refusal line of every budget (after the field): ``needed`` units of the budget ``name`` over
    ``bound`` (its value now, or a caller's own cap): what was asked, the budget, what its default costs, what to use
    ``instead`` and the variable with the value that admits the request (none beyond ``reach`` times the bound).
    `check` raises it as a BudgetError before any work; a limit met while the work runs (the beliefs a
    receding-horizon law plans at, ``belief_plans``) raises it as a plain ResourceError, ``needed`` then the most
    the run can need. O(1).

    Examples
    --------
    >>> print(refusal_text("belief_plans", 6000, 2000, "a plan at each of up to 6000 beliefs"))
    a plan at each of up to 6000 beliefs is over the budget of 2e+03 distinct beliefs one receding-horizon law plans \
at in a simulation (a plan each) (about 3 s at pendulum_bursty's N = 80, 1.2-1.8 ms a plan); to run it on purpose \
set PACKETLOSS_CVX_BUDGET_BELIEF_PLANS=6e+03
    """
    budget = BUDGETS[name]
    needed = _float(needed)
    if needed > reach * bound:
        return (f"{what} is {needed / bound:.2g} times the budget of {bound:.3g} {budget.unit} ({budget.costs}): out "
                f"of reach (no override of the budget could finish it)" + (f"; {instead}" if instead else ""))
    shown = _rounded_up(needed) if math.isfinite(needed) else "inf"
    way = f"{instead}, or " if instead else ""
    return (f"{what} is over the budget of {bound:.3g} {budget.unit} ({budget.costs}); {way}to run it on purpose set "
            f"{budget.env}={shown}")


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


def gib_text(size: float) -> str:
    """Bytes as an error line shows them: GiB to three digits. O(1).

    Examples
    --------
    >>> gib_text(2 ** 30), gib_text(3.15e8)
    ('1 GiB', '0.293 GiB')
    """
    return f"{size / 2 ** 30:.3g} GiB"


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


#: What a run-step of the clipped law costs in the constrained loop, in program solves: 9.5 us (two_actuator, chunks of
#: 8 runs, one BLAS thread: 9.9 us at 800 x 100, 9.2 at 1600 x 200) beside the budget's 5 ms a solve.
CLIPPED_SOLVE_SHARE = 2e-3


#: A chance row exact under a Markov chain (qp/constrained.py: its N cones hold per channel the innovations' terms of
#: the deliveries' covariance, `delivery_factor`) beyond the plug-in row's price, with K the chain's most states per
#: channel (the first state's responses are zero, so a Gilbert channel adds one term): cvxpy's compile of the cones,
#: ``CHAIN_COMPILE_N3 m^2 (K - 1) N^3`` us; Clarabel's factorisations of a KKT system whose cone rows each reach up to
#: N inputs (the plug-in row's reach one), ``CHAIN_RESOLVE_N4 m^2 (K - 1) N^4`` us a solve; cvxpy's parameter maps of
#: the cones, ``(K - 1) N^3 (115 m^2 + 50 n)`` bytes (`CHAIN_BYTES_N3`). Fitted (least squares on the log of measured
#: over predicted; benchmarks/chain_chance_budget.py) on the exact program less its plug-in twin, one chance row and
#: an input box, ``ConstrainedQP(..., u_prev=True)`` in a fresh process, one BLAS thread, CPU time: N in 50..200, a
#: scalar plant behind a Gilbert channel (K = 2) and a 3-state chain (K = 3), n = m = 2 behind two Gilbert channels,
#: pendulum_bursty (n = 4) up to N = 100; the cases and the ratios are in `constrained_work`, `constrained_bytes` and
#: `mpc_solve_size`.
CHAIN_COMPILE_N3 = 0.56
CHAIN_RESOLVE_N4 = 3.2e-3
CHAIN_BYTES_N3 = (115.0, 50.0)


def chain_states(channel: object) -> int:
    """The states per channel that price a program's chance rows behind ``channel``: a Markov channel's largest
    ``sizes`` (the width of its innovations in qp/constrained.py), 0 for Bernoulli losses (``None``): the ``states``
    argument of `constrained_work`, `constrained_bytes`, `mpc_solve_size` and `check_constrained`. O(m).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> chain_states(None), chain_states(SimpleNamespace(sizes=(2, 3)))
    (0, 3)
    """
    return 0 if channel is None else max(channel.sizes)


def _chained(states: int) -> float:
    """The chain's factor of a chance row's price beyond the plug-in row's, ``K - 1`` for ``states`` = K (0 below 2:
    Bernoulli losses)."""
    return float(max(int(states) - 1, 0))


def mpc_solve_size(horizon: int, n: int, m: int, rows: int, chance: int = 0, states: int = 0) -> float:
    """One solve of the constrained loop's program (``ConstrainedQP.solve`` from a new state: Clarabel on the compiled
    program and the solution's checks) in the ``mpc_solves`` budget's unit, solves of 5 ms: ``(1600 + 0.75 N (n +
    m)^2 + 0.055 N^2 n m + 3.5 rows + 0.6 chance N^2 (n + m)) us / 5 ms``, ``rows`` the program's linear rows
    (`Constraints.program_rows`), ``chance`` its chance rows. The terms: a fixed cost, the sparse KKT system's banded
    factorisation, the checks' dense products with the plan's moment maps, the rows, each chance row's N cones.
    Fitted (least squares on the relative error) on benchmarks/mpc_solve_time.py (section 22 of benchmarks/run.py:
    N in 10..200, (n, m) in (2, 1), (4, 2), (8, 3), an input box, with a rate bound, state limits or one chance row,
    one BLAS thread, CPU time): the measured solve 0.59 to 1.8 times this on all 59 cases, median 0.89 (1.1 ms at
    N = 10, n = 2, m = 1 to 100 ms at N = 200, n = 8, m = 3, 4400 rows; the largest ratios where the condensed form
    carries state limits, 1.1 and 1.3 with a chance row at N = 200), Clarabel's linear solver pinned to QDLDL
    (tolerances.CLARABEL_LINEAR_SOLVER; its own default, "auto", took 10 and 21 times this there).

    Behind a Markov chain of ``states`` = K states per channel (`chain_states`; 0 for Bernoulli losses) each chance
    row is exact under the chain and costs ``3.2e-3 m^2 (K - 1) N^4`` us more (`CHAIN_RESOLVE_N4`: Clarabel's
    factorisations, each cone row reaching up to N inputs), priced at a solve from a new belief (a TCP-like
    controller filters its belief every step). Measured re-solves (new x0 and belief) against this: a scalar plant
    behind a Gilbert channel, N = 50 / 100 / 200, 27 ms / 0.21 s / 5.3 s (predicted 25 ms / 0.34 s / 5.2 s; the
    plug-in row's 6 ms / 18 ms / 75 ms); a 3-state chain, N = 100, 0.30 s (0.66 s); n = m = 2 behind two Gilbert
    channels, N = 100 / 200, 0.45 s / 12 s (1.3 s / 21 s); pendulum_bursty, whose chance row binds at most steps,
    N = 60 / 80 / 100, 0.18 s / 0.77 s / 1.2 s (56 ms / 0.16 s / 0.36 s; its plug-in solves, 44 ms / 85 ms / 0.16 s,
    are 3 to 4.4 times the plug-in formula too): 0.34 to 5.0 times this, median 0.84. O(1).

    Examples
    --------
    >>> round(mpc_solve_size(10, 2, 1, 20), 4)      # 1600 + 67.5 + 11 + 70 = 1748.5 us: 0.35 of a 5 ms solve
    0.3497
    >>> round(mpc_solve_size(200, 8, 3, 4400), 2)   # 88 ms predicted, 101 ms measured
    17.59
    >>> # behind a Gilbert channel: 1600 + 300 + 550 + 700 + 12000 + 3.2e-3 1e8 = 335150 us (0.21 s measured)
    >>> round(mpc_solve_size(100, 1, 1, 200, 1, states=2), 2)
    67.03
    """
    N = _float(horizon)
    micro = (1600.0 + 0.75 * N * (n + m) ** 2 + 0.055 * N * N * n * m + 3.5 * _float(rows)
             + 0.6 * chance * N * N * (n + m) + chance * _chained(states) * m * m * CHAIN_RESOLVE_N4 * N ** 4)
    return micro * 1e-6 / BUDGETS["mpc_solves"].seconds_per_unit


def mpc_solves(samples: int, steps: int, programs: int, clipped: int = 0, size: float = 1.0) -> float:
    """Program solves of the constrained loop, in solves of 5 ms: ``samples steps (programs size +
    CLIPPED_SOLVE_SHARE clipped)`` (a controller with a program solves it once per run and step, ``size`` the
    solve's weight, `mpc_solve_size`; the soft twin's solves, on infeasible steps only, come on top; the ``clipped``
    laws' run-steps, which solve nothing, priced at their measured share of a 5 ms solve).

    Examples
    --------
    >>> mpc_solves(100, 30, 3)
    9000.0
    >>> round(mpc_solves(100, 30, 3, size=mpc_solve_size(10, 2, 1, 20)), 1)
    3147.3
    >>> mpc_solves(10 ** 9, 30, 0, clipped=1)          # the clipped law alone: 3e10 run-steps, 80 h
    60000000.0
    """
    return _float(samples) * _float(steps) * (programs * size + CLIPPED_SOLVE_SHARE * clipped)


def mpc_loop_solves(samples: int, steps: int, programs: int, clipped: int, exact: int, horizon: int, n: int, m: int,
                    rows: int, chance: int = 0, states: int = 0) -> tuple[float, str]:
    """`mpc_solves` of a constrained loop whose ``programs`` include ``exact`` ones with their chance rows exact
    under a chain of ``states`` states per channel (`chain_states`; priced by `mpc_solve_size` with ``states``, the
    others without), and how they were priced, as the refusal says it: ``"<price>: N = .., n = .., m = .., R linear
    rows, C chance rows"``. The one pricing of the simulate command's preflight and the loop's own check. O(1).

    Examples
    --------
    >>> units, how = mpc_loop_solves(100, 30, 3, 0, 0, 10, 2, 1, 20)
    >>> round(units, 1), how
    (3147.3, '0.35 of a 5 ms solve each: N = 10, n = 2, m = 1, 20 linear rows, 0 chance rows')
    """
    size = mpc_solve_size(horizon, n, m, rows, chance)
    chained = mpc_solve_size(horizon, n, m, rows, chance, states)
    priced = (f"{exact} with the rows exact under the {states}-state chain at {chained:.2g} of a 5 ms solve each, "
              f"the others at {size:.2g}" if exact else f"{size:.2g} of a 5 ms solve each")
    units = mpc_solves(samples, steps, programs - exact, clipped, size) + mpc_solves(samples, steps, exact, 0, chained)
    return units, (f"{priced}: N = {horizon}, n = {n}, m = {m}, {rows} linear rows, {chance} chance row"
                   + "s" * (chance != 1))


def mpc_bytes(samples: int, steps: int, n: int, m: int, jobs: int, rows: int, keep: int = 0) -> float:
    """Bytes of the constrained loop's arrays (montecarlo/mpc.py): the paths as drawn per block and joined
    (deliveries a byte an entry, noise 8 n), ``2 samples steps (m + 8 n)``; per job (controller and protocol) its
    stage costs, violation flags of ``rows`` rows and infeasibility flags, in chunks and joined, ``2 samples steps
    (9 + rows)``; the ``keep`` kept runs' states and commands, ``16 jobs keep (steps + 1) (n + m)``. O(1).

    Examples
    --------
    >>> round(mpc_bytes(10 ** 9, 30, 1, 1, 2, 2) / 2 ** 40, 2)      # a billion runs of the clipped law: TiB
    1.69
    """
    S, T = _float(samples), _float(steps)
    return (2.0 * S * T * (m + 8.0 * n) + 2.0 * jobs * S * T * (9.0 + rows)
            + 16.0 * jobs * _float(keep) * (T + 1.0) * (n + m))


def sweep_work(horizons: Iterable[int], n: int, m: int, protocols: int, stability: bool = False,
               chunk: int = 2048) -> float:
    """Work units of a sweep (2.5e-8 s each, within a factor 3 on the measured cases): per protocol, every point's N
    steps of the batched recursion at ``n^3 + m^3 + 40`` each, plus 1000 for each step of each batch (a chunk of
    ``chunk`` points of one horizon: the per-step overhead of NumPy calls, which dominates a sweep over long horizons);
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


#: The Markov dense route's time model (:func:`markov_dense_seconds`), seconds ``(a, b, c)``.
MARKOV_DENSE_SECONDS = (6e-4, 3.0e-10, 2.0e-11)


def markov_dense_seconds(horizon: int, n: int, m: int) -> float:
    """Seconds (one BLAS thread) of the exact UDP-like minimum under Markov losses by the dense route
    (lq/markov_cost.py), ``a + b (N m)^3 + c (N n)^2 N m`` (the (N m)^3 solve and the (N n)^2 N m products of
    Omega_g) with (a, b, c) = `MARKOV_DENSE_SECONDS`. benchmarks/markov_auto.py: its least-squares fit is
    (1.0e-3, 2.1e-10, 2.7e-11); these values, rounded toward the small-N times the fit overstates, make ``auto`` take
    the faster route in 75 of its 77 cases, the other two within 14 % (docs/performance.md). O(1).

    Examples
    --------
    >>> round(1e3 * markov_dense_seconds(400, 1, 1), 1)          # ms: about the crossover for m = n = 1
    21.1
    """
    N = horizon
    a, b, c = MARKOV_DENSE_SECONDS
    return a + b * float(N * m) ** 3 + c * float(N * n) ** 2 * (N * m)


def markov_recursion_work(horizon: int, size: int) -> float:
    """Work units of one exact UDP-like minimum under Markov losses by the augmented recursion (lq/augmented.py), an
    upper bound: every one of the N steps priced as a full step, ``D^3`` for the Riccati step on the augmented state
    of size D (its products and solve) plus 6e5 for the step's Python and small-matrix work; 1.2e-10 s a unit
    (benchmarks/markov_auto.py --fit: D from 2 to 200, N from 10 to 640, horizons whose passes ran every step).

    Why an upper bound and not the work done: where A is stable and the chains reach their float fixed point at a
    step s, the pass closes its stationary tail after s + L full steps and rolls the rest out by powers (O(N D^2),
    far below a step's D^3 + 6e5), but L, the steps until the cost-to-go settles to ``STATIONARY_RTOL``, is known
    only once the pass has run; a bound that guessed it could admit work that then runs every step. So the budget
    is checked on N full steps, which no run exceeds, and a refused recursion whose tail would settle runs on
    purpose with the variable (benchmarks/markov_tail.py, run.py section 21: stable chains at N = 8000, D = 6 to 9,
    take 21-69 ms where N full steps are priced at 0.58 s). The budget check of
    [`exact_closed_form`][packetloss_cvx.lq.markov_cost.exact_closed_form] and its ``method="auto"`` chooser both
    read it. O(1).

    Examples
    --------
    >>> markov_recursion_work(80, 8)       # pendulum_bursty: 48 ms predicted
    48040960.0
    >>> work = markov_recursion_work(100, 800)      # a 200-state chain behind a plant of n = 4, N = 100
    >>> round(estimated_seconds("markov_recursion_work", work), 1)      # measured: 5 s
    6.2
    """
    return _float(horizon) * (float(size) ** 3 + 6e5)


def qp_work(horizon: int, n: int, m: int, formulation: str = "sparse") -> float:
    """Work units (1e-6 s each) of one protocol's QP cross-check (qp/: cvxpy's compile and Clarabel's solve),
    per step ``28 + 1.1 n^2 + 1.5 n m``, and for the condensed form also its dense factorisation ``1.3e-3 (N m)^3``.
    Fitted on ``solve`` with the cross-check, one BLAS thread (both protocols): n = m = 1, N = 2e5 12.5 s
    (predicted 12.2), N = 5e5 30.5 s (30.6); n = 4, m = 2, N = 4e4 5.3 s (4.6); n = 10, m = 3, N = 2e4 8.3 s (7.3);
    n = 30, m = 5, N = 2000 4.7 s (5.0); condensed n = m = 1, N = 2000 21 s (21). ``formulation`` "auto" is
    priced as the sparse form (auto takes the condensed form only for N m <= 60, where both cost milliseconds). O(1).

    Examples
    --------
    >>> qp_work(10 ** 6, 1, 1)                          # a scalar plant over a million steps: about 31 s
    30600000.0
    """
    work = _float(horizon) * (28.0 + 1.1 * n * n + 1.5 * n * m)
    if formulation == "condensed":
        work += 1.3e-3 * (_float(horizon) * m) ** 3
    return work


def solve_work(horizon: int, n: int, m: int, protocols: int = 2, qp: str | None = "sparse") -> float:
    """Work units (1e-6 s each) of ``solve``: per protocol the closed form, ``N (0.45 + 0.0175 n^2)`` (the recursion,
    its plan and gain, the JSON of the plan), and unless ``qp`` is None the QP cross-check (`qp_work`, ``qp``
    its formulation). Measured with ``--no-qp`` (both protocols, one BLAS thread, less the 0.3 s start): n = m = 1,
    N = 1e6 0.94 s (predicted 0.94); n = 4, m = 2, N = 5e5 0.68 s (0.73); n = 10, m = 3, N = 2e5 0.87 s (0.88);
    n = 30, m = 5, N = 5e4 1.8 s (1.6). O(1).

    Examples
    --------
    >>> solve_work(10 ** 6, 1, 1)                       # the cross-check is 60 times the closed forms
    62135000.0
    >>> solve_work(10 ** 6, 1, 1, qp=None)
    935000.0
    """
    closed = _float(horizon) * (0.45 + 0.0175 * n * n)
    return protocols * (closed + (0.0 if qp is None else qp_work(horizon, n, m, qp)))


def solve_bytes(horizon: int, n: int, m: int, qp: str | None = "sparse") -> float:
    """Peak bytes of ``solve`` beyond the interpreter's own: per step ``260 + 15 n^2 + 40 m`` for the closed forms and
    the plans printed as JSON, and with the QP cross-check ``3000 + 350 n^2 + 500 n m`` more (cvxpy's and Clarabel's
    data; the condensed form also ``250 (N n) (N m)``). Fitted on the peak resident memory of ``solve`` (less 65 MB,
    110 MB with the QP's imports): n = m = 1, N = 5e6 1.34 GB (predicted 1.58), N = 5e5 with the QP 1.74 GB (2.08);
    n = 30, m = 5, N = 5e4 0.68 GB (0.70), N = 2000 with the QP 0.71 GB (0.81). With the cross-check it is at least
    the closed forms' bytes and the QP's own (`qp_bytes`, the estimate the QP is refused by), which is the
    larger where m is large beside n; so a QP that would be refused is refused with ``solve``, before any work. O(1).

    Examples
    --------
    >>> solve_bytes(5 * 10 ** 7, 1, 1, qp=None) / 2 ** 30           # what ended in a MemoryError: 15 GiB
    14.668...
    >>> solve_bytes(5000, 1, 20) == 5000 * 1075 + qp_bytes(5000, 1, 20)     # twenty channels: the QP's estimate
    True
    """
    N = _float(horizon)
    need = N * (260.0 + 15.0 * n * n + 40.0 * m)
    if qp is None:
        return need
    fitted = need + N * (3000.0 + 350.0 * n * n + 500.0 * n * m)
    if qp == "condensed":
        fitted += 250.0 * (N * n) * (N * m)
    return max(fitted, need + qp_bytes(horizon, n, m, qp))


def constrained_work(horizon: int, n: int, m: int, chance: int = 0, states: int = 0) -> float:
    """Work units (1e-6 s each) of one constrained program's compile and solve (qp/constrained.py) beyond its
    fixed second: the polish's least squares on the active set's KKT matrix and the checks' dense products,
    ``6.8e-4 (N m)^2 N (n + m) / 2``, and per chance row (N second-order cones whose data cvxpy maps per parameter
    entry) ``0.65 N^3 m^2``. Measured (one BLAS thread, input box, a 2-core machine at load 5): n = m = 1, N = 3000
    18.3 s (predicted 18.4), N = 2000 2.3-5.6 s (5.4); n = m = 2, N = 500 0.8 s (0.7); n = 4, m = 1, N = 1000 1.4 s
    (1.7); n = 10, m = 3, N = 300 1.0 s (1.1); one chance row, n = m = 1, N = 300 17.5 s (17.6), N = 200 2.3 s
    (5.2).

    Behind a Markov chain of ``states`` = K states per channel (`chain_states`; 0 for Bernoulli losses) each chance
    row, exact under the chain, costs ``m^2 (K - 1) (0.56 N^3 + 3.2e-3 N^4)`` more (`CHAIN_COMPILE_N3`, cvxpy's
    compile of its denser cones, and `CHAIN_RESOLVE_N4`, Clarabel's first solve). Measured (``ConstrainedQP`` and its
    first solve, one chance row and an input box, CPU time, one BLAS thread; the plug-in program in brackets): a
    scalar plant behind a Gilbert channel, N = 50 / 100 / 200, 0.28 s / 0.89 s / 10.6 s (0.18 / 0.41 / 1.2 s),
    predicted 0.17 / 1.5 / 14.8 s; a 3-state chain, N = 50 / 100, 0.40 / 1.3 s (0.21 / 0.39 s), predicted 0.26 /
    2.4 s; n = m = 2 behind two Gilbert channels, N = 50 / 100 / 200, 0.48 / 2.8 / 31 s (0.20 / 0.55 / 6.9 s),
    predicted 0.69 / 6.1 / 59 s; pendulum_bursty (its chance row binding at most steps), N = 60 / 80 / 100, 0.59 /
    1.3 / 2.8 s (0.31 / 0.43 / 0.56 s), predicted 0.30 / 0.75 / 1.5 s: 0.45 to 1.9 times this, median 0.71. O(1).

    Examples
    --------
    >>> round(estimated_seconds("solve_work", constrained_work(3000, 1, 1)), 1)     # a scalar plant, N = 3000
    18.4
    >>> constrained_work(200, 4, 1, 1, states=2) - constrained_work(200, 4, 1, 1)   # pendulum_bursty's chain rows
    9600000.0
    """
    N = _float(horizon)
    return (6.8e-4 * (N * m) ** 2 * N * (n + m) / 2 + 0.65 * chance * N ** 3 * m * m
            + chance * _chained(states) * m * m * (CHAIN_COMPILE_N3 * N ** 3 + CHAIN_RESOLVE_N4 * N ** 4))


def constrained_bytes(horizon: int, n: int, m: int, rows: int, chance: int = 0, states: int = 0) -> float:
    """Bytes of one constrained program at its peak (qp/constrained.py): the plan's moment maps T, C and a plan's
    spread, ``3 N^2 n m`` doubles; the ``rows`` linear rows as dense Jacobians, ``rows N m``; the polish's KKT
    matrices (the Hessian, the active set's K and its least-squares copy), ``9 (N m)^2``; per chance row cvxpy's
    parameter maps of its N cones, ``N^3 (60 m^2 + 40 n)`` bytes; and the sparse QP's own (`qp_bytes`). Measured
    peak resident memory less the interpreter's 140 MB: n = m = 1, N = 3000, input box 560 MB (predicted 1.0 GB);
    one chance row, N = 100 / 200 / 300 80 MB / 735 MB / 2.5 GB (predicted 0.11 / 0.83 / 2.8 GB); n = 1, m = 2,
    N = 100 223 MB (0.29 GB); n = 4, m = 1, N = 100 224 MB (0.23 GB).

    Behind a Markov chain of ``states`` = K states per channel (`chain_states`; 0 for Bernoulli losses) each chance
    row, exact under the chain, holds ``(K - 1) N^3 (115 m^2 + 50 n)`` bytes more (`CHAIN_BYTES_N3`: cvxpy's maps of
    its denser cones). Measured (the peak resident memory of ``ConstrainedQP`` and its solves in a fresh process less
    that before it, one chance row and an input box; the plug-in program in brackets): a scalar plant behind a Gilbert
    channel, N = 100 / 200, 275 MB / 2.1 GB (105 / 790 MB), predicted 276 MB / 2.1 GB; a 3-state chain, N = 100,
    504 MB (105 MB), predicted 441 MB; n = m = 2 behind two Gilbert channels, N = 100 / 200, 874 MB / 6.9 GB (348 MB
    / 2.7 GB), predicted 895 MB / 7.1 GB; pendulum_bursty, N = 100 / 200, 612 MB / 4.8 GB (254 MB / 2.0 GB),
    predicted 547 MB / 4.3 GB: 0.72 to 1.14 times this for N = 50 to 200, median 0.98. O(1).

    Examples
    --------
    >>> round(constrained_bytes(10 ** 5, 1, 1, 2 * 10 ** 5) / 2 ** 30)     # a horizon of 1e5: 1 TiB
    1043
    >>> constrained_bytes(100, 1, 1, 200, 1, states=3) - constrained_bytes(100, 1, 1, 200, 1)   # 2 x 1e6 x 165
    330000000.0
    """
    N = _float(horizon)
    dense = 8.0 * (3.0 * N * N * n * m + _float(rows) * N * m + 9.0 * (N * m) ** 2)
    chained = chance * _chained(states) * N ** 3 * (CHAIN_BYTES_N3[0] * m * m + CHAIN_BYTES_N3[1] * n)
    return dense + chance * N ** 3 * (60.0 * m * m + 40.0 * n) + chained + qp_bytes(horizon, n, m)


def check_constrained(horizon: int, n: int, m: int, rows: int, chance: int, field: str, programs: int = 1,
                      instead: str = "use a shorter horizon", states: int = 0) -> None:
    """Refuse, before anything is built, ``programs`` constrained programs (solved one after another) whose work
    (`constrained_work`) exceeds the ``solve_work`` budget or one of which exceeds ``memory_bytes``
    (`constrained_bytes`), under ``field`` (the API's ``horizon``, the file's ``cost.horizon``); ``states`` the
    states per channel of the Markov chain the chance rows are exact under (`chain_states`; 0 for Bernoulli
    losses). O(1).

    Examples
    --------
    >>> check_constrained(8, 1, 1, 16, 0, "cost.horizon")                 # silent
    >>> check_constrained(10 ** 5, 1, 1, 2 * 10 ** 5, 0, "cost.horizon")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.BudgetError: cost.horizon: the constrained program of N = 100000 (n = 1, m = 1; ...
    """
    size = (f"the constrained program of N = {horizon} (n = {n}, m = {m}; {rows} linear rows"
            + (f", {count_text(chance)} chance row" + "s" * (chance != 1) if chance else "")
            + (f" exact under a {states}-state chain" if chance and states >= 2 else "") + ")"
            + (f" x {programs}" if programs > 1 else ""))
    work = programs * constrained_work(horizon, n, m, chance, states)
    check("solve_work", work, field, f"{size}, about {duration_text(estimated_seconds('solve_work', work))}",
          instead=instead)
    need = constrained_bytes(horizon, n, m, rows, chance, states)
    check("memory_bytes", need, field, f"{size}, about {gib_text(need)} for one", instead=instead)


def dense_bytes(horizon: int, n: int, m: int) -> float:
    """Bytes of the dense Theorem-1 method (lq/dense.py): Gamma, Omega Gamma, Omega_g, G and its LU, the powers of A,
    Phi and Omega Phi, ``8 (3 (N n)(N m) + 2 (N m)^2 + 4 N n^2)``. O(1).

    Examples
    --------
    >>> dense_bytes(60_000, 2, 1) / 2 ** 30         # a 2-state plant over 60000 steps: the recursion is O(N)
    214.58...
    """
    N = horizon
    return 8.0 * (3 * (N * n) * (N * m) + 2 * (N * m) ** 2 + 4 * N * n * n)


def markov_dense_bytes(horizon: int, n: int, m: int) -> float:
    """Bytes of the dense route to the exact cost under Markov losses (lq/markov_cost.py): a few (N m)×(N m) and
    (N n)×(N m) matrices, ``8 (6 (N m)^2 + 3 (N n)(N m) + 4 N n^2)``. O(1).

    Examples
    --------
    >>> markov_dense_bytes(80, 4, 1)                # pendulum_bursty
    962560.0
    """
    N = horizon
    return 8.0 * (6 * (N * m) ** 2 + 3 * (N * n) * (N * m) + 4 * N * n * n)


def qp_bytes(horizon: int, n: int, m: int, formulation: str = "sparse") -> float:
    """Bytes of one expected-cost QP (qp/) at its peak. The sparse form (tracemalloc over its compile and first
    solve; n = 1..100, m = 1..8, N up to 8000, full weights): about 250 N n^2 bytes for the state terms, 350 N n m
    for the dynamics' input columns and 610 N m for the input terms, plus cvxpy's and Clarabel's fixed ~10 MB,
    ``260 N n^2 + 400 N n m + 650 N m + 1e7`` (no Parameter multiplies a Variable, so cvxpy keeps no (N m)^2 map).
    The condensed form adds its dense (N n)×(N m) data, a Parameter since its problems are shared by shape: 150 bytes
    per entry measured at the peak. O(1).

    Examples
    --------
    >>> qp_bytes(1, 1, 1), qp_bytes(1, 1, 1, "condensed")          # one 1x1 dense block more
    (10001310.0, 10001460.0)
    """
    N = _float(horizon)
    need = 260.0 * N * n * n + 400.0 * N * n * m + 650.0 * N * m + 1e7
    return need + 150.0 * (N * n) * (N * m) if formulation == "condensed" else need


def operator_bytes(rows: int) -> float:
    """Bytes of a dense second-moment operator of ``rows`` rows (closedloop/modes.py) and its eigenvalue routine's copy,
    ``16 rows^2``; its eigenvalues take O(rows^3) time, which the ``operator_rows`` budget bounds. O(1).

    Examples
    --------
    >>> operator_bytes(2048) / 2 ** 20                # the default budget: 64 MiB
    64.0
    """
    return 8.0 * rows * rows * 2


def krylov_bytes(rows: int, vectors: int) -> float:
    """Bytes of ARPACK's Krylov basis on an operator of ``rows`` rows, ``8 rows vectors``. O(1).

    Examples
    --------
    >>> krylov_bytes(2 ** 20, 24) / 2 ** 20
    192.0
    """
    return 8.0 * rows * vectors


def loop_bytes(block: int, steps: int, n: int, m: int, laws: int, keep: int) -> float:
    """Bytes of a sampled closed loop's block arrays (montecarlo/runs.py): deliveries and noise as drawn and as the
    loop reads them (a copy of each, block steps (2 m + 16 n)), norms and stage costs (16 laws block steps), and the
    ``keep`` kept runs' states (8 laws keep steps n). O(1).

    Examples
    --------
    >>> loop_bytes(10, 10_000_000, 4, 1, 3, 0)        # a block of 10 runs of pendulum, 1e7 steps, three laws
    11400001140
    """
    return block * (steps + 1) * (2 * m + 16 * n + 16 * laws) + 8 * laws * keep * (steps + 1) * n


#: Bytes of one compiled TCP-like allocation program (cvxpy's parameter map and Clarabel's data) per N (n + m)^2:
#: the sparse QP's measurement (:func:`qp_bytes`), which it mirrors.
PROGRAM_BYTES_PER_ENTRY = 300


def program_bytes(horizon: int, n: int, m: int) -> float:
    """Bytes of one compiled TCP-like allocation program (allocation/tcp.py), ``300 N (n + m)^2``: what the system's
    cache of them is charged (model.STRUCTURE_CACHE_MAX_BYTES). O(1).

    Examples
    --------
    >>> program_bytes(80, 4, 1)
    600000
    """
    return PROGRAM_BYTES_PER_ENTRY * horizon * (n + m) ** 2


def constraint_bytes(m: int) -> float:
    """Bytes of parsing one linear constraint over ``m`` channels (allocation/grammar.py): five dense arrays of m
    doubles. O(1).

    Examples
    --------
    >>> constraint_bytes(10 ** 9)
    40000000000.0
    """
    return 40.0 * m


def udp_box_work(horizon: int, n: int, m: int) -> float:
    """Work units (1e-6 s each) of one box of the UDP-like branch and bound on the closed-form cost
    (allocation/udp.py): about ``15 m`` cost evaluations (its corner probes and the line searches along its edges;
    27 a box measured for m = 2) of ``100 + N (1 + 0.02 n^2)`` each, and 1000 for its LP. Measured (one BLAS thread):
    a scalar plant with two channels, 15 boxes, N = 3e4 11.3 s (predicted 13.8), N = 1e4 1.1 s (4.7: the shorter
    horizon's arrays stay in cache). The box count is what the budget bounds: the cost of a box grows with N. O(1).

    Examples
    --------
    >>> udp_box_work(100_000, 1, 2) / 1e6                  # seconds a box over 1e5 steps
    3.064
    """
    return 1000.0 + 15.0 * m * (100.0 + _float(horizon) * (1.0 + 0.02 * n * n))


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
