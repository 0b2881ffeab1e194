"""Expected costs J_tcp(U), J_udp(U) and Theorem 1 in closed form.

.. math::
   J_{tcp}(U) = x'(Q + \\Omega_p)x + \\mathrm{tr}(\\Omega_l\\Sigma_W) + 2U'\\bar V\\Omega_{gp}x
                + U'(\\bar V\\Omega_g\\bar V + \\bar V\\Psi)U,\\qquad
   J_{udp}(U) = J_{tcp}(U) + U'\\bar V\\Omega_d(I - \\bar V)U

(eq:opt-lqg-simplest with Lemma 1). Theorem 1: ``U* = -G^{-1} Omega_gp x`` with
``G_tcp = Omega_g Vbar + Psi`` and ``G_udp = G_tcp + Omega_d (I - Vbar)``.
The minimum is ``C - x' Omega_gp' Vbar G^{-1} Omega_gp x``; the paper prints
``G^{-1} Vbar`` in place of ``Vbar G^{-1}``, which differs whenever Vbar is not a
multiple of the identity (see docs/claims.md, [`paper_optimal_cost`][packetloss_cvx.lq.costs.paper_optimal_cost]).

This module is the API of the Theorem-1 pipeline: [`closed_form`][packetloss_cvx.lq.costs.closed_form] validates and
hands the system to `solve` (the method choice, the kernel, the one self-check); the kernels are
`dense` and [`recursion`][packetloss_cvx.lq.recursion], on the system's
`Structure`. The chooser and the dense kernels are also importable from here.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..errors import DimensionError
from ..model.protocols import check_protocol
from ..model.system import System, check_system, numeric_array
from ..results import Solution
from ..threads import blas_limited
from .dense import dense_constant, dense_cost, hessian_diagonal, hessian_factor, loss_variance_term
from .policy import (
    AUTO_DENSE_MAX,
    lyapunov_weights_if_needed,
    pick_method,
    refuse_correlated,
    refuse_dense,
    self_check,
    solve,
    weight_spread,
)
from .policy import choose as dense_or_recursion
from .prediction import prediction
from .recursion import (
    check_plan_cost,
    plan_cost,
    udp_variance_weights,
)

__all__ = [
    "AUTO_DENSE_MAX", "check_inputs", "closed_form", "dense_cost", "dense_or_recursion", "expected_cost",
    "hessian_diagonal", "hessian_factor", "loss_variance_term", "lyapunov_weights_if_needed", "paper_optimal_cost",
    "pick_method", "refuse_correlated", "refuse_dense", "weight_spread",
]


def check_inputs(system: System, inputs: npt.ArrayLike) -> np.ndarray:
    """The N×m input sequence as a float array, or [`InputError`][packetloss_cvx.errors.InputError] naming ``inputs``.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> check_inputs(s, [[1], [2]]).tolist()
    [[1.0], [2.0]]
    >>> check_inputs(s, [[1.0, 2.0]])
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.DimensionError: inputs: expected shape (2, 1) but found (1, 2)
    """
    U = numeric_array(inputs, "inputs")
    shape = (system.horizon, system.m)
    if U.shape != shape:
        raise DimensionError("inputs", f"expected shape {shape} but found {U.shape}")
    return U


@blas_limited
def expected_cost(system: System, inputs: npt.ArrayLike, protocol: str, method: str = "auto") -> float:
    """Expected cost J(U) of the N×m input sequence ``inputs`` as the paper defines it.

    .. math:: J_{udp}(U) = J_{tcp}(U) + U'\\bar V\\Omega_d(I-\\bar V)U

    ``method="auto"`` (the default) and ``"recursion"`` roll out the mean state and add its
    nonnegative stage costs (O(N n^3), no cancellation); ``"dense"`` evaluates the quadratic
    form of eq:opt-lqg-simplest (O((N n)^2 N m)), refused where its condition estimate says
    it would lose digits, and checked against the forward pass.
    Either way the value is returned only where the forward pass is resolved to ``PLAN_COST_RTOL``
    (relative; [`plan_cost`][packetloss_cvx.lq.recursion.plan_cost] bounds its error a posteriori): on an unstable plant
    over a long horizon the rolled-out states of a fixed plan carry its rounding amplified by the open-loop
    growth of A, and the cost of the plan is then not computable in double precision.
    The paper's labels: eq:TCP-prediction-error and eq:lqg-sub-err (the cost with the prediction error),
    eq:opt-lqg-simplest (its value for a plan U).
    Note: for a fixed plan U, the sampled expectation of the realised cost is
    J_udp(U) under both protocols; J_tcp(U) drops the loss-variance term
    (docs/claims.md, expected-cost-tcp).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0],
    ...            input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> # J_udp = E[(1 + v u)^2 + v u^2] with u = -1: 0.5*0 + 0.5*1 + 0.5 = 1.0
    >>> bool(np.isclose(expected_cost(s, [[-1.0]], "udp"), 1.0))
    True

    Raises
    ------
    NumericalError
        The cost exceeds the double range, or its error bound exceeds ``PLAN_COST_RTOL`` of it (the plan's
        rounding amplified by an unstable A: use the closed form's own cost or a shorter horizon), or
        ``"dense"`` where its condition estimate or its self-check refuses.
    """
    system = check_system(system)
    protocol = check_protocol(protocol)
    refuse_correlated(system, protocol)
    U = check_inputs(system, inputs)
    choice = pick_method(system, method) if method != "auto" else "recursion"
    weights = udp_variance_weights(system)
    if choice == "dense":
        refuse_dense(system, weights)
    value, bound = plan_cost(system, U, protocol, weights)
    check_plan_cost(system, protocol, value, bound)
    if choice == "dense":
        dense = dense_cost(system, U, protocol)
        self_check(system, protocol, dense, value, "dense")
        return dense
    return value


@blas_limited
def closed_form(system: System, protocol: str, method: str = "auto") -> Solution:
    """Theorem 1: the optimal plan, its expected cost, gain and closed-loop eigenvalues.

    .. math:: U^* = -G^{-1}\\Omega_{gp}x,\\qquad J^* = C - x'\\Omega_{gp}'\\bar V G^{-1}\\Omega_{gp}x

    Parameters
    ----------
    system : System
    protocol : {"tcp", "udp"}
    method : {"auto", "dense", "recursion"}
        ``"dense"`` solves the (N m)×(N m) system of eq:opt-law-1/2: O((N m)^3 + (N n)^3);
        ``"recursion"`` is the exact backward recursion: O(N (n^3 + m^3)); ``"auto"`` (default)
        takes the dense form for small well-conditioned problems and the recursion otherwise.
        Every method checks its cost against the forward cost of its own plan (a sum of
        nonnegative terms) and raises rather than return a number that fails the check; the
        cost returned is the forward one, which does not cancel (``FORWARD_COST_ROUNDING``).

    Returns
    -------
    Solution

    Raises
    ------
    NumericalError
        ``"dense"`` where its condition estimate exceeds ``DENSE_MAX_CONDITION`` (before anything
        is built), a dense solve whose residual is not small, a cost that disagrees with the
        forward cost of its plan (badly scaled weights), or an exact cost beyond the double range.
    BudgetError
        ``"dense"`` where its matrices would not fit the ``memory_bytes`` budget (before anything is built; a
        ResourceError and a ValueError, field ``method``).

    References
    ----------
    eq:opt-lqg (the minimisation), eq:control-laws, eq:opt-law-1, eq:opt-law-2, eq:TCP-opt-cost,
    eq:UDP-opt-cost (corrected).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0],
    ...            input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> sol = closed_form(s, "tcp")      # min (1 + u)^2 + u^2 at u = -1/2
    >>> bool(np.allclose([sol.inputs[0, 0], sol.cost], [-0.5, 0.5]))
    True
    """
    return solve(check_system(system), check_protocol(protocol), method)


def paper_optimal_cost(system: System, protocol: str) -> float:
    """The optimal cost exactly as printed in eq:TCP-opt-cost / eq:UDP-opt-cost.

    .. math:: C - x'\\Omega_{gp}' G^{-1}\\bar V \\Omega_{gp} x

    Kept for the audit: it equals the true minimum only when Vbar commutes with
    G (e.g. one shared channel, Vbar = nu I). Use [`closed_form`][packetloss_cvx.lq.costs.closed_form] for the cost.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> paper_optimal_cost(s, "udp")               # one channel, Vbar = mu I: the printed form is exact
    0.75
    >>> bool(np.isclose(paper_optimal_cost(s, "udp"), closed_form(s, "udp").cost))
    True
    """
    protocol = check_protocol(protocol)
    pred = prediction(system)
    G = hessian_factor(pred, protocol)
    g = pred.Omega_gp @ system.x0
    return dense_constant(system, pred, system.x0) - float(g @ np.linalg.solve(G, pred.Vbar * g))
