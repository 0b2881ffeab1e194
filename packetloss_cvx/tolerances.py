"""Every numerical tolerance of the package, in one place, with what it promises.

Change a value here, not a literal at the call site; tests import these names so that
a tolerance and the check that relies on it move together.
"""

from __future__ import annotations

import os

__all__ = [
    "ACCEPTED_STATUSES",
    "CLARABEL_DEFAULT",
    "CLARABEL_TIGHT",
    "CROSS_CHECK_COST_RTOL",
    "CROSS_CHECK_INPUT_ATOL",
    "DENSE_MAX_CONDITION",
    "DENSE_RESIDUAL_RTOL",
    "MEMORY_BUDGET_BYTES",
    "PLAN_CHECK_MAX_GROWTH",
    "SELF_CHECK_ATOL",
    "SELF_CHECK_RTOL",
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

#: The dense path of Theorem 1 is refused when the condition estimate
#: (trace Omega_g + max Psi) / min Psi exceeds this. Measured: its relative error is about
#: estimate * 2.2e-16 / 25 (pendulum at mu = 1: N = 200 gives 3.4e11 and a gain off by 3e-6;
#: a rho = 1.2, N = 60 plant gives 9.5e10 and 8e-7), so 1e8 keeps it near 1e-9.
DENSE_MAX_CONDITION = 1e8

#: A closed-form cost is kept only if it agrees with the forward pass of its own plan (a sum of
#: nonnegative terms, free of cancellation): |J_closed - J_forward| <= SELF_CHECK_RTOL * J_forward
#: + SELF_CHECK_ATOL * ||P_0|| ||x||^2 (the last term only for the recursion, whose x'P_0 x has
#: that rounding scale). Well-posed systems agree to 1e-14 (300 random ones: worst 4.7e-15);
#: badly scaled weights (1e10 against 1) disagree by 5e-7 and more.
SELF_CHECK_RTOL = 1e-9
SELF_CHECK_ATOL = 1e-13

#: What one dense computation or one QP may allocate: a quarter of the machine's memory.
MEMORY_BUDGET_BYTES = 0.25 * (os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
                              if hasattr(os, "sysconf") else 8 * 2**30)

#: The QP's objective is checked against the forward cost of its plan only while the open-loop
#: growth max_t ||A^t|| stays below this: beyond it the cost of a fixed plan amplifies the plan's
#: rounding (rho = 1.5, N = 200: a plan right to 1e-12 has a forward cost of 2e40 against the
#: minimum 3.93), and the cross-check against the closed form is the check that binds.
PLAN_CHECK_MAX_GROWTH = 1e4
