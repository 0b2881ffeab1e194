"""Building blocks shared by the TCP-like and UDP-like solvers: the cost at a point, LPs over
sub-boxes of the constraint set, and bisection along a segment on which J* is monotone."""

from __future__ import annotations

from collections.abc import Callable

import cvxpy as cp
import numpy as np
from scipy.optimize import linprog

from ..costs import closed_form
from ..errors import SolverError
from ..model import System
from .grammar import base_constraints

__all__ = ["BoxLP", "boundary", "bracket", "cost_at", "solve_clarabel"]


def solve_clarabel(problem: cp.Problem, what: str) -> None:
    """Clarabel at its default tolerances (1e-8 gap): the tightened ones of the QP twin stall on
    quad-over-lin terms near mu = 0 or 1 and end 'optimal_inaccurate'."""
    try:
        problem.solve(solver=cp.CLARABEL)
    except cp.error.SolverError as err:
        raise SolverError("solver_error", f"{what}: {err}") from None


class BoxLP:
    """min c'mu over [l, u] and the linear/callable constraints: HiGHS (scipy) for G mu <= h,
    a cvxpy problem re-solved through Parameters when callables are present."""

    def __init__(self, m: int, G, h, calls) -> None:
        self.G, self.h, self.fast = G, h, not calls
        if self.fast:
            return
        self.mu = cp.Variable(m)
        self.l, self.u, self.c = cp.Parameter(m), cp.Parameter(m), cp.Parameter(m)
        cons = [self.mu >= self.l, self.mu <= self.u] + base_constraints(self.mu, 0.0, 1.0, G, h, calls)
        self.problem = cp.Problem(cp.Minimize(self.c @ self.mu), cons)

    def solve(self, c, l, u) -> np.ndarray | None:
        if self.fast:
            if not self.G.shape[0]:   # a box alone: the minimiser is a corner
                return np.where(np.asarray(c) > 0, l, np.where(np.asarray(c) < 0, u, l)).astype(float)
            res = linprog(c, A_ub=self.G, b_ub=self.h, bounds=list(zip(l, u, strict=True)), method="highs")
            if res.status == 2:
                return None
            if res.status != 0:
                raise SolverError(f"linprog status {res.status}", res.message)
            return np.clip(res.x, l, u)
        self.c.value, self.l.value, self.u.value = c, l, u
        solve_clarabel(self.problem, "box LP")
        if self.problem.status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
            return None
        if self.problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
            raise SolverError(self.problem.status, "box LP")
        return np.clip(self.mu.value, l, u)


def cost_at(system: System, protocol: str, mu: np.ndarray) -> float:
    return closed_form(system.with_mu(np.clip(mu, 0.0, 1.0)), protocol, "auto").cost


def bracket(f: Callable[[float], float], alpha: float, a: float, b: float, tol: float) -> tuple[float, float]:
    """For f decreasing with f(b) <= alpha: bisect to (s_in, s_out), s_in - s_out <= tol, where
    f(s_in) <= alpha and s_out is the last point known to have f > alpha (both a if f(a) <= alpha)."""
    if f(a) <= alpha:
        return a, a
    while b - a > tol:
        mid = 0.5 * (a + b)
        if f(mid) <= alpha:
            b = mid
        else:
            a = mid
    return b, a


def boundary(f: Callable[[float], float], alpha: float, a: float, b: float, tol: float) -> float:
    """Smallest feasible t (to within tol, on the feasible side) for f decreasing, f(b) <= alpha."""
    return bracket(f, alpha, a, b, tol)[0]
