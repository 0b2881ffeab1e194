"""The Theorem-1 policy: which exact form answers (dense or recursion), run it, check it once, return the result.

`solve` is [`closed_form`][packetloss_cvx.lq.costs.closed_form]'s whole pipeline: the system's
`Structure` (built once per structure), `choose` (the one method chooser and
its fallback, also for [`CostEvaluator`][packetloss_cvx.lq.evaluator.CostEvaluator] and the Markov closed form), the
kernel (`dense_law` or [`optimal_plan`][packetloss_cvx.lq.recursion.optimal_plan]), and
`self_check`: the one test of a closed-form cost against the forward cost of its own plan (a sum of
nonnegative terms, free of cancellation), which every closed form (dense, recursion, batched, pointwise, Markov)
passes before its number is returned.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TypeVar

import numpy as np

from ..budgets import check, dense_bytes, gib_text
from ..errors import InputError, NumericalError
from ..model.system import System
from ..results import Solution
from ..tolerances import DENSE_MAX_CONDITION, PLAN_COST_RTOL, SELF_CHECK_ATOL, SELF_CHECK_RTOL
from .dense import dense_law
from .recursion import optimal_plan, plan_cost, recursion_cost
from .structure import condition_from, structure_of

__all__ = ["AUTO_DENSE_MAX", "choose", "lyapunov_weights_if_needed", "pick_method", "refuse_correlated",
           "refuse_dense", "self_check", "solve", "weight_spread"]

#: ``method="auto"`` uses the dense form up to this many decision variables N*m
#: (measured crossover for n = 4, m = 2 between N*m = 160 and 200: docs/performance.md),
#: and only while the condition estimate stays below ``tolerances.DENSE_MAX_CONDITION``.
AUTO_DENSE_MAX = 160

T = TypeVar("T")


def solve(system: System, protocol: str, method: str = "auto") -> Solution:
    """Theorem 1 for a validated system and protocol ([`closed_form`][packetloss_cvx.lq.costs.closed_form], which
    validates): the method chosen (`choose`), run, self-checked (`self_check`) and returned as a Solution whose cost
    is the forward one. Time as closed_form's.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> sol = solve(s, "tcp")                      # min (1 + u)^2 + u^2 at u = -1/2
    >>> sol.method, sol.cost, sol.inputs.tolist()
    ('dense', 0.5, [[-0.5]])
    """
    refuse_correlated(system, protocol)
    weights = lyapunov_weights_if_needed(system, protocol, method)
    _, dense = choose(system, method, weights, lambda: _dense_solution(system, protocol, weights))
    return _recursion_solution(system, protocol, weights) if dense is None else dense


def _recursion_solution(system: System, protocol: str, weights: tuple[np.ndarray, float]) -> Solution:
    gain, P0, noise, U, X = optimal_plan(system, protocol, weights)
    x = system.x0
    cost = float(x @ (system.initial_weight + P0) @ x) + noise
    scale = SELF_CHECK_ATOL * float(np.linalg.norm(P0, 2)) * float(x @ x)
    forward = recursion_cost(system, U, protocol, weights, X[1:])
    self_check(system, protocol, cost, forward, "recursion", atol=scale)
    return Solution(protocol=protocol, cost=forward, inputs=U, gain=gain,
                    closed_loop_eigenvalues=_eigs(system, gain), method="recursion")


def _dense_solution(system: System, protocol: str, weights: tuple[np.ndarray, float]) -> Solution:
    cost, U, F = dense_law(system, protocol)
    forward, bound = plan_cost(system, U, protocol, weights)
    if np.isfinite(forward) and not bound <= PLAN_COST_RTOL * forward:
        raise NumericalError(
            f"method 'dense': the forward cost of its plan, the referee of its self-check, is not resolved "
            f"({forward:.6g}, which rounding may move by up to {bound:.2g}): the open-loop growth of A over the "
            "horizon amplifies a fixed plan's rounding; use method='recursion' (checked on the states its law "
            "rolls out)")
    self_check(system, protocol, cost, forward, "dense")
    gain = F[: system.m]
    return Solution(protocol=protocol, cost=forward, inputs=U, gain=gain,
                    closed_loop_eigenvalues=_eigs(system, gain), method="dense")


def _eigs(system: System, K: np.ndarray) -> np.ndarray:
    return np.linalg.eigvals(system.A - system.B @ K)


def self_check(system: System, protocol: str, closed: np.ndarray | float, forward: np.ndarray | float, method: str,
               atol: np.ndarray | float = 0.0, raise_: bool = True) -> np.ndarray | bool:
    """The self-check of every closed form: which points' ``closed`` costs are finite, nonnegative and within
    ``SELF_CHECK_RTOL`` (plus ``atol``, the rounding scale of x'P_0 x where a caller has it) of ``forward``, the
    forward cost of their own plans (the referee: a sum of nonnegative terms, finite). Scalars or arrays (points,).
    With ``raise_`` (default) a point that fails raises NumericalError: beyond the double range, or naming the
    disagreement and the weights' spread (`weight_spread`) of ``system``; otherwise the boolean mask is
    returned (a bool for Python floats). ``closed`` (x'P_0 x, or C - g'Vbar G^-1 g) cancels and is right to about
    eps ||P_0|| ||x||^2, the forward cost to about eps sqrt(||P_0|| ||x||^2 J*), and the plan's own error enters
    it only at second order:
    the forward cost is the one to report. O(points).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> self_check(s, "tcp", np.array([0.5, 0.6, -0.0]), np.array([0.5, 0.5, 0.0]), "dense", raise_=False).tolist()
    [True, False, True]
    >>> self_check(s, "tcp", 0.6, 0.5, "dense")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.NumericalError: method 'dense': the closed-form cost 0.6 and the forward cost of its own ...
    """
    if type(closed) is float and type(forward) is float and type(atol) is float:      # one point: no arrays
        if (math.isfinite(closed) and math.isfinite(forward) and closed >= 0
                and abs(closed - forward) <= SELF_CHECK_RTOL * forward + atol):
            return True
        if not raise_:
            return False
    closed, forward = np.asarray(closed, dtype=float), np.asarray(forward, dtype=float)
    finite = np.isfinite(closed) & np.isfinite(forward)
    with np.errstate(invalid="ignore"):
        agree = finite & (np.abs(closed - forward) <= SELF_CHECK_RTOL * forward + atol) & (closed >= 0)
    if not raise_ or agree.all():
        return agree
    if not finite.all():
        raise NumericalError(
            f"the {protocol}-like expected cost exceeds the double-precision range (about 1e308): the "
            "open-loop prediction of an unstable plant over this horizon, or inputs/states that large")
    k = int(np.flatnonzero(~agree.ravel())[0])
    c, f = float(closed.ravel()[k]), float(forward.ravel()[k])
    raise NumericalError(
        f"method '{method}': the closed-form cost {c:.10g} and the forward cost of its own plan {f:.10g} differ by "
        f"{abs(c - f) / max(f, 1e-300):.1e} (relative): double precision cannot resolve this problem "
        f"({weight_spread(system)}); rescale the weights")


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
            f"span {hi / lo:.1e}; condition estimate {structure_of(system).condition:.1e}")


def pick_method(system: System, method: str, weights: tuple[np.ndarray, float] | None = None,
                dense_max: int = AUTO_DENSE_MAX) -> str:
    """Resolve ``"auto"`` to the faster exact path: ``"dense"`` for small (N m <= ``dense_max``, the caller's
    measured crossover), well-conditioned problems, ``"recursion"`` otherwise. Time O(N n^3) (the condition
    estimate) the first time for a structure.

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
        return "dense" if _condition(system, weights) <= DENSE_MAX_CONDITION else "recursion"
    if method not in ("dense", "recursion"):
        raise InputError("method", f"expected 'auto', 'dense' or 'recursion', found {method!r}")
    return method


def _condition(system: System, weights: tuple[np.ndarray, float] | None) -> float:
    """The structure's condition estimate, or the one of ``weights`` where they are not its own. O(1) kept."""
    structure = structure_of(system)
    if weights is None or weights is structure.variance_weights:
        return structure.condition
    return condition_from(structure, weights[0])


def refuse_dense(system: System, weights: tuple[np.ndarray, float]) -> None:
    """Raise before building anything dense that would not fit or would lose the answer.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> refuse_dense(s, structure_of(s).variance_weights) is None       # small and well conditioned: no objection
    True
    """
    N, n, m = system.horizon, system.n, system.m
    needed = dense_bytes(N, n, m)
    check("memory_bytes", needed, "method", f"method 'dense' for N = {N}, n = {n}, m = {m} (about {gib_text(needed)})",
          instead="use method='recursion' (exact, O(N) memory; --method recursion)")
    kappa = _condition(system, weights)
    if kappa > DENSE_MAX_CONDITION:
        raise NumericalError(
            f"method 'dense': the condition estimate (trace Omega_g + max Psi)/min Psi = {kappa:.2g} exceeds "
            f"{DENSE_MAX_CONDITION:.0e}, so the dense formulas would lose their digits (unstable plant over a "
            f"long horizon, or weights of very different sizes); use method='recursion'")


def choose(system: System, method: str, weights: tuple[np.ndarray, float],
           build: Callable[[], T], dense_max: int = AUTO_DENSE_MAX) -> tuple[str, T | None]:
    """The one method chooser and its fallback, for `solve`,
    [`CostEvaluator`][packetloss_cvx.lq.evaluator.CostEvaluator] and the Markov closed form alike (``dense_max``: the
    caller's crossover, `pick_method`): `pick_method`; on ``"dense"``,
    `refuse_dense` then ``build()``. Under ``"auto"`` a NumericalError of either (a dense form that
    would lose or lost its digits) falls back: ``("recursion", None)``, the recursion not depending on
    the conditioning; under ``"dense"`` it is raised. Returns ``(method, what build returned or None)``.
    O(N n^3) (the condition estimate) plus ``build``.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> choose(s, "auto", structure_of(s).variance_weights, lambda: "built")
    ('dense', 'built')
    >>> def lost(): raise NumericalError("a residual too large")
    >>> choose(s, "auto", structure_of(s).variance_weights, lost)
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


def lyapunov_weights_if_needed(system: System, protocol: str, method: str) -> tuple[np.ndarray, float]:
    """The structure's variance weights, or zeros where they cannot enter the answer: the recursion is taken
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
    structure = structure_of(system)
    recursion = method == "recursion" or (method == "auto" and system.horizon * system.m > AUTO_DENSE_MAX)
    unused = protocol == "tcp" or bool(np.all(system.mu_schedule == 1.0))
    if recursion and unused and not structure.has_noise:
        return np.zeros((system.horizon, system.m)), 0.0
    return structure.variance_weights


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
                                    "predicted mu_t is not the expected cost: use packetloss_cvx.markov."
                                    "exact_closed_form / exact_cost for the exact values, or "
                                    "system.with_mu(system.mu_schedule) for the paper's plug-in law")
