"""Expected costs J_tcp(U), J_udp(U) and Theorem 1 in closed form.

.. math::
   J_{tcp}(U) = x'(Q + \\Omega_p)x + \\mathrm{tr}(\\Omega_l\\Sigma_W) + 2U'\\bar V\\Omega_{gp}x
                + U'(\\bar V\\Omega_g\\bar V + \\bar V\\Psi)U,\\qquad
   J_{udp}(U) = J_{tcp}(U) + U'\\bar V\\Omega_d(I - \\bar V)U

(eq:opt-lqg-simplest with Lemma 1). Theorem 1: ``U* = -G^{-1} Omega_gp x`` with
``G_tcp = Omega_g Vbar + Psi`` and ``G_udp = G_tcp + Omega_d (I - Vbar)``.
The minimum is ``C - x' Omega_gp' Vbar G^{-1} Omega_gp x``; the paper prints
``G^{-1} Vbar`` in place of ``Vbar G^{-1}``, which differs whenever Vbar is not a
multiple of the identity (see docs/claims.md, :func:`paper_optimal_cost`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from ..budgets import check, dense_bytes, gib_text
from ..errors import DimensionError, InputError, NumericalError
from ..linalg import solve_checked
from ..model.protocols import check_protocol
from ..model.system import System, check_system, numeric_array
from ..results import Solution
from ..threads import blas_limited
from ..tolerances import DENSE_MAX_CONDITION, PLAN_COST_RTOL, SELF_CHECK_ATOL, SELF_CHECK_RTOL
from .prediction import Prediction, prediction
from .recursion import (
    check_plan_cost,
    condition_estimate,
    optimal_plan,
    plan_cost,
    recursion_cost,
    udp_variance_weights,
)

__all__ = [
    "check_inputs", "closed_form", "dense_or_recursion", "expected_cost", "hessian_diagonal", "hessian_factor",
    "loss_variance_term", "lyapunov_weights_if_needed", "paper_optimal_cost", "pick_method", "refuse_correlated",
    "refuse_dense", "weight_spread",
]

#: ``method="auto"`` uses the dense form up to this many decision variables N*m
#: (measured crossover for n = 4, m = 2 between N*m = 160 and 200: docs/performance.md),
#: and only while the condition estimate stays below ``tolerances.DENSE_MAX_CONDITION``.
AUTO_DENSE_MAX = 160

T = TypeVar("T")


def pick_method(system: System, method: str, weights: tuple[np.ndarray, float] | None = None,
                dense_max: int = AUTO_DENSE_MAX) -> str:
    """Resolve ``"auto"`` to the faster exact path: ``"dense"`` for small (N m <= ``dense_max``, the caller's
    measured crossover), well-conditioned problems, ``"recursion"`` otherwise. Time O(N n^3) (the condition
    estimate).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> pick_method(s, "auto")                     # N m = 2 variables, well conditioned
    'dense'
    >>> pick_method(s, "qr")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: method: expected 'auto', 'dense' or 'recursion', found 'qr'
    """
    if method == "auto":
        if system.horizon * system.m > dense_max:
            return "recursion"
        return "dense" if condition_estimate(system, weights) <= DENSE_MAX_CONDITION else "recursion"
    if method not in ("dense", "recursion"):
        raise InputError("method", f"expected 'auto', 'dense' or 'recursion', found {method!r}")
    return method


def refuse_dense(system: System, weights: tuple[np.ndarray, float]) -> None:
    """Raise before building anything dense that would not fit or would lose the answer.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> refuse_dense(s, udp_variance_weights(s)) is None       # small and well conditioned: no objection
    True
    """
    N, n, m = system.horizon, system.n, system.m
    needed = dense_bytes(N, n, m)
    check("memory_bytes", needed, "method", f"method 'dense' for N = {N}, n = {n}, m = {m} (about {gib_text(needed)})",
          instead="use method='recursion' (exact, O(N) memory; --method recursion)")
    kappa = condition_estimate(system, weights)
    if kappa > DENSE_MAX_CONDITION:
        raise NumericalError(
            f"method 'dense': the condition estimate (trace Omega_g + max Psi)/min Psi = {kappa:.2g} exceeds "
            f"{DENSE_MAX_CONDITION:.0e}, so the dense formulas would lose their digits (unstable plant over a "
            f"long horizon, or weights of very different sizes); use method='recursion'")


def _self_checked(system: System, protocol: str, closed: float, U: np.ndarray, method: str,
                  weights: tuple[np.ndarray, float], atol: float = 0.0, states: np.ndarray | None = None) -> float:
    """The forward cost of the plan ``U`` (a sum of nonnegative terms, free of cancellation; ``states``: its
    mean states if the caller has them, else the plan is rolled out open loop and must be resolved,
    :func:`~packetloss_cvx.lq.recursion.plan_cost`) if ``closed`` agrees with it to ``SELF_CHECK_RTOL`` (plus
    ``atol``); NumericalError otherwise. The forward cost is the one to report as J*: ``closed`` (x'P_0 x, or
    C - g'Vbar G^-1 g) cancels and is right to about eps ||P_0|| ||x||^2, the forward cost to about
    eps sqrt(||P_0|| ||x||^2 J*) (its states cancel, its sum does not), and the plan's own error enters it only at
    second order."""
    if states is None:
        forward, bound = plan_cost(system, U, protocol, weights)
        if np.isfinite(forward) and not bound <= PLAN_COST_RTOL * forward:
            raise NumericalError(
                f"method '{method}': the forward cost of its plan, the referee of its self-check, is not resolved "
                f"({forward:.6g}, which rounding may move by up to {bound:.2g}): the open-loop growth of A over the "
                "horizon amplifies a fixed plan's rounding; use method='recursion' (checked on the states its law "
                "rolls out)")
    else:
        forward = recursion_cost(system, U, protocol, weights, states)
    _agree(system, protocol, closed, forward, method, atol)
    return forward


def _agree(system: System, protocol: str, closed: float, forward: float, method: str, atol: float = 0.0) -> None:
    """Raise NumericalError unless ``closed`` is nonnegative and agrees with the referee ``forward`` to
    ``SELF_CHECK_RTOL`` (plus ``atol``), both finite."""
    if not (np.isfinite(forward) and np.isfinite(closed)):
        raise NumericalError(
            f"the {protocol}-like expected cost exceeds the double-precision range (about 1e308): the "
            "open-loop prediction of an unstable plant over this horizon, or inputs/states that large")
    if abs(closed - forward) > SELF_CHECK_RTOL * forward + atol or closed < 0:
        raise NumericalError(
            f"method '{method}': the closed-form cost {closed:.10g} and the forward cost of its own plan "
            f"{forward:.10g} differ by {abs(closed - forward) / max(forward, 1e-300):.1e} (relative): double "
            f"precision cannot resolve this problem ({weight_spread(system)}); rescale the weights")


def weight_spread(system: System) -> str:
    """Which weights span how much: the usual cause of a failed self-check.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> weight_spread(s).split(": ")[1].split(";")[0]          # all weights are 1
    'the weights span 1.0e+00'
    """
    w = np.linalg.eigvalsh(system.state_weights)
    positive = w[w > 0]
    psi = system.input_weights
    if not positive.size:
        return f"input weights span {psi.max() / psi.min():.1e}"
    hi, lo = max(positive.max(), psi.max()), min(positive.min(), psi.min())
    return (f"state weights up to {positive.max():.3g} and input weights down to {psi.min():.3g}: the weights "
            f"span {hi / lo:.1e}; condition estimate {condition_estimate(system):.1e}")


def check_inputs(system: System, inputs: npt.ArrayLike) -> np.ndarray:
    """The N×m input sequence as a float array, or :class:`InputError` naming ``inputs``.

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


def hessian_factor(pred: Prediction, protocol: str, v: np.ndarray | None = None,
                   rows: np.ndarray | None = None, block: np.ndarray | None = None) -> np.ndarray:
    """G of Theorem 1 (the Hessian of J is Vbar G): eq:opt-law-1, and eq:opt-law-2 for the UDP-like protocol.

    .. math:: G = \\Omega_g \\bar V + \\Psi\\ [+\\ \\Omega_d (I - \\bar V)]

    ``v``: the stacked delivery probabilities, (N m,) or a batch (P, N m) (default: the prediction's Vbar);
    the result is (N m, N m) or (P, N m, N m). ``rows``: a boolean mask of the entries to keep, for the
    principal block G[rows, rows] alone (one point; the line's fixed channels; or the ascending indices of
    those entries); ``block``: Omega_g[rows, rows]
    where the caller keeps it (the line's, per channel: the fancy index costs more than the product). The one
    dense form of the Hessian (closed_form, the evaluator's batches, its pointwise and line paths, the cost difference).
    O(P (N m)^2).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> p = prediction(s)                          # Omega_g = [[5, 2], [2, 1]], Vbar = 0.5 I, Psi = I
    >>> hessian_factor(p, "tcp").tolist()          # Omega_g Vbar + Psi
    [[3.5, 1.0], [1.0, 1.5]]
    >>> hessian_factor(p, "udp").tolist()          # + Omega_d (I - Vbar) = diag(2.5, 0.5)
    [[6.0, 1.0], [1.0, 2.0]]
    >>> hessian_factor(p, "udp", np.array([[1.0, 1.0], [0.5, 0.5]]))[1].tolist()    # a batch of two
    [[6.0, 1.0], [1.0, 2.0]]
    """
    v = pred.Vbar if v is None else v
    if rows is not None:
        G = (pred.Omega_g[np.ix_(rows, rows)] if block is None else block) * v[rows]
        G.flat[:: G.shape[0] + 1] += hessian_diagonal(pred, protocol, v)[rows]
        return G
    k = v.shape[-1]
    G = pred.Omega_g * v[..., None, :]
    G.reshape(*v.shape[:-1], k * k)[..., :: k + 1] += hessian_diagonal(pred, protocol, v)
    return G


def hessian_diagonal(pred: Prediction, protocol: str, v: np.ndarray) -> np.ndarray:
    """What G adds to ``Omega_g Vbar`` on its diagonal: ``Psi + [UDP] Omega_d (1 - v)``, shaped like v. O(N m).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> hessian_diagonal(prediction(s), "udp", np.array([0.5, 0.5])).tolist()    # 1 + (5, 1) / 2
    [3.5, 1.5]
    """
    return pred.Psi + (pred.Omega_d * (1.0 - v) if protocol == "udp" else 0.0)


def loss_variance_term(pred: Prediction, u: np.ndarray) -> float:
    """U' Vbar Omega_d (I - Vbar) U: what the UDP-like cost adds to the TCP-like one (Lemma 1, eq:UDP-err).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> loss_variance_term(prediction(s), np.array([1.0, 1.0]))     # 0.5 * 0.5 * (5 + 1)
    1.5
    """
    v = pred.Vbar
    return float(np.sum(v * pred.Omega_d * (1.0 - v) * u * u))


def _constant(system: System, pred: Prediction) -> float:
    x = system.x0
    return float(x @ (system.initial_weight + pred.Omega_p) @ x) + pred.noise_term


def dense_cost(system: System, U: np.ndarray, protocol: str, pred: Prediction | None = None) -> float:
    """J(U) by the paper's dense quadratic form (eq:opt-lqg-simplest, with eq:plant4 for E[U' Y' Psi Y U]).

    Time O((N n)^2 N m) to build, O((N m)^2) to evaluate.
    """
    pred = prediction(system) if pred is None else pred
    u = U.ravel()
    v = pred.Vbar
    vu = v * u
    value = _constant(system, pred) + 2.0 * vu @ (pred.Omega_gp @ system.x0)
    value += vu @ pred.Omega_g @ vu + np.sum(v * pred.Psi * u * u)
    if protocol == "udp":
        value += loss_variance_term(pred, u)
    return float(value)


def refuse_correlated(system: System, protocol: str) -> None:
    """Refuse the UDP-like expected cost of a system behind a Gilbert–Elliott chain: its losses are
    correlated over time, so J_udp on the chain's predicted mu_t is not the expected cost of anything
    (pendulum_bursty: 15706 against 51735 for the same plan). The TCP-like cost holds first moments
    only and stays exact. O(1).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.3]))
    >>> refuse_correlated(s, "tcp")        # nothing to refuse
    >>> refuse_correlated(s, "udp")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: channel: a Gilbert-Elliott channel's losses are correlated, ...
    """
    if system.channel is not None and protocol == "udp":
        raise InputError("channel", "a Gilbert-Elliott channel's losses are correlated, so the UDP-like cost on its "
                                    "predicted mu_t is not the expected cost: use packetloss_cvx.lq.markov_cost."
                                    "exact_closed_form / exact_cost for the exact values, or "
                                    "system.with_mu(system.mu_schedule) for the paper's plug-in law")


@blas_limited
def expected_cost(system: System, inputs: npt.ArrayLike, protocol: str, method: str = "auto") -> float:
    """Expected cost J(U) of the N×m input sequence ``inputs`` as the paper defines it.

    .. math:: J_{udp}(U) = J_{tcp}(U) + U'\\bar V\\Omega_d(I-\\bar V)U

    ``method="auto"`` (the default) and ``"recursion"`` roll out the mean state and add its
    nonnegative stage costs (O(N n^3), no cancellation); ``"dense"`` evaluates the quadratic
    form of eq:opt-lqg-simplest (O((N n)^2 N m)), refused where its condition estimate says
    it would lose digits, and checked against the forward pass.
    Either way the value is returned only where the forward pass is resolved to ``PLAN_COST_RTOL``
    (relative; :func:`~packetloss_cvx.lq.recursion.plan_cost` bounds its error a posteriori): on an unstable plant
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
        _agree(system, protocol, dense, value, "dense")
        return dense
    return value


def _eigs(system: System, K: np.ndarray) -> np.ndarray:
    return np.linalg.eigvals(system.A - system.B @ K)


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
    system = check_system(system)
    protocol = check_protocol(protocol)
    refuse_correlated(system, protocol)
    weights = lyapunov_weights_if_needed(system, protocol, method)
    _, dense = dense_or_recursion(system, method, weights, lambda: _dense_solution(system, protocol, weights))
    return _recursion_solution(system, protocol, weights) if dense is None else dense


def lyapunov_weights_if_needed(system: System, protocol: str, method: str) -> tuple[np.ndarray, float]:
    """udp_variance_weights(system), or zeros where they cannot enter the answer: the recursion is taken
    without a condition estimate (``"recursion"``, or ``"auto"`` beyond ``AUTO_DENSE_MAX``), there is no
    noise (the noise term is 0), and the UDP-like variance weight ``(1 - mu) d`` vanishes (TCP-like, or every
    mu = 1). Saves the O(N n^3) Lyapunov sums of a long perfect-channel horizon. O(N m) otherwise.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> lyapunov_weights_if_needed(s, "udp", "recursion")[0].tolist()     # mu = 1: (1 - mu) d = 0
    [[0.0], [0.0]]
    >>> lyapunov_weights_if_needed(s, "udp", "dense")[0].tolist()         # the condition estimate needs them
    [[5.0], [1.0]]
    """
    recursion = method == "recursion" or (method == "auto" and system.horizon * system.m > AUTO_DENSE_MAX)
    unused = protocol == "tcp" or bool(np.all(system.mu_schedule == 1.0))
    if recursion and unused and not np.any(system.noise_cov != 0):
        return np.zeros((system.horizon, system.m)), 0.0
    return udp_variance_weights(system)


def dense_or_recursion(system: System, method: str, weights: tuple[np.ndarray, float],
                       build: Callable[[], T], dense_max: int = AUTO_DENSE_MAX) -> tuple[str, T | None]:
    """The one method chooser and its fallback, for :func:`closed_form`,
    :class:`~packetloss_cvx.lq.evaluator.CostEvaluator` and the Markov closed form alike (``dense_max``: the
    caller's crossover, :func:`pick_method`): :func:`pick_method`; on ``"dense"``,
    :func:`refuse_dense` then ``build()``. Under ``"auto"`` a NumericalError of either (a dense form that
    would lose or lost its digits) falls back: ``("recursion", None)``, the recursion not depending on
    the conditioning; under ``"dense"`` it is raised. Returns ``(method, what build returned or None)``.
    O(N n^3) (the condition estimate) plus ``build``.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> dense_or_recursion(s, "auto", udp_variance_weights(s), lambda: "built")
    ('dense', 'built')
    >>> def lost(): raise NumericalError("a residual too large")
    >>> dense_or_recursion(s, "auto", udp_variance_weights(s), lost)
    ('recursion', None)
    """
    choice = pick_method(system, method, weights, dense_max)
    if choice == "recursion":
        return choice, None
    try:
        refuse_dense(system, weights)
        return choice, build()
    except NumericalError:
        if method != "auto":
            raise
        return "recursion", None


def _recursion_solution(system: System, protocol: str, weights: tuple[np.ndarray, float]) -> Solution:
    gain, P0, noise, U, X = optimal_plan(system, protocol, weights)
    x = system.x0
    cost = float(x @ (system.initial_weight + P0) @ x) + noise
    scale = SELF_CHECK_ATOL * float(np.linalg.norm(P0, 2)) * float(x @ x)
    cost = _self_checked(system, protocol, cost, U, "recursion", weights, atol=scale, states=X[1:])
    return Solution(protocol=protocol, cost=cost, inputs=U, gain=gain,
                    closed_loop_eigenvalues=_eigs(system, gain), method="recursion")


def _dense_solution(system: System, protocol: str, weights: tuple[np.ndarray, float]) -> Solution:
    pred = prediction(system)
    G = hessian_factor(pred, protocol)
    F = solve_checked(G, pred.Omega_gp, "G^-1 Omega_gp (Theorem 1)")     # (N m)×n
    u = -F @ system.x0
    g = pred.Omega_gp @ system.x0
    cost = _constant(system, pred) + float(g @ (pred.Vbar * u))             # C - g' Vbar G^{-1} g
    U = u.reshape(system.horizon, system.m)
    cost = _self_checked(system, protocol, cost, U, "dense", weights)
    gain = F[: system.m]
    return Solution(protocol=protocol, cost=cost, inputs=U, gain=gain,
                    closed_loop_eigenvalues=_eigs(system, gain), method="dense")


def paper_optimal_cost(system: System, protocol: str) -> float:
    """The optimal cost exactly as printed in eq:TCP-opt-cost / eq:UDP-opt-cost.

    .. math:: C - x'\\Omega_{gp}' G^{-1}\\bar V \\Omega_{gp} x

    Kept for the audit: it equals the true minimum only when Vbar commutes with
    G (e.g. one shared channel, Vbar = nu I). Use :func:`closed_form` for the cost.

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
    return _constant(system, pred) - float(g @ np.linalg.solve(G, pred.Vbar * g))
