"""Running cvxpy problems with Clarabel under one policy.

* solver warnings are captured, never printed (the command line prints one line);
* cvxpy's own solver failures become :class:`SolverError`;
* only the statuses in :data:`tolerances.ACCEPTED_STATUSES` count as an answer
  (``optimal_inaccurate`` does not);
* infeasibility counts only when the solver proved it (``infeasible``, not ``infeasible_inaccurate``).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import cvxpy as cp

from .errors import SolverError
from .tolerances import ACCEPTED_STATUSES, CLARABEL_DEFAULT, CLARABEL_TIGHT

__all__ = ["PROVEN_INFEASIBLE", "require_optimal", "solve_problem"]

#: The status that proves infeasibility (Clarabel's certificate); "infeasible_inaccurate" does not.
PROVEN_INFEASIBLE = cp.INFEASIBLE


def solve_problem(problem: cp.Problem, what: str,
                  attempts: Sequence[Mapping] = (CLARABEL_TIGHT, CLARABEL_DEFAULT)) -> str:
    """Solve with Clarabel, trying each settings dict in ``attempts`` until one gives an
    accepted status or a proven infeasibility; returns the final status.

    Raises
    ------
    SolverError
        When cvxpy or Clarabel fails outright (status ``"solver_error"``).

    Examples
    --------
    >>> x = cp.Variable()
    >>> problem = cp.Problem(cp.Minimize(cp.square(x - 1)))
    >>> solve_problem(problem, "a scalar QP")
    'optimal'
    >>> bool(abs(x.value - 1.0) < 1e-6)
    True
    """
    status = "not_solved"
    for settings in attempts:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                problem.solve(solver=cp.CLARABEL, **settings)
            except cp.error.SolverError as err:
                raise SolverError("solver_error", f"{what}: {err}") from None
            except (ValueError, ArithmeticError) as err:   # e.g. a parameter value cvxpy refuses
                raise SolverError("solver_error", f"{what}: {err}") from None
        status = str(problem.status)
        if status in ACCEPTED_STATUSES or status == PROVEN_INFEASIBLE:
            return status
    return status


def require_optimal(status: str, what: str) -> None:
    """Raise :class:`SolverError` unless ``status`` is an accepted answer.

    Examples
    --------
    >>> require_optimal("optimal", "the QP") is None
    True
    >>> require_optimal("infeasible", "the QP")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.SolverError: solver status 'infeasible': the QP
    """
    if status not in ACCEPTED_STATUSES:
        raise SolverError(status, what)
