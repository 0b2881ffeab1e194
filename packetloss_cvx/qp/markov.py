"""The exact expected cost under correlated losses minimised as a cvxpy + Clarabel QP, and
cross-checked against the closed form ([`exact_closed_form`][packetloss_cvx.lq.markov_cost.exact_closed_form]).

UDP-like objective, every term a sum of squares (weights scaled to one, x to unit size):

    || L (Phi x + Gamma (Vbar ∘ U)) ||^2 + || sqrt(Vbar Psi) ∘ U ||^2 + || F U ||^2,

``L'L = Omega`` and ``F'F = Omega_g ∘ C`` (PSD by the Schur product theorem: both factors are PSD),
C the covariance of the stacked deliveries. Its value plus x'Qx + tr(Omega_l Sigma_W) is the exact
expected cost. The TCP-like cost holds only mu_t, so its QP is the package's own
([`solve_qp`][packetloss_cvx.qp.expected_cost.solve_qp]) on the plug-in schedule.
"""

from __future__ import annotations

import time

import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from ..errors import NumericalError, SolverError
from ..linalg import psd_factor
from ..lq.markov_cost import dense_prediction, exact_closed_form
from ..model.chain import stacked_moments
from ..model.protocols import check_protocol
from ..model.system import System, check_system
from ..results import Solution
from ..tolerances import ACCEPTED_STATUSES, CLARABEL_TIGHT
from .convex import solve_problem
from .expected_cost import compare, solve_qp

__all__ = ["exact_qp"]


def exact_qp(system: System, protocol: str = "udp", cross_check: bool = True,
             reference: Solution | None = None) -> Solution:
    """Minimise the exact expected cost with cvxpy + Clarabel (the solver twin of the closed form).

    Parameters
    ----------
    system : System
        With a Gilbert–Elliott channel (a Bernoulli one gives the UDP-like QP of the paper).
    protocol : {"udp", "tcp"}
    cross_check : bool
        Compare with ``reference`` (default [`exact_closed_form`][packetloss_cvx.lq.markov_cost.exact_closed_form]); a
        disagreement beyond ``CROSS_CHECK_INPUT_ATOL`` / ``CROSS_CHECK_COST_RTOL`` raises
        [`CrossCheckError`][packetloss_cvx.errors.CrossCheckError].

    Returns
    -------
    Solution
        ``method="markov-qp"``, with ``status``, ``solve_time`` and ``cross_check``; no gain.

    Raises
    ------
    NumericalError
        Any status but optimal (the QP is unconstrained and strictly convex).
    CrossCheckError
        The QP and the closed form disagree.

    Notes
    -----
    Time O((N n)^2 N m + (N m)^3) to build (the factor F), one Clarabel solve; memory O((N m)^2).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> sol = exact_qp(s)            # min 0.5 (1 + u)^2 + 0.5 + 0.5 u^2 = 0.75 at u = -1/2
    >>> bool(np.allclose([sol.inputs[0, 0], sol.cost], [-0.5, 0.75], atol=1e-6))
    True
    """
    system = check_system(system)
    if check_protocol(protocol) == "tcp":
        ref = reference if reference is not None or not cross_check else exact_closed_form(system, "tcp")
        sol = solve_qp(system, "tcp", with_gain=False, cross_check=cross_check, reference=ref)
        return Solution(protocol="tcp", cost=sol.cost, inputs=sol.inputs, gain=None, closed_loop_eigenvalues=None,
                        method="markov-qp", status=sol.status, solve_time=sol.solve_time, cross_check=sol.cross_check)
    N, n, m = system.horizon, system.n, system.m
    pred = dense_prediction(system)
    v, C = stacked_moments(system)
    scale = max(float(system.input_weights.max()), float(np.linalg.eigvalsh(system.state_weights).max()))
    L = sla.block_diag(*[psd_factor(W) for W in system.state_weights]) / np.sqrt(scale)
    F = psd_factor(0.5 * (pred.Omega_g * C + (pred.Omega_g * C).T) / scale)
    x = cp.Parameter(n, name="x")
    U = cp.Variable(N * m, name="U")
    terms = [cp.sum_squares(cp.multiply(np.sqrt(v * pred.Psi / scale), U))]
    if L.shape[0]:
        terms.append(cp.sum_squares(L @ pred.Phi @ x + (L @ pred.Gamma * v[None, :]) @ U))
    if F.shape[0]:
        terms.append(cp.sum_squares(F @ U))
    problem = cp.Problem(cp.Minimize(cp.sum(terms)))
    size = float(np.abs(system.x0).max())
    start = time.perf_counter()
    if size > 0:
        x.value = system.x0 / size
        try:
            status = solve_problem(problem, "exact Markov QP", attempts=(CLARABEL_TIGHT,))
        except SolverError as err:
            status = err.status
        if status not in ACCEPTED_STATUSES:
            raise NumericalError(f"Clarabel ended {status!r} on the exact Markov QP, which is unconstrained and "
                                 "strictly convex: the problem's scale is beyond the solver's range; the closed form "
                                 "(exact_closed_form) is exact here")
        u = np.asarray(U.value) * size
        value = float(problem.value) * scale * size**2
    else:
        u, value, status = np.zeros(N * m), 0.0, "optimal"
    u = np.where(v > 0, u, 0.0)          # an input over a channel that cannot deliver does not enter the cost
    solve_time = time.perf_counter() - start
    cost = value + float(system.x0 @ system.initial_weight @ system.x0) + pred.noise_term
    check = None
    if cross_check:
        ref = reference if reference is not None else exact_closed_form(system, "udp")
        check = compare(u.reshape(N, m), cost, ref, system, scale=(scale * size**2, size))
    return Solution(protocol="udp", cost=cost, inputs=u.reshape(N, m), gain=None, closed_loop_eigenvalues=None,
                    method="markov-qp", status=status, solve_time=solve_time, cross_check=check)
