"""§III–IV: how the two protocols' optima are ordered (Theorem 2, Corollary 1) and how they
move with the channel (Theorem 3, Corollary 2)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from ..errors import NumericalError
from ..linalg import frobenius
from ..lq import difference
from ..lq.costs import closed_form, expected_cost
from ..lq.evaluator import CostEvaluator
from ..lq.prediction import prediction
from ..model.system import System
from ..results import ClaimResult, Solution
from ..threads import blas_limited
from ..tolerances import CROSS_CHECK_FLOOR, RESOLVED_MIN
from .context import Context, interior
from .evaluate import cost_scale, evaluate, resolved

__all__ = ["case_ids", "corollary_1", "corollary_2", "optimal_plan", "theorem_2", "theorem_3"]


def optimal_plan(ctx: Context, system: System, protocol: str, case: bool | None = None) -> Solution:
    """Theorem 1's plan at the system's own channel: from the audit's cached evaluator for one of its
    cases (built once, shared by the claims,
    [`CostEvaluator.optimum`][packetloss_cvx.lq.evaluator.CostEvaluator.optimum]), from
    [`closed_form`][packetloss_cvx.lq.costs.closed_form] for any other system (a shrunk counterexample's candidates,
    computed as before). Equal to rounding either way (tests: 1e-12). ``case``: whether ``system`` is one of the cases,
    when the caller knows (`case_ids`), else looked up.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[1.0], x0=[1])
    >>> ctx = Context(paper={}, random=[s], seed=0)
    >>> plan = optimal_plan(ctx, s, "tcp")             # min (1 + u)^2 + u^2 at u = -1/2
    >>> plan is optimal_plan(ctx, s, "tcp"), bool(np.isclose(plan.cost, 0.5))
    (True, True)
    """
    if _is_case(ctx, system) if case is None else case:
        return ctx.evaluator(system, protocol).optimum()
    return closed_form(system, protocol)


def case_ids(ctx: Context) -> set[int]:
    """The ``id`` of each of the audit's cases: they live as long as ``ctx``, so no other object shares
    one while it does (``id(system) in case_ids(ctx)`` says whether ``system`` is a case). O(cases).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[1.0], x0=[1])
    >>> ids = case_ids(Context(paper={}, random=[s], seed=0))
    >>> id(s) in ids, id(s.with_mu([0.5])) in ids
    (True, False)
    """
    return {id(case) for case in ctx.cases}


def _is_case(ctx: Context, system: System) -> bool:
    """Whether ``system`` is one of the audit's cases: an evaluator cached for it says so in O(1) (only
    cases get one here), else a scan of the cases. O(1) or O(cases)."""
    return ((id(system), "tcp") in ctx.evaluators or (id(system), "udp") in ctx.evaluators
            or any(system is case for case in ctx.cases))


@blas_limited
def theorem_2(ctx: Context) -> ClaimResult:
    """`J*_udp` - `J*_tcp` > 0 for interior channels (Theorem 2, from eq:G-inequality), by the
    cancellation-free difference.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> ctx = Context(paper={}, random=[s], seed=0)
    >>> r = theorem_2(ctx)                           # (J*_udp - J*_tcp) / J*_tcp = (3/4 - 2/3) / (2/3)
    >>> r.verdict, bool(np.isclose(r.worst, 1 / 8))
    ('holds', True)
    """
    cases = case_ids(ctx)

    def margin(s: System) -> float | None:
        if not interior(s) or not np.any(prediction(s).Omega_gp @ s.x0):
            return None  # Omega_gp x0 = 0: both optima are C, the trivial equality
        # the cancellation-free difference: a strict inequality needs value > 0, not >= 0
        gap = difference.cost_difference(s)
        if not abs(gap) >= RESOLVED_MIN:   # a product of three small factors: 0.0 here may be an underflow
            raise NumericalError(f"J*_udp - J*_tcp is {gap:.3g}, below {RESOLVED_MIN:.1e}: at this scale double "
                                 "precision does not resolve its sign, so the case is undecided")
        cost = resolved(optimal_plan(ctx, s, "tcp", id(s) in cases).cost, "J*_tcp")
        value = gap / max(abs(cost), CROSS_CHECK_FLOOR * cost_scale(s))
        return value if value > 0 else min(value, -1e-300)
    return evaluate("theorem-2", ctx, ctx.cases, margin,
                    "margin = (J*_udp - J*_tcp)/J*_tcp, the difference computed without cancellation "
                    "(difference.cost_difference); a difference below 1e-292 in size (a product of three factors "
                    "that underflows for weights near 1e-100 against input weights of one) is undecided. Holds: "
                    "J_udp(U) >= J_tcp(U) for every U (the extra "
                    "term is PSD), so the minima are ordered. The paper's proof orders non-symmetric matrices "
                    "(G^-1 Vbar) and uses the wrong cost formula. Cases with Omega_gp x0 = 0 (e.g. x0 = 0), where "
                    "both optima equal C, are skipped: there the strict inequality fails trivially.")


@blas_limited
def corollary_1(ctx: Context) -> ClaimResult:
    """||`U*_udp`|| < ||`U*_tcp`|| for interior channels.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> ctx = Context(paper={}, random=[s], seed=0)
    >>> r = corollary_1(ctx)                         # ||U*_tcp|| = 2/3, ||U*_udp|| = 1/2
    >>> r.verdict, bool(np.isclose(r.worst, 1 / 4))
    ('holds', True)
    """
    cases = case_ids(ctx)

    def margin(s: System) -> float | None:
        if not interior(s):
            return None
        a = resolved(frobenius(optimal_plan(ctx, s, "tcp", id(s) in cases).inputs), "||U*_tcp||")
        b = resolved(frobenius(optimal_plan(ctx, s, "udp", id(s) in cases).inputs), "||U*_udp||")
        return (a - b) / a if a > 0 else (0.0 if b == 0 else -np.inf)     # a = b = 0: Omega_gp x0 = 0, as before
    return evaluate("corollary-1", ctx, ctx.cases, margin,
                    "margin = (||U*_tcp|| - ||U*_udp||)/||U*_tcp||. The proof's step 'G_G^-1 < G_F^-1 implies "
                    "G_G^-1 g < G_F^-1 g' applies a matrix order to vectors; it is not a valid inference.")


@blas_limited
def theorem_3(ctx: Context) -> ClaimResult:
    """`J*(mu1)` > `J*(mu2)` for mu2 > mu1 entrywise, both protocols (Theorem 3, eq:monotonic-cost-pos-def).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> ctx = Context(paper={}, random=[s], seed=0)
    >>> theorem_3(ctx).verdict                       # J*_tcp = 1/(1 + mu), J*_udp = 1 - mu/2 both fall as mu rises
    'holds'
    """
    cases = case_ids(ctx)

    def margin(s: System) -> float | None:
        rng = np.random.default_rng(ctx.seed + 3)
        mu1 = np.clip(s.mu_schedule, 0.01, 0.99)
        mu2 = mu1 + (1 - mu1) * rng.uniform(0.1, 0.9, mu1.shape)
        # J* = C - D(mu) with C = J(U = 0) independent of mu: compare the part that depends on mu
        C = expected_cost(s, np.zeros((s.horizon, s.m)), "tcp")
        worst = np.inf
        case = id(s) in cases
        for p in ("tcp", "udp"):
            if case:      # the case's cached evaluator: J* at two channels without rebuilding anything
                j1, j2 = ctx.evaluator(s, p).cost(mu1), ctx.evaluator(s, p).cost(mu2)
            else:
                j1, j2 = closed_form(s.with_mu(mu1), p).cost, closed_form(s.with_mu(mu2), p).cost
            D2 = C - j2
            if D2 <= 0 or abs(j1 - j2) <= 1e-12 * C:
                return None   # the cost does not depend on mu here, or not beyond double precision
            worst = min(worst, (j1 - j2) / D2)
        return worst
    return evaluate("theorem-3", ctx, ctx.cases, margin,
                    "mu2 > mu1 entrywise (stationary and non-stationary), margin = (J*(mu1) - J*(mu2)) / (C - "
                    "J*(mu2)), C = J(U = 0) the part that does not depend on mu; cases where J* does not depend on "
                    "mu, or only below double precision (1e-12 C), are skipped. "
                    "Holds: with Z = Vbar U the costs are C + 2Z'g + Z'Omega_g Z + Z'(Psi + Omega_d (I - Vbar)) "
                    "Vbar^-1 Z, whose weights fall as mu rises.")


@blas_limited
def corollary_2(ctx: Context) -> ClaimResult:
    """At equal optimal cost the TCP-like protocol needs a smaller shared delivery probability.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> ctx = Context(paper={}, random=[s], seed=0)
    >>> corollary_2(ctx).verdict                     # 1/(1 + nu2) = 1 - nu1/2 at nu2 = nu1/(2 - nu1) < nu1
    'holds'
    """
    def margin(s: System) -> float | None:
        rng = np.random.default_rng(ctx.seed + 4)
        nu1 = float(rng.uniform(0.05, 0.95))
        tcp = ctx.evaluator(s, "tcp") if s in ctx.cases else CostEvaluator(s, "tcp")
        udp = ctx.evaluator(s, "udp") if s in ctx.cases else CostEvaluator(s, "udp")
        target = udp.cost(np.full(s.m, nu1))          # J* on a shared channel, structure cached

        def gap(nu: float) -> float:
            return tcp.cost(np.full(s.m, float(nu))) - target

        if gap(0.0) <= 0 or gap(nu1) >= 0:
            return None
        nu2 = brentq(gap, 0.0, nu1, xtol=1e-14)
        return (nu1 - nu2) / nu1
    return evaluate("corollary-2", ctx, ctx.cases, margin,
                    "Shared channel nu1 for UDP-like; nu2 solves J*_tcp(nu2) = J*_udp(nu1) (Brent); "
                    "margin = (nu1 - nu2)/nu1. Holds (Theorems 2 and 3 with continuity); cases where x0 gives "
                    "equal costs are skipped.")
