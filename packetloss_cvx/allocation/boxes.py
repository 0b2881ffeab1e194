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

import numpy as np
from scipy.optimize import linprog

from ..costs import closed_form
from ..errors import SolverError
from ..evaluator import CostEvaluator
from ..model import System
from ..tolerances import ALLOCATION_LP_FEASIBILITY
from .grammar import Polytope

__all__ = [
    "Outcome", "boundary", "box_lp", "bracket", "check_in_polytope", "cost_at", "cost_function", "dual_bound", "lp",
]

_HIGHS = {"primal_feasibility_tolerance": ALLOCATION_LP_FEASIBILITY,
          "dual_feasibility_tolerance": ALLOCATION_LP_FEASIBILITY}


class Outcome(NamedTuple):
    """What a solver found.

    ``mu`` the point (None if none), ``value`` its objective, ``lower_bound`` a proven lower
    bound on the optimum, ``status`` "optimal" (gap certified) or "gap_not_certified",
    ``boxes`` boxes explored, ``note`` how it ended. Construction O(1).
    """

    mu: np.ndarray | None
    value: float
    lower_bound: float
    status: str
    boxes: int
    note: str


def cost_at(system: System, protocol: str, mu: np.ndarray) -> float:
    """J*(mu) by the closed form (method "auto"), mu clipped to [0, 1]. O(N (n^3 + m^3))."""
    return closed_form(system.with_mu(np.clip(mu, 0.0, 1.0)), protocol, "auto").cost


def cost_function(system: System, protocol: str) -> tuple[Callable[[np.ndarray], float], CostEvaluator]:
    """``mu -> J*(mu)`` (mu clipped to [0, 1]) through one :class:`CostEvaluator` built for the
    system, and the evaluator: what does not depend on mu is built once (O(N n^3), plus
    O((N n)^2 N m) where the dense path is allowed); each call O((N m)^3) dense or
    O(N (n^3 + m^3)), equal to :func:`cost_at` to rounding and self-checked the same way."""
    evaluator = CostEvaluator(system, protocol)
    return (lambda mu: evaluator.cost(np.clip(mu, 0.0, 1.0))), evaluator


def dual_bound(c: np.ndarray, G: np.ndarray, h: np.ndarray, l: np.ndarray, u: np.ndarray, y: np.ndarray) -> float:
    """The weak-duality bound g(y) above for multipliers ``y`` (clipped to >= 0). O(m r)."""
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
        A lower bound on the minimum, proved by :func:`dual_bound`; +inf when infeasible.

    Raises
    ------
    SolverError
        Any other HiGHS outcome.

    Notes
    -----
    Without rows the box is solved exactly at a corner, O(m). Otherwise one HiGHS solve
    (dual simplex: polynomial in practice in the n variables and r rows, exponential in the
    worst case) and the O(n r) bound.
    """
    c = np.asarray(c, dtype=float)
    if not G.shape[0]:
        point = np.where(c < 0, u, l).astype(float)
        return point, dual_bound(c, G, h, l, u, np.zeros(0))
    res = linprog(c, A_ub=G, b_ub=h, bounds=list(zip(l, u, strict=True)), method="highs", options=_HIGHS)
    if res.status == 2:
        return None, np.inf
    if res.status != 0:
        raise SolverError(f"linprog status {res.status}", f"LP over a box of the constraint set: {res.message}")
    return np.clip(res.x, l, u), dual_bound(c, G, h, l, u, -res.ineqlin.marginals)


def box_lp(c: np.ndarray, poly: Polytope, l: np.ndarray, u: np.ndarray,
           extra: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray | None, float]:
    """:func:`lp` over the box ``[l, u]``, the polytope's rows and ``extra`` rows (if given);
    O(m r) to stack the rows plus the LP."""
    G, h = poly.G, poly.h
    if extra is not None:
        G, h = np.vstack([G, extra[0]]), np.concatenate([h, extra[1]])
    return lp(c, G, h, l, u)


def check_in_polytope(mu: np.ndarray, poly: Polytope, what: str) -> np.ndarray:
    """Raise SolverError unless ``mu`` meets the bounds and rows to ``ALLOCATION_LP_FEASIBILITY``.
    O(m r)."""
    excess = max(float(np.max(poly.G @ mu - poly.h, initial=0.0)),
                 float(np.max(poly.lo - mu, initial=0.0)), float(np.max(mu - poly.hi, initial=0.0)))
    if excess > ALLOCATION_LP_FEASIBILITY:
        raise SolverError("constraint_violation", f"{what}: mu violates the constraints by {excess:.2e}")
    return mu


def bracket(f: Callable[[float], float], alpha: float, a: float, b: float, tol: float) -> tuple[float, float]:
    """For ``f(b) <= alpha``: bisect to ``(s_in, s_out)`` with ``s_in - s_out <= tol`` (or
    adjacent floats), ``f(s_in) <= alpha`` and ``f(s_out) > alpha`` the last point found
    above alpha (both ``a`` if ``f(a) <= alpha``). O(log2((b - a) / tol)) evaluations of f."""
    if f(a) <= alpha:
        return a, a
    while b - a > tol:
        mid = 0.5 * (a + b)
        if not a < mid < b:
            break
        if f(mid) <= alpha:
            b = mid
        else:
            a = mid
    return b, a


def boundary(f: Callable[[float], float], alpha: float, a: float, b: float, tol: float) -> float:
    """Smallest t found with ``f(t) <= alpha`` (within tol of the crossing, on the feasible
    side), given ``f(b) <= alpha``. O(log2((b - a) / tol)) evaluations of f."""
    return bracket(f, alpha, a, b, tol)[0]
