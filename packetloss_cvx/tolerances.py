"""Every numerical tolerance of the package, in one place, with what it promises.

Change a value here, not a literal at the call site; tests import these names so that
a tolerance and the check that relies on it move together.
"""

from __future__ import annotations

__all__ = [
    "ACCEPTED_STATUSES",
    "CLARABEL_DEFAULT",
    "CLARABEL_TIGHT",
    "CROSS_CHECK_COST_RTOL",
    "CROSS_CHECK_INPUT_ATOL",
    "DENSE_RESIDUAL_RTOL",
    "PSD_FACTOR_RTOL",
    "SYMMETRY_RTOL",
]

#: A weight is symmetric when ||W - W'|| <= SYMMETRY_RTOL * max(1, ||W||) (spectral norms),
#: and positive semidefinite when its least eigenvalue is >= -SYMMETRY_RTOL * max(1, ||W||).
SYMMETRY_RTOL = 1e-10

#: psd_factor drops eigen-directions below PSD_FACTOR_RTOL * max(1, largest eigenvalue).
PSD_FACTOR_RTOL = 1e-14

#: Clarabel for the expected-cost QP twin: tight enough that the cross-check below is meaningful.
CLARABEL_TIGHT = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10, "max_iter": 400}

#: Clarabel's own defaults (1e-8 gap and feasibility), tried where the tight settings stall.
CLARABEL_DEFAULT: dict[str, float] = {}

#: The only solver status taken as an answer. ``optimal_inaccurate`` is never accepted: a caller
#: may retry with other settings, and otherwise raises SolverError with the status.
ACCEPTED_STATUSES = frozenset({"optimal"})

#: The QP twin agrees with the closed form when max |U_qp - U*| <= CROSS_CHECK_INPUT_ATOL * max(1, max|U*|)
#: (over channels with mu > 0) ...
CROSS_CHECK_INPUT_ATOL = 1e-6
#: ... and |J_qp - J*| <= CROSS_CHECK_COST_RTOL * max(1, |J*|).
CROSS_CHECK_COST_RTOL = 1e-7

#: A dense solve G U = b is kept only if ||G U - b|| <= DENSE_RESIDUAL_RTOL * ||G|| ||U|| + ||b|| scaled
#: likewise; past it the dense path has lost the answer and raises NumericalError.
DENSE_RESIDUAL_RTOL = 1e-9
