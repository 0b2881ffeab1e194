"""Building blocks shared by the TCP-like and UDP-like solvers: the cost at a point, LPs over
sub-boxes of the constraint set with a lower bound proved by an exactly evaluated dual, and
bisection along a segment.

The LP bound: for ``min c'mu`` over ``{l <= mu <= u, G mu <= h}`` and any ``y >= 0``,

.. math:: g(y) = -h'y + \\sum_i \\min\\big((c + G'y)_i l_i,\\ (c + G'y)_i u_i\\big)

is a lower bound (weak duality: the minimum over the box alone of the Lagrangian
``c'mu + y'(G mu - h)``). It is evaluated here in O(m r) floating-point operations from the
multipliers HiGHS returns, so the bound does not rest on the LP solver's tolerances.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import clarabel
import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog

try:        # the HiGHS build scipy's linprog runs (scipy >= 1.15): the same solver without linprog's checks of options
    from scipy.optimize._highspy import _core as highs_core
    from scipy.optimize._highspy._core import simplex_constants as highs_simplex
except ImportError:         # pragma: no cover - an older scipy: linprog alone
    highs_core = highs_simplex = None

from ..errors import SolverError, is_panic
from ..lq.costs import closed_form
from ..lq.evaluator import CostEvaluator
from ..model.system import System
from ..tolerances import ALLOCATION_AIM_RTOL, ALLOCATION_GAP_FLOOR, ALLOCATION_LP_FEASIBILITY, CLARABEL_TIGHT
from .grammar import Polytope

__all__ = [
    "Outcome", "boundary", "box_bound", "box_lp", "bracket", "check_in_polytope", "cost_at", "cost_function",
    "dual_bound", "gap_unit", "highs_optimum", "lp", "polytope_excess", "reported_gap", "small_lp", "unit_prices",
]

_HIGHS = {"primal_feasibility_tolerance": ALLOCATION_LP_FEASIBILITY,
          "dual_feasibility_tolerance": ALLOCATION_LP_FEASIBILITY}
#: linprog's own check of a HiGHS optimum (scipy.optimize._linprog_util._check_result at its default tol = 1e-9):
#: bounds and rows met to sqrt(tol) * 10, else its status 4
_LINPROG_CHECK = np.sqrt(1e-9) * 10


class Outcome(NamedTuple):
    """What a solver found.

    ``mu`` the point (None if none), ``value`` its objective, ``lower_bound`` a proven lower
    bound on the optimum, ``status`` "optimal" (gap certified) or "gap_not_certified",
    ``boxes`` boxes explored, ``note`` how it ended, ``cost`` `J*(mu)` where the solver evaluated it
    (`cost_function`, equal to `cost_at` to rounding), else None; ``scale`` the unit of the gap's
    floor (`gap_unit`): 1 at unit prices, `J*` at the box's lower corner for a cost.
    Construction O(1).

    Examples
    --------
    >>> out = Outcome(np.array([0.25]), 0.25, 0.2499, "optimal", 0, "by hand")
    >>> out.value - out.lower_bound <= 1e-3 * out.value, out._fields[:3]
    (True, ('mu', 'value', 'lower_bound'))
    """

    mu: np.ndarray | None
    value: float
    lower_bound: float
    status: str
    boxes: int
    note: str
    cost: float | None = None
    scale: float | None = None


def gap_unit(value: float, scale: float | None) -> float:
    """What a relative gap is taken of, the one definition for every allocation (the searches' certificate,
    `certified`, the TCP-like programs' and the power relaxations'
    stopping tests, and every reported gap, `reported_gap`): ``|value|``, floored at
    ``ALLOCATION_GAP_FLOOR * scale`` and at the least normal double. ``scale`` is the problem's own size: 1 for a
    communication cost or a power at prices scaled by `unit_prices` (the largest price is 1), J* at the box's
    lower corner (its largest cost) for a cost. An absolute floor certified anything where every cost was below
    1e-12 (weights of 1e-20). ``scale`` None: no floor in the problem's size. O(1).

    Examples
    --------
    >>> gap_unit(2.0, 1.0), gap_unit(-2.0, None), gap_unit(1e-15, 10.0), gap_unit(0.0, 0.0) > 0
    (2.0, 2.0, 1e-11, True)
    """
    floor = 0.0 if scale is None else ALLOCATION_GAP_FLOOR * abs(scale)
    return float(max(abs(value), floor, np.finfo(float).tiny))


def reported_gap(value: float, lower: float, scale: float | None) -> float:
    """The gap a result reports: ``(value - lower) / gap_unit(value, scale)``, the quantity the search
    certified against the requested gap. O(1).

    Examples
    --------
    >>> reported_gap(2.0, 1.5, 1.0), reported_gap(0.5, 0.0, 1e12)      # the second below its floor, 1e-12 * 1e12
    (0.25, 0.5)
    """
    return (value - lower) / gap_unit(value, scale)


def unit_prices(beta: np.ndarray) -> tuple[np.ndarray, float]:
    """``(prices, unit)``: the prices scaled so that the largest is 1, and the unit they were divided by (1 where no
    price is positive). The one price scaling of every allocation: its problem is invariant to the prices' scale,
    so it is solved at unit prices, its gaps taken with `gap_unit` at scale 1, and its bounds reported times
    ``unit``. O(m).

    Examples
    --------
    >>> prices, unit = unit_prices(np.array([1e-20, 4e-20]))
    >>> prices.tolist(), unit
    ([0.25, 1.0], 4e-20)
    """
    top = float(np.max(beta))
    unit = top if top > 0 else 1.0
    return beta / unit, unit


def cost_at(system: System, protocol: str, mu: np.ndarray) -> float:
    """J*(mu) by the closed form (method "auto"), mu clipped to [0, 1]. O(N (n^3 + m^3)).

    Examples
    --------
    One step of x' = x + v u from x0 = 1 (Q = R = 1): `J*_tcp` = 1/(1 + mu), `J*_udp` = 1 - mu/2.

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> bool(np.isclose(cost_at(s, "tcp", np.array([0.5])), 2 / 3)), cost_at(s, "udp", np.array([1.5]))  # clipped to 1
    (True, 0.5)
    """
    return closed_form(system.with_mu(np.clip(mu, 0.0, 1.0)), protocol, "auto").cost


def cost_function(system: System, protocol: str) -> tuple[Callable[[np.ndarray], float], CostEvaluator]:
    """``mu -> J*(mu)`` (mu clipped to [0, 1]) through one [`CostEvaluator`][packetloss_cvx.lq.evaluator.CostEvaluator]
    built for the system, and the evaluator: what does not depend on mu is built once (O(N n^3), plus
    O((N n)^2 N m) where the dense path is allowed); each call O((N m)^3) dense or
    O(N (n^3 + m^3)), equal to `cost_at` to rounding and self-checked the same way.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> J, _ = cost_function(s, "udp")
    >>> bool(np.isclose(J(np.array([0.5])), 0.75)), bool(np.isclose(J(np.array([-1.0])), 1.0))   # 1 - mu/2
    (True, True)
    """
    evaluator = CostEvaluator(system, protocol)
    return (lambda mu: evaluator.cost(np.clip(mu, 0.0, 1.0))), evaluator


def dual_bound(c: np.ndarray, G: np.ndarray, h: np.ndarray, l: np.ndarray, u: np.ndarray, y: np.ndarray) -> float:
    """The weak-duality bound g(y) above for multipliers ``y`` (clipped to >= 0). O(m r).

    Examples
    --------
    min mu1 + mu2 over [0, 1]^2 with mu1 + mu2 >= 1 is 1; y = 1 proves it, y = 0 (or y < 0, clipped) proves 0.

    >>> c, G, h, l, u = np.ones(2), np.array([[-1.0, -1.0]]), np.array([-1.0]), np.zeros(2), np.ones(2)
    >>> dual_bound(c, G, h, l, u, np.array([1.0])), dual_bound(c, G, h, l, u, np.array([-3.0]))
    (1.0, 0.0)
    """
    y = np.maximum(np.asarray(y, dtype=float), 0.0)
    r = c + G.T @ y
    return float(-h @ y + np.sum(np.minimum(r * l, r * u)))


def lp(c: np.ndarray, G: np.ndarray, h: np.ndarray, l: np.ndarray, u: np.ndarray) -> tuple[np.ndarray | None, float]:
    """``min c'x`` over ``l <= x <= u`` (finite) and ``G x <= h``.

    Returns
    -------
    point : ndarray or None
        A minimiser from HiGHS (rows met to ``ALLOCATION_LP_FEASIBILITY``), None when HiGHS
        reports the LP infeasible.
    bound : float
        A lower bound on the minimum, proved by `dual_bound`; +inf when infeasible.

    Raises
    ------
    SolverError
        Any other HiGHS outcome.

    Notes
    -----
    Without rows the box is solved exactly at a corner, O(m). Otherwise one HiGHS solve
    (dual simplex: polynomial in practice in the n variables and r rows, exponential in the
    worst case) and the O(n r) bound.

    Examples
    --------
    >>> c, G, h, l, u = np.ones(2), np.array([[-1.0, -1.0]]), np.array([-1.0]), np.zeros(2), np.ones(2)
    >>> point, bound = lp(c, G, h, l, u)                   # min mu1 + mu2 s.t. mu1 + mu2 >= 1
    >>> bool(np.isclose(point.sum(), 1.0)), bound
    (True, 1.0)
    >>> lp(c, G, np.array([-3.0]), l, u)                   # mu1 + mu2 >= 3: infeasible in the box
    (None, inf)
    """
    c = np.asarray(c, dtype=float)
    if not G.shape[0]:
        point = np.where(c < 0, u, l).astype(float)
        return point, dual_bound(c, G, h, l, u, np.zeros(0))
    direct = highs_optimum(c, G, h, l, u)
    if direct is not None:
        if direct[0] is None:
            return None, np.inf
        return np.clip(direct[0], l, u), dual_bound(c, G, h, l, u, -direct[1])
    res = linprog(c, A_ub=G, b_ub=h, bounds=list(zip(l, u, strict=True)), method="highs", options=_HIGHS)
    if res.status == 2:
        return None, np.inf
    if res.status != 0:
        raise SolverError(f"linprog status {res.status}", f"LP over a box of the constraint set: {res.message}")
    return np.clip(res.x, l, u), dual_bound(c, G, h, l, u, -res.ineqlin.marginals)


def highs_optimum(c: np.ndarray, G: np.ndarray, h: np.ndarray, l: np.ndarray, u: np.ndarray
                  ) -> tuple[np.ndarray | None, np.ndarray | None] | None:
    """What ``linprog(c, A_ub=G, b_ub=h, bounds=(l, u), method="highs", options=_HIGHS)`` answers, where it answers
    "optimal" or "infeasible", without linprog's parsing and option checks (several times the LP itself): the same
    HiGHS build (scipy's), the same model (G as CSC without its zeros, rows ``-inf <= G x <= h``) and the same
    options as scipy's ``_linprog_highs`` passes, so the same simplex run, bit for bit
    (tests/allocation/test_allocation_lp.py
    compares the two on random LPs).

    Returns ``(x, row duals)`` at an optimum that linprog's own check (``_LINPROG_CHECK``) accepts, ``(None,
    None)`` when HiGHS proves the LP infeasible (linprog's status 2), and None for anything else (or a scipy
    without the module): the caller then runs linprog, which reports it. O(m r) plus the simplex.

    Examples
    --------
    >>> x, y = highs_optimum(np.ones(2), np.array([[-1.0, -1.0]]), np.array([-1.0]), np.zeros(2), np.ones(2))
    >>> float(x.sum()), y.tolist()                 # min mu1 + mu2 s.t. mu1 + mu2 >= 1: the row's dual is -1
    (1.0, [-1.0])
    >>> highs_optimum(np.ones(2), np.array([[-1.0, -1.0]]), np.array([-3.0]), np.zeros(2), np.ones(2))
    (None, None)
    """
    if _HIGHS_OPTIONS is None or not (np.all(np.isfinite(G)) and np.all(np.isfinite(c)) and np.all(np.isfinite(h))
                                      and np.all(l <= u)):
        return None             # an older scipy, or data linprog checks or HiGHS refuses: linprog answers
    try:
        return _highs_run(c, G, h, l, u)
    except (AttributeError, TypeError):     # a scipy whose private HiGHS binding changed shape: linprog answers
        return None


def _highs_run(c: np.ndarray, G: np.ndarray, h: np.ndarray, l: np.ndarray, u: np.ndarray
               ) -> tuple[np.ndarray | None, np.ndarray | None] | None:
    """`highs_optimum`'s call of scipy's HiGHS binding (``scipy.optimize._highspy``, private to scipy: any
    change of its shape raises AttributeError or TypeError, which the caller answers by linprog). O(m r) plus the
    simplex."""
    rows, cols = G.shape
    nonzero = G.T != 0                      # CSC: column by column, rows ascending (as scipy.sparse.csc_array(G))
    model = highs_core.HighsLp()
    model.num_col_, model.num_row_ = cols, rows
    model.a_matrix_.num_col_, model.a_matrix_.num_row_ = cols, rows
    model.a_matrix_.format_ = highs_core.MatrixFormat.kColwise
    model.a_matrix_.start_ = np.concatenate([[0], np.cumsum(nonzero.sum(axis=1))]).astype(np.int32)
    model.a_matrix_.index_ = np.nonzero(nonzero)[1].astype(np.int32)
    model.a_matrix_.value_ = G.T[nonzero].astype(float)
    model.col_cost_ = c
    model.col_lower_, model.col_upper_ = np.asarray(l, dtype=float), np.asarray(u, dtype=float)
    model.row_lower_ = np.full(rows, -highs_core.kHighsInf)
    model.row_upper_ = np.asarray(h, dtype=float)
    solver = highs_core._Highs()
    if solver.passOptions(_HIGHS_OPTIONS) == highs_core.HighsStatus.kError or \
            solver.passModel(model) == highs_core.HighsStatus.kError or \
            solver.run() == highs_core.HighsStatus.kError:
        return None
    status = solver.getModelStatus()
    if status == highs_core.HighsModelStatus.kInfeasible:
        return None, None
    if status != highs_core.HighsModelStatus.kOptimal:
        return None
    solution = solver.getSolution()
    x, row = np.array(solution.col_value), np.array(solution.row_value)
    if not (np.all(np.isfinite(x)) and np.all(x >= l - _LINPROG_CHECK) and np.all(x <= u + _LINPROG_CHECK)
            and np.all(h - row >= -_LINPROG_CHECK)):
        return None
    return x, np.array(solution.row_dual)


def _highs_options():
    """scipy's _linprog_highs options for method "highs" with our two tolerances, built once (passOptions
    copies them into each solver)."""
    if highs_core is None:      # pragma: no cover - an older scipy
        return None
    try:
        return _highs_options_of(highs_core, highs_simplex)
    except (AttributeError, TypeError):     # a scipy whose private HiGHS binding changed shape: linprog alone
        return None


def _highs_options_of(core, simplex):
    """The options object of `_highs_options` from the binding ``core`` (its simplex constants ``simplex``).
    O(1)."""
    options = core.HighsOptions()
    options.presolve = "on"
    options.highs_debug_level = core.HighsDebugLevel.kHighsDebugLevelNone
    options.log_to_console = options.output_flag = False
    options.simplex_strategy = simplex.SimplexStrategy.kSimplexStrategyDual
    options.primal_feasibility_tolerance = _HIGHS["primal_feasibility_tolerance"]
    options.dual_feasibility_tolerance = _HIGHS["dual_feasibility_tolerance"]
    return options


_HIGHS_OPTIONS = _highs_options()


def small_lp(c: np.ndarray, G: np.ndarray, h: np.ndarray, l: np.ndarray, u: np.ndarray
             ) -> tuple[np.ndarray | None, float]:
    """`lp`'s contract for an LP of a few variables solved many times (the TCP-like tangent cuts):
    Clarabel's interior point first, `lp` (HiGHS) when Clarabel does not end "Solved" or its
    point misses a row by more than ``ALLOCATION_LP_FEASIBILITY``.

    The bound is `dual_bound` at Clarabel's row multipliers, proved whatever their accuracy, as
    `lp`'s is at HiGHS's; the point is an optimum to Clarabel's tolerance (``CLARABEL_TIGHT``),
    not necessarily a vertex, with coordinates within ``ALLOCATION_LP_FEASIBILITY`` of a bound put on
    it (where the rows allow). Why: ``linprog`` spends ten times the HiGHS run validating its options,
    where one Clarabel solve of this size costs about twice the HiGHS run.

    Notes
    -----
    O(r m^2 + m^3) per interior-point iteration (dense rows), about 10 iterations; then O(m r).

    Examples
    --------
    >>> c, G, h, l, u = np.ones(2), np.array([[-1.0, -1.0]]), np.array([-1.0]), np.zeros(2), np.ones(2)
    >>> point, bound = small_lp(c, G, h, l, u)             # min mu1 + mu2 s.t. mu1 + mu2 >= 1
    >>> bool(np.isclose(point.sum(), 1.0)), bool(1.0 - 1e-9 <= bound <= 1.0)
    (True, True)
    >>> small_lp(c, G, np.array([-3.0]), l, u)             # infeasible in the box: HiGHS says so
    (None, inf)
    """
    c = np.asarray(c, dtype=float)
    m, rows = len(c), G.shape[0]
    if not rows:
        return lp(c, G, h, l, u)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    for key, value in CLARABEL_TIGHT.items():
        setattr(settings, key, value)
    A = sp.csc_array(np.vstack([G, np.eye(m), -np.eye(m)]))
    b = np.concatenate([h, u, -l])
    try:
        solution = clarabel.DefaultSolver(sp.csc_array((m, m)), c, A, b, [clarabel.NonnegativeConeT(rows + 2 * m)],
                                          settings).solve()
    except BaseException as err:    # Clarabel's own failures (untyped, or a Rust panic): HiGHS decides
        if not (isinstance(err, Exception) or is_panic(err)):
            raise
        return lp(c, G, h, l, u)
    if str(solution.status) != "Solved":
        return lp(c, G, h, l, u)
    point = np.clip(np.asarray(solution.x, dtype=float), l, u)
    # an interior point stops just inside the bounds a vertex sits on: snap those within the feasibility
    # tolerance onto them (mu = 0 exactly where HiGHS returns 0), unless that breaks a row
    snapped = np.where(point - l <= ALLOCATION_LP_FEASIBILITY, l, np.where(u - point <= ALLOCATION_LP_FEASIBILITY,
                                                                           u, point))
    y = np.asarray(solution.z, dtype=float)[:rows]
    for candidate in (snapped, point):
        if float(np.max(G @ candidate - h)) <= ALLOCATION_LP_FEASIBILITY:
            return candidate, polished(c, G, h, l, u, point, y)
    return lp(c, G, h, l, u)


def polished(c: np.ndarray, G: np.ndarray, h: np.ndarray, l: np.ndarray, u: np.ndarray, point: np.ndarray,
             y: np.ndarray) -> float:
    """The best `dual_bound` among ``y`` and multipliers made exact on guesses of the active set
    at ``point``.

    An interior point's multipliers are off by its tolerance, and `dual_bound` passes that on.
    For each width w in ``POLISH_WIDTHS``, the rows within w of equality and the coordinates more than
    w inside their bounds give the stationarity equations ``(c + G_A' y_A)_F = 0``, solved in least
    squares. Any result is a multiplier vector (clipped to >= 0), so every bound here is proved; the
    right active set makes it the LP's optimum to rounding. O(r m^2) per width.

    Examples
    --------
    min mu1 + mu2 s.t. mu1 + mu2 >= 1 over [0, 1]^2: at (0.5, 0.5) the exact multiplier 1 proves 1.

    >>> c, G, h, l, u = np.ones(2), np.array([[-1.0, -1.0]]), np.array([-1.0]), np.zeros(2), np.ones(2)
    >>> dual_bound(c, G, h, l, u, np.array([0.9])), round(polished(c, G, h, l, u, np.array([0.5, 0.5]),
    ...                                                          np.array([0.9])), 12)
    (0.9, 1.0)
    """
    best = dual_bound(c, G, h, l, u, y)
    slack = h - G @ point
    for width in POLISH_WIDTHS:
        active = slack <= width
        free = (point - l > width) & (u - point > width)
        if not (active.any() and free.any()):
            continue
        exact = np.zeros_like(y)
        exact[active] = np.linalg.lstsq(G[np.ix_(active, free)].T, -c[free], rcond=None)[0]
        best = max(best, dual_bound(c, G, h, l, u, exact))
    return best


#: widths of the active-set guesses in :func:`polished` (rows unit-scaled, mu in [0, 1])
POLISH_WIDTHS = (1e-10, 1e-8, 1e-6)


def box_lp(c: np.ndarray, poly: Polytope, l: np.ndarray, u: np.ndarray,
           extra: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray | None, float]:
    """`lp` over the box ``[l, u]``, the polytope's rows and ``extra`` rows (if given);
    O(m r) to stack the rows plus the LP.

    Examples
    --------
    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> poly = read_polytope([([[-1.0, -1.0]], [-1.0])], 2, 0.0, 1.0)     # mu1 + mu2 >= 1
    >>> c, l, u = np.array([1.0, 2.0]), np.zeros(2), np.ones(2)          # min mu1 + 2 mu2
    >>> box_lp(c, poly, l, u)[1], box_lp(c, poly, l, u, extra=(np.array([[1.0, 0.0]]), np.array([0.25])))[1]
    (1.0, 1.75)
    """
    G, h = poly.G, poly.h
    if extra is not None:
        G, h = np.vstack([G, extra[0]]), np.concatenate([h, extra[1]])
    return lp(c, G, h, l, u)


def box_bound(beta: np.ndarray, poly: Polytope, l: np.ndarray, u: np.ndarray,
              best: float) -> tuple[float, np.ndarray, np.ndarray, np.ndarray] | None:
    """A box's certified lower bound on ``beta'mu`` for the monotone searches: lower ``u`` (in place) where
    ``beta'mu`` could not beat the incumbent's ``best``, then `box_lp`. ``(lb, l, u, p)`` with ``p`` the
    LP's minimiser, or None when the box holds no point of the rows that could improve. O(m r) plus the LP.

    Examples
    --------
    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> poly = read_polytope([], 2, 0.0, 1.0)
    >>> lb, l, u, p = box_bound(np.array([1.0, 1.0]), poly, np.array([0.25, 0.5]), np.ones(2), 1.0)
    >>> lb, u.tolist()                    # mu1 <= 1 - 0.5 and mu2 <= 1 - 0.25: nothing better above
    (0.75, [0.5, 0.75])
    >>> box_bound(np.array([1.0, 1.0]), poly, np.array([0.5, 0.75]), np.ones(2), 1.0) is None
    True
    """
    if np.isfinite(best):                    # lower u where beta'mu would not beat the incumbent
        rest = beta @ l - beta * l
        positive = beta > 0
        u[positive] = np.minimum(u[positive], (best - rest[positive]) / beta[positive])
        if np.any(u < l):
            return None
    p, lb = box_lp(beta, poly, l, u)
    if p is None:
        return None
    return lb, l, u, p


def check_in_polytope(mu: np.ndarray, poly: Polytope, what: str) -> np.ndarray:
    """Raise SolverError unless ``mu`` meets the bounds and rows to ``ALLOCATION_LP_FEASIBILITY``.
    O(m r).

    Examples
    --------
    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> poly = read_polytope([([[1.0, 1.0]], [1.0])], 2, 0.0, 1.0)        # mu1 + mu2 <= 1
    >>> check_in_polytope(np.array([0.5, 0.5]), poly, "x").tolist()
    [0.5, 0.5]
    >>> check_in_polytope(np.array([0.5, 0.6]), poly, "x")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.SolverError: solver status 'constraint_violation': x: mu violates the constraints by 1.00e-01
    """
    excess = polytope_excess(mu, poly)
    if excess > ALLOCATION_LP_FEASIBILITY:
        raise SolverError("constraint_violation", f"{what}: mu violates the constraints by {excess:.2e}")
    return mu


def polytope_excess(mu: np.ndarray, poly: Polytope) -> float:
    """How far ``mu`` is outside the bounds and rows (0 inside). O(m r).

    Examples
    --------
    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> poly = read_polytope([([[1.0, 1.0]], [1.0])], 2, 0.0, 1.0)        # mu1 + mu2 <= 1
    >>> polytope_excess(np.array([0.5, 0.5]), poly), round(polytope_excess(np.array([0.5, 0.6]), poly), 12)
    (0.0, 0.1)
    """
    return max(float(np.max(poly.G @ mu - poly.h, initial=0.0)),
               float(np.max(poly.lo - mu, initial=0.0)), float(np.max(mu - poly.hi, initial=0.0)))


def bracket(f: Callable[[float], float], alpha: float, a: float, b: float, tol: float,
            fb: float | None = None) -> tuple[float, float]:
    """For ``f(b) <= alpha``: shrink [a, b] to ``(s_in, s_out)`` with ``s_in - s_out <= tol`` (or
    adjacent floats), ``f(s_in) <= alpha`` and ``f(s_out) > alpha`` the last point found
    above alpha (both ``a`` if ``f(a) <= alpha``). ``fb``: f(b) if the caller has it.

    Each step evaluates f where the line through (a, f(a)) and (b, f(b)) crosses alpha (1 -
    ALLOCATION_AIM_RTOL) (regula falsi,
    the Illinois variant: an end kept twice has its value halved), at least tol/4 inside the bracket;
    the bracket is always valid, so the contract is bisection's. `J*` along a line is smooth: about 4-6
    evaluations where bisection takes log2((b - a) / tol), 8 to 25 in the allocation; never more than
    about 4 log2((b - a) / tol). Where alpha's own crossing lies more than tol beyond the aim's (`J*` shallow
    at a small tol), the end game steps a just below it and b 3/4 tol above (the aim's margin cannot be kept
    within tol there) instead of creeping down by tol / 4 (300-800 evaluations at tol = 1e-9).

    Examples
    --------
    >>> s_in, s_out = bracket(lambda t: 1 - t, 0.5, 0.0, 1.0, 1e-3)      # 1 - t <= 0.5 from t = 0.5 on
    >>> s_out < 0.5 <= s_in, s_in - s_out <= 1e-3, bracket(lambda t: 1 - t, 2.0, 0.0, 1.0, 1e-3)
    (True, True, (0.0, 0.0))
    >>> calls = []
    >>> s_in, s_out = bracket(lambda t: calls.append(t) or np.exp(-3 * t), 0.2, 0.0, 1.0, 1e-9)
    >>> bool(s_out < np.log(5) / 3 <= s_in), len(calls) <= 12          # bisection: 31 evaluations
    (True, True)
    """
    fa = f(a)
    if fa <= alpha:
        return a, a
    aim = alpha - ALLOCATION_AIM_RTOL * abs(alpha)      # interpolate toward a level just inside (tolerances.py)
    ga, gb = fa - aim, (f(b) if fb is None else fb) - aim
    side, jumped = 0, False
    while b - a > tol:
        x = b - gb * (b - a) / (gb - ga) if gb - ga < 0 else 0.5 * (a + b)
        if jumped:
            jumped = False
            if side == 1:                   # the jump put a just below alpha's crossing: b 3/4 tol above a
                x = a + 0.75 * tol
        elif x >= b - 0.25 * tol:
            # b is at (or past) the aim, and the step would creep down by tol / 4 toward alpha's own crossing, which
            # a must come within tol of (up to 800 evaluations at tol = 1e-9 where that crossing lies far below b):
            # where it lies more than tol below b, land a just below it, then b 3/4 tol above a
            ha, hb = ga - (alpha - aim), gb - (alpha - aim)
            crossing = b - hb * (b - a) / (hb - ha) if hb - ha < 0 else 0.5 * (a + b)
            if b - crossing > tol:
                x, jumped = crossing - 0.25 * tol, True
        x = min(max(x, a + 0.25 * tol), b - 0.25 * tol)
        if not a < x < b:
            x = 0.5 * (a + b)
            if not a < x < b:
                break
        fx = f(x)
        gx = fx - aim
        if fx <= alpha:
            b, gb = x, gx
            if side == -1:
                ga *= 0.5
            side = -1
        else:
            a, ga = x, gx
            if side == 1:
                gb *= 0.5
            side = 1
    return b, a


def boundary(f: Callable[[float], float], alpha: float, a: float, b: float, tol: float,
             fb: float | None = None) -> float:
    """Smallest t found with ``f(t) <= alpha`` (within tol of the crossing, on the feasible
    side), given ``f(b) <= alpha``. O(log2((b - a) / tol)) evaluations of f.

    Examples
    --------
    >>> t = boundary(lambda t: 1 - t, 0.5, 0.0, 1.0, 1e-3)
    >>> 0.5 <= t <= 0.5 + 1e-3
    True
    """
    return bracket(f, alpha, a, b, tol, fb)[0]
