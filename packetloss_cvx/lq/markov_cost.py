"""The exact expected cost of a plan under correlated (Markov) losses, and its minimiser in closed form.

With ``X = Phi x + Gamma Upsilon U + Lambda W`` and ``v = diag(Upsilon)`` (step-major), ``v`` has
mean ``Vbar`` and second moment ``R = E[v v'] = Vbar Vbar' + C``; ``v_j^2 = v_j`` and W is independent
of v, so (docs/mathematics.md, "Bursty links")

    E[cost] = x'(Q + Omega_p)x + tr(Omega_l Sigma_W) + 2 U' Vbar Omega_gp x + U'(Omega_g ∘ R + Vbar Psi) U
            = J_udp(U) + U'(Omega_g ∘ C_off) U,

``C_off`` the covariance off its diagonal (non-zero only within a channel, across steps). This is the
UDP-like cost (the expected cost of the plan, which sampling measures). The paper's TCP-like cost
(eq:opt-lqg-simplest with eq:TCP-err) holds only first moments, so the chain enters it through mu_t
alone: its plug-in law is already its exact minimiser. Both are convex quadratics in U; the UDP-like
minimiser is ``U* = -(Omega_g ∘ R + Vbar Psi)^{-1} Vbar Omega_gp x`` on the channels that can deliver.

Two routes to each UDP-like number (``method``): ``"recursion"``, the exact LQ problem on the augmented state of
`.augmented`, O(N) time and memory for any finite-state chain (refused beyond its time budget);
``"dense"``, the stacked form above, O((N m)^3 + (N n)^2 N m) time and O((N m)^2) memory (refused beyond
the memory budget), kept as the independent second computation. ``"auto"``: for the minimiser the route
`auto_route` estimates faster (dense for short horizons), for the cost of a plan the recursion's forward pass.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..budgets import (
    MARKOV_DENSE_SECONDS,
    check,
    duration_text,
    estimated_seconds,
    gib_text,
    markov_dense_bytes,
    markov_dense_seconds,
    markov_recursion_work,
)
from ..budgets import limit as budget
from ..errors import InputError, NumericalError
from ..linalg import check_finite, solve_checked
from ..model.chain import stacked_moments
from ..model.protocols import check_protocol
from ..model.system import System, check_system
from ..results import Solution
from .augmented import augmented_size, augmented_solve, chain_cost, check_recursion_budget, mean_state_bound
from .costs import check_inputs, closed_form, expected_cost
from .dense import dense_constant
from .policy import choose, pick_method, self_check
from .prediction import Prediction, prediction
from .recursion import check_plan_cost, overflow_error, udp_variance_weights

__all__ = ["DENSE_SECONDS", "METHODS", "auto_route", "check_method", "correlation_term", "dense_max",
           "dense_prediction", "exact_closed_form", "exact_cost", "exact_hessian", "route_seconds"]

#: The routes to the exact UDP-like cost and minimiser: "auto" is the faster of the two for the minimiser
#: (:func:`auto_route`) and the recursion's forward pass for the cost of a plan.
METHODS = ("auto", "recursion", "dense")

#: The dense route's time model (:func:`~packetloss_cvx.budgets.markov_dense_seconds`, which holds the measurement).
DENSE_SECONDS = MARKOV_DENSE_SECONDS


def check_method(method: str) -> str:
    """``"recursion"`` or ``"dense"`` (``"auto"`` is the recursion here: the cost of a plan by its forward pass;
    [`exact_closed_form`][packetloss_cvx.lq.markov_cost.exact_closed_form] resolves ``"auto"`` for the minimiser by
    `auto_route`); InputError naming ``method`` otherwise. O(1).

    Examples
    --------
    >>> check_method("auto"), check_method("dense")
    ('recursion', 'dense')
    """
    if method not in METHODS:
        raise InputError("method", f"expected 'auto', 'recursion' or 'dense', found {method!r}")
    return "dense" if method == "dense" else "recursion"


def _dense_bytes(system: System) -> float:
    """What the dense route holds (`markov_dense_bytes`). O(1)."""
    return markov_dense_bytes(system.horizon, system.n, system.m)


def _check_memory(system: System) -> None:
    """Refuse the dense route before building its matrices beyond the ``memory_bytes`` budget (BudgetError under
    ``method``)."""
    N, n, m = system.horizon, system.n, system.m
    needed = _dense_bytes(system)
    check("memory_bytes", needed, "method", f"the exact Markov cost by method 'dense' for N = {N}, n = {n}, m = {m} "
                                            f"(dense Omega_g and R, about {gib_text(needed)})",
          instead="use method='recursion' (the augmented recursion, O(N) memory)")


def route_seconds(system: System) -> tuple[float, float]:
    """The estimated CPU seconds (one BLAS thread) of the exact UDP-like minimum by each route, ``(dense,
    recursion)``: `markov_dense_seconds` and the recursion's work
    (`markov_recursion_work` on the augmented size D) at its measured seconds per unit.
    O(m).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=400, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.2]))
    >>> [round(1e3 * t, 1) for t in route_seconds(s)]        # ms at N = 400: about the crossover for m = n = 1
    [21.1, 28.8]
    """
    N, n, m = system.horizon, system.n, system.m
    dense = markov_dense_seconds(N, n, m)
    recursion = estimated_seconds("markov_recursion_work", markov_recursion_work(N, augmented_size(system)))
    return dense, recursion


def dense_max(system: System) -> int:
    """The crossover handed to the one chooser (`dense_or_recursion`) for this system:
    its own N m where the dense route is estimated faster (`route_seconds`) and its matrices fit the memory
    budget, else 0 (the recursion). O(m).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=20, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.2]))
    >>> dense_max(s)                             # N = 20: the dense route is faster
    20
    """
    dense, recursion = route_seconds(system)
    if dense >= recursion or _dense_bytes(system) > budget("memory_bytes"):
        return 0
    return system.horizon * system.m


def auto_route(system: System) -> str:
    """The route ``method="auto"`` takes for the exact UDP-like minimum, before any fallback: the one chooser
    `pick_method` at this system's crossover (`dense_max`), so ``"dense"`` where it
    is estimated faster, fits the memory budget and the condition estimate is within ``DENSE_MAX_CONDITION``
    (the Markov Hessian, scaled by sqrt(mu), has the Bernoulli bound: trace Omega_g + max Psi over min Psi),
    else ``"recursion"``. O(m) plus, where the time favours the dense route, the condition estimate's O(N n^3).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=20, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.2]))
    >>> long = System(A=[[1.0]], B=[[1.0]], horizon=2000, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...               channel=GilbertElliott(p=[0.2], r=[0.2]))
    >>> auto_route(s), auto_route(long)          # the dense route at N = 20, the recursion at N = 2000
    ('dense', 'recursion')
    """
    limit = dense_max(system)
    return pick_method(system, "auto", udp_variance_weights(system), limit) if limit else "recursion"


def dense_prediction(system: System) -> Prediction:
    """The paper's stacked matrices ([`prediction`][packetloss_cvx.lq.prediction.prediction]) after the memory check;
    an overflow says what to do here (the recursion, ``method="recursion"``, needs no dense matrix).
    Time O((N n)^2 N m).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> dense_prediction(s).Gamma.tolist()              # [[B, 0], [A B, B]]
    [[1.0, 0.0], [2.0, 1.0]]
    """
    _check_memory(system)
    try:
        return prediction(system)
    except NumericalError:
        rho = float(max(abs(np.linalg.eigvals(system.A))))
        raise NumericalError(f"the exact Markov cost needs the dense prediction (Gamma, Omega_g), which overflows for "
                             f"rho(A)^N = {rho:.3g}^{system.horizon}; use method='recursion' (the augmented "
                             "recursion) or shorten the horizon") from None


def correlation_term(system: System, inputs: npt.ArrayLike, pred: Prediction | None = None) -> float:
    """U'(Omega_g ∘ C_off)U: what correlated losses add to J_udp(U) (0 for Bernoulli channels).

    Time O((N n)^2 N m) for Omega_g (or given ``pred``), O((N m)^2) for the form.

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> bern = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> bursty = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[0.0],
    ...                 channel=GilbertElliott(p=[0.2], r=[0.2]))     # mu = 1/2, Cov(v_1, v_2) = 0.15
    >>> # Omega_g = [[2, 1], [1, 1]]: U'(Omega_g o C_off)U = 2 * 1 * 0.15 for U = (1, 1)
    >>> round(correlation_term(bursty, [[1.0], [1.0]]), 12), correlation_term(bern, [[1.0], [1.0]])
    (0.3, 0.0)
    """
    system = check_system(system)
    U = check_inputs(system, inputs).ravel()
    if system.channel is None or not system.channel.correlated:
        return 0.0
    pred = dense_prediction(system) if pred is None else pred
    C = stacked_moments(system)[1].copy()
    C[np.diag_indices_from(C)] = 0.0
    with np.errstate(over="ignore", invalid="ignore"):
        value = float(U @ ((pred.Omega_g * C) @ U))
    return float(check_finite("U'(Omega_g o C)U", value))


def exact_cost(system: System, inputs: npt.ArrayLike, protocol: str = "udp", method: str = "auto") -> float:
    """The expected cost of the plan ``inputs`` (N×m) under the system's channel.

    ``"udp"``: E[cost | belief], exact under Markov losses. ``method="auto"``/``"recursion"``: the forward pass
    of the mean state, the state-chain correlations and the error covariance
    (`chain_cost`: nonnegative terms, O(N n^2 (n + m k)));
    ``"dense"``: J_udp(U) + U'(Omega_g ∘ C_off)U (the forward pass of
    [`expected_cost`][packetloss_cvx.lq.costs.expected_cost] plus `correlation_term`, O((N n)^2 N m)).
    ``"tcp"``: the paper's TCP-like cost, which holds only the marginals mu_t (= J_tcp(U)), either method.

    Raises
    ------
    NumericalError
        The cost exceeds the double range (an unstable plant over a long horizon), or it is not resolved to
        ``PLAN_COST_RTOL``: the plan's rolled-out mean states carry its rounding amplified by the open-loop growth
        of A (`check_plan_cost`; the correlations and the error covariance are
        sums of nonnegative terms, no cancellation).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[0.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.2]))
    >>> # x = 0, U = (1, 1): E[(v1)^2] + E[(v1 + v2)^2] + E[v1] + E[v2] = 0.5 + (1 + 2 * 0.4) + 1 = 3.3
    >>> round(exact_cost(s, [[1.0], [1.0]]), 12), round(exact_cost(s, [[1.0], [1.0]], method="dense"), 12)
    (3.3, 3.3)
    """
    protocol = check_protocol(protocol)
    route = check_method(method)
    if protocol == "tcp":
        return expected_cost(system.with_mu(system.mu_schedule), inputs, protocol)
    if route == "dense":
        return expected_cost(system.with_mu(system.mu_schedule), inputs, protocol) + correlation_term(system, inputs)
    system = check_system(system)
    U = check_inputs(system, inputs)
    value = float(chain_cost(system, U[None])[0])
    if not np.isfinite(value):
        raise overflow_error("the exact Markov cost of these inputs", "udp")
    check_plan_cost(system, "udp", value, mean_state_bound(system, U))
    return value


def exact_hessian(system: System, pred: Prediction | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(M, s)`` with ``s = sqrt(Vbar)`` and ``M = Omega_g ∘ (R / s s') + Psi`` on the active entries
    (Vbar > 0), so that the UDP-like Hessian is ``diag(s) M diag(s)`` (M is well conditioned even for
    rarely delivering channels: |R_jk| <= s_j s_k). Time O((N n)^2 N m).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> bern = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> bursty = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[0.0],
    ...                 channel=GilbertElliott(p=[0.2], r=[0.2]))     # mu = 1/2, Cov(v_1, v_2) = 0.15
    >>> M, s = exact_hessian(bern)     # Omega_g o (R / s s') + Psi, R / s s' = [[1, 0.5], [0.5, 1]]
    >>> bool(np.allclose(M, [[3.0, 0.5], [0.5, 2.0]]) and np.allclose(s, np.sqrt(0.5)))
    True
    """
    pred = dense_prediction(system) if pred is None else pred
    v, C = stacked_moments(system)
    active = v > 0
    s = np.sqrt(v[active])
    R = (np.outer(v, v) + C)[np.ix_(active, active)] / np.outer(s, s)
    M = pred.Omega_g[np.ix_(active, active)] * R + np.diag(pred.Psi[active])
    return M, s


def exact_closed_form(system: System, protocol: str = "udp", method: str = "auto") -> Solution:
    """The minimiser of [`exact_cost`][packetloss_cvx.lq.markov_cost.exact_cost] in closed form, with its cost, gain and
        eigenvalues.

    .. math:: U^* = -(\\Omega_g \\circ R + \\bar V\\Psi)^{-1}\\bar V\\Omega_{gp}x,\\qquad
              J^* = C_0 + U^{*\\prime}\\bar V\\Omega_{gp}x

    on the entries with mu_t > 0 (an input over a channel that cannot deliver does not enter the
    cost; it is 0 here). ``"tcp"``: the paper's law with mu_t ([`closed_form`][packetloss_cvx.lq.costs.closed_form]),
    exact because the TCP-like cost holds only first moments (``method`` is not used): the paper's cost at the
    chain's prior-mean rates, which no law with acknowledgements attains behind the chain (the least cost one attains
    is closedloop.chain_dp.chain_attainable's: 10668.7 against 9111.31 on pendulum_bursty).

    ``method="recursion"``: the backward Riccati recursion of the LQ problem on the augmented
    state (`augmented_solve`), any finite-state chain, time
    O(N (D^3 + m^3)) with D = n (1 + sum_i (k_i - 1)) (n (1 + m) for Gilbert–Elliott channels), memory O(N m D),
    refused in advance beyond the ``markov_recursion_work`` budget (BudgetError naming what the dense route
    would need); ``"dense"``: the stacked solve above, time O((N m)^3 + (N n)^2 N m), memory
    O((N m)^2 + N n N m), refused in advance beyond the memory budget; ``"auto"``: the route
    `auto_route` estimates faster (the dense one for short horizons, within the memory budget and
    well conditioned), falling back to the recursion if the dense route raises NumericalError. Either cost is
    checked against the forward cost of its own plan to
    ``SELF_CHECK_RTOL`` (the recursion: `chain_cost`; the dense route:
    [`exact_cost`][packetloss_cvx.lq.markov_cost.exact_cost] with ``method="dense"``).

    Raises
    ------
    BudgetError
        (a ResourceError and an InputError) ``"dense"``: the dense matrices would not fit the ``memory_bytes``
        budget (under ``method``); the recursion's estimated time is beyond its budget (under ``channel``).
    NumericalError
        A solve without a small residual, an overflow (an unstable plant over a long horizon, as the Bernoulli
        recursion), or a self-check that fails.

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> bern = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> bursty = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...                 channel=GilbertElliott(p=[0.2], r=[0.2]))     # mu = 1/2, Cov(v_1, v_2) = 0.15
    >>> # Bernoulli losses: the exact cost is the paper's J_udp, so the minima agree
    >>> bool(np.isclose(exact_closed_form(bern).cost, closed_form(bern, "udp").cost))
    True
    >>> # correlated losses: the two routes agree
    >>> bool(np.isclose(exact_closed_form(bursty).cost, exact_closed_form(bursty, method="dense").cost, rtol=1e-12))
    True
    """
    system = check_system(system)
    route = check_method(method)
    if check_protocol(protocol) == "tcp":
        sol = closed_form(system, "tcp")
        return Solution(protocol="tcp", cost=sol.cost, inputs=sol.inputs, gain=sol.gain,
                        closed_loop_eigenvalues=sol.closed_loop_eigenvalues, method=f"markov-{sol.method}")
    # auto: the one chooser and fallback at this system's estimated crossover; past it straight to the recursion,
    # without the condition estimate's O(N n^3) Lyapunov sum (the recursion runs its own)
    limit = dense_max(system) if method == "auto" else 0
    if limit:
        route, dense = choose(system, "auto", udp_variance_weights(system),
                                          lambda: _dense_closed_form(system), limit)
        if dense is not None:
            return dense
    if route == "recursion":
        size = augmented_size(system)
        dense, _ = route_seconds(system)
        instead = (f"method='dense' needs about {duration_text(dense)} and {_dense_bytes(system) / 2**30:.2g} GiB"
                   + (", within the memory budget" if _dense_bytes(system) <= budget("memory_bytes") else
                      ", over the memory budget: use a chain with fewer states or a shorter horizon"))
        check_recursion_budget(system, size, instead)
        U, gain, cost = augmented_solve(system)
        return Solution(protocol="udp", cost=cost, inputs=U, gain=gain,
                        closed_loop_eigenvalues=np.linalg.eigvals(system.A - system.B @ gain),
                        method="markov-recursion")
    return _dense_closed_form(system)


def _dense_closed_form(system: System) -> Solution:
    N, m, x = system.horizon, system.m, system.x0
    pred = dense_prediction(system)
    M, s = exact_hessian(system, pred)
    active = pred.Vbar > 0
    rhs = s[:, None] * pred.Omega_gp[active]                                   # diag(s)^-1 Vbar Omega_gp
    F = np.zeros((N * m, system.n))
    F[active] = solve_checked(M, check_finite("Omega_gp", rhs), "the exact Markov Hessian", "a shorter horizon") \
        / s[:, None]
    u = -F @ x
    g = pred.Omega_gp @ x
    cost = dense_constant(system, pred, x) + float(g @ (pred.Vbar * u))
    U = u.reshape(N, m)
    forward = exact_cost(system, U, "udp", method="dense")
    self_check(system, "udp", cost, forward, "markov-dense")
    gain = F[:m]
    return Solution(protocol="udp", cost=cost, inputs=U, gain=gain,
                    closed_loop_eigenvalues=np.linalg.eigvals(system.A - system.B @ gain), method="markov-dense")
