"""What a loop attains at the paper's designs: does the TCP-like allocation M* (eq:opt_M, ``J*_tcp(M*) <= alpha``)
give a loop that meets alpha, and is the acknowledgement link's break-even price on the paper's costs what the link
is worth?

The paper's ``J*_tcp`` is a first-moment value (docs/claims.md, expected-cost-tcp); the least expected cost any
TCP-like causal law reaches over the horizon is the finite-horizon dynamic programme with acknowledgements
([`tcp_attainable_cost`][packetloss_cvx.allocation.attainable.tcp_attainable_cost]), the *attainable* cost. Both
claims compare the paper's design with that cost, on the same cases (`design_cases`): the two-actuator system at
`ALPHAS` with beta = (1, 1) (the acknowledgement study of ``reproduce``), the pendulum, and the first
`RANDOM_CASES` of the audit's other systems, each of these at the geometric mean of ``J*_tcp`` at mu = 1 and at
mu = 0 with beta = (1, ..., 1).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..errors import InfeasibleError, SolverError
from ..lq.costs import closed_form
from ..model.system import System
from ..results import ClaimResult
from ..tolerances import SELF_CHECK_RTOL
from .context import Context
from .evaluate import CASE_ERRORS, Tally

__all__ = ["ALPHAS", "DESIGN_GAP", "DESIGN_MAX_M", "RANDOM_CASES", "STATEMENTS", "DesignCase", "ack_price_paper_basis",
           "allocation_tcp_meets_alpha", "design_alpha", "design_cases"]

STATEMENTS = {
    "allocation-tcp-meets-alpha": (
        "The TCP-like allocation M* of eq:opt_M (the cheapest mu with J*_tcp(mu) <= alpha) gives a loop whose "
        "expected cost is within alpha: some TCP-like law attains at most alpha at M*."),
    "ack-price-paper-basis": (
        "(Not the paper's: its conclusion's acknowledgement link, priced.) The break-even price of the "
        "acknowledgement link on the paper's costs (the cheapest UDP-like beta'mu with J*_udp <= alpha minus the "
        "cheapest TCP-like beta'mu with J*_tcp <= alpha) is at most what the link is worth to a loop that meets "
        "alpha: no TCP-like loop attaining alpha is cheaper than the paper's TCP-like design."),
}

#: the two-actuator system's cost bounds: the paper's 4.78 and three of reproduce's levels (the acknowledgement
#: study's, ``reproduce.ACK_ATTAINABLE_ALPHAS``)
ALPHAS = (4.78, 8.0, 20.0, 50.0)
#: how many of the audit's other systems (the caller's, then the random ones) are checked: an allocation each (a
#: TCP-like SOCP, about 0.02 s) and for the price an attainable design (a branch and bound, up to 0.3 s)
RANDOM_CASES = 24
#: the relative gap the attainable designs are certified to: the violations found are 0.5 % and more of the
#: price of perfect channels, where a design's lower bound is within 1 % of it
DESIGN_GAP = 1e-2
#: the attainable design is a branch and bound over mu ((1/gap)^(m-1) boxes at worst): channels up to this many
DESIGN_MAX_M = 2


class DesignCase(NamedTuple):
    """One case of both claims: a report's ``label``, the ``system``, the cost bound ``alpha``, the prices ``beta``
    (None, with the reason in ``why``, where no allocation applies)."""

    label: str
    system: System
    alpha: float | None
    beta: np.ndarray
    why: str = ""


def design_alpha(system: System) -> tuple[float | None, str]:
    """The cost bound a case is designed for: ``sqrt(J*_tcp(1) J*_tcp(0))``, the geometric mean of the paper's
    TCP-like cost with every channel perfect and with none, so that the design buys some delivery but not all;
    ``(None, why)`` where the allocation does not apply (a time-varying channel, lossy sensor links, channels
    that change nothing). O(N (n^3 + m^3)).

    Examples
    --------
    One step of x' = x + v u: J*_tcp = 1/(1 + mu), from 1 (mu = 0) to 1/2 (mu = 1):

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> alpha, _ = design_alpha(s)
    >>> bool(np.isclose(alpha, np.sqrt(0.5)))
    True
    """
    if not system.is_stationary:
        return None, "time-varying channel (the allocation needs a stationary one)"
    if system.sensor is not None:
        return None, "lossy sensor links (the attainable cost assumes the state is measured)"
    full = closed_form(system.with_mu(np.ones(system.m)), "tcp").cost
    none = closed_form(system.with_mu(np.zeros(system.m)), "tcp").cost
    if not none > full * (1 + SELF_CHECK_RTOL):
        return None, "the channels change J*_tcp by less than its accuracy"
    return float(np.sqrt(full * none)), ""


def design_cases(ctx: Context) -> list[DesignCase]:
    """The cases of both claims, in order: the two-actuator system at each of `ALPHAS` (beta = (1, 1)), the paper's
    other system (the pendulum) and the first `RANDOM_CASES` other systems at `design_alpha` (beta = 1 per
    channel). O(cases) closed forms.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> [(c.label, round(c.alpha, 4)) for c in design_cases(Context(paper={}, random=[s], seed=0))]
    [('random 1', 0.7071)]
    """
    out = []
    two = ctx.paper.get("two_actuator")
    if two is not None:
        out += [DesignCase(f"two_actuator alpha = {a:g}", two, a, np.ones(two.m)) for a in ALPHAS]
    for name, system in ctx.paper.items():
        if name != "two_actuator":
            alpha, why = design_alpha(system)
            out.append(DesignCase(name, system, alpha, np.ones(system.m), why))
    for system in ctx.random[:RANDOM_CASES]:
        alpha, why = design_alpha(system)
        out.append(DesignCase(ctx.label(system), system, alpha, np.ones(system.m), why))
    return out


def _paper_design(ctx: Context, case: DesignCase) -> Any:
    """The paper's TCP-like allocation of ``case`` (solved once per audit, shared by both claims). Its
    InfeasibleError cannot be a verdict here (alpha lies above J*_tcp with every channel perfect): a SolverError."""
    from ..allocation.api import allocate  # cvxpy (the allocation package): only when these claims run

    key = ("paper tcp design", id(case.system), case.alpha)
    if key not in ctx.cache:
        try:
            ctx.cache[key] = allocate(case.system, "tcp", case.alpha, case.beta)
        except InfeasibleError as err:
            raise SolverError("inconsistent", f"alpha = {case.alpha:g} is above J*_tcp(1), yet the allocation "
                                              f"reports no feasible mu: {err}") from None
    return ctx.cache[key]


def allocation_tcp_meets_alpha(ctx: Context) -> ClaimResult:
    """margin = ``1 + SELF_CHECK_RTOL - attainable(M*) / alpha``, the attainable cost the forward second moments of
    the DP's own law (checked against its backward recursion to SELF_CHECK_RTOL,
    [`AttainableEvaluator`][packetloss_cvx.allocation.attainable.AttainableEvaluator]); the note gives the
    stabilisable verdict at each M* too.

    Examples
    --------
    One step of x' = x + v u: the paper designs on 1/(1 + mu), the best law attains 1 - mu/2, more at every mu in
    (0, 1):

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> r = allocation_tcp_meets_alpha(Context(paper={}, random=[s], seed=0))
    >>> r.verdict, r.outcomes
    ('fails', '-')
    """
    from ..allocation.attainable import AttainableEvaluator

    tally = Tally()
    found: dict[str, tuple[float, float, bool | None]] = {}       # label -> (alpha, attained, stabilisable)

    def margin(case: DesignCase) -> float | None:
        if case.alpha is None:
            return None
        design = _paper_design(ctx, case)
        attained = AttainableEvaluator(case.system).cost(design.mu, checked=True)
        found[case.label] = (case.alpha, attained, design.stabilisable)
        return 1.0 + SELF_CHECK_RTOL - attained / case.alpha

    cases = design_cases(ctx)
    for case in cases:
        tally.run(margin, case, case.label)
    paper = [f"{label.removeprefix('two_actuator ')}: {att:.4g} ({att / a:.3g} alpha)"
             for label, (a, att, _) in found.items() if label.startswith("two_actuator")]
    pendulum = found.get("pendulum")
    others = {label: v for label, v in found.items() if not label.startswith(("two_actuator", "pendulum"))}
    ratios = [att / a for a, att, _ in others.values()]
    unstable = [label for label, (_, _, stab) in found.items() if stab is False]
    noisy_holds = [label for label, (a, att, _) in others.items()
                   if att <= a and np.any(next(c.system for c in cases if c.label == label).noise_cov)]
    held = [label for label, (a, att, _) in others.items() if att <= a]
    note = ("Margin = 1 + 1e-9 - (the attainable cost at M*) / alpha: the least expected cost of any TCP-like law "
            "over the horizon (the finite-horizon DP with acknowledgements, its cost by the forward second moments "
            "of its own law, checked against its backward recursion) at the paper's TCP-like allocation "
            "(allocate(system, 'tcp', alpha, beta), an SOCP certified to 1e-8). Cases: the two-actuator system "
            f"at alpha in {list(ALPHAS)}, beta = (1, 1); the pendulum and the first {RANDOM_CASES} other systems "
            "at alpha = sqrt(J*_tcp(1) J*_tcp(0)), beta = 1 per channel (not applicable: time-varying channels). "
            "Two-actuator system, what the best loop attains at M*: " + "; ".join(paper) + ". ")
    if pendulum is not None:
        note += (f"Pendulum: alpha = {pendulum[0]:.4g}, the loop attains {pendulum[1]:.4g} "
                 f"({pendulum[1] / pendulum[0]:.3g} alpha). ")
    if ratios:
        note += (f"Other systems: attained / alpha from {min(ratios):.3g} to {max(ratios):.3g} over {len(ratios)} "
                 f"cases; within alpha in {len(held)}"
                 + (f", {len(noisy_holds)} of them with process noise (there the DP's feedback beats the paper's "
                    "plan, whose J*_tcp counts the noise open loop)" if held else "") + ". ")
    note += (f"No linear law holds the loop mean-square stable at M* in {len(unstable)} of {len(found)} cases"
             + (f" ({', '.join(unstable[:4])}{', ...' if len(unstable) > 4 else ''})" if unstable else "")
             + ". Design on the attainable cost instead: allocate(..., target='attainable').")
    first = next((c for c, o in zip(cases, tally.outcomes, strict=True) if o == "-"), None)
    return tally.result("allocation-tcp-meets-alpha", STATEMENTS["allocation-tcp-meets-alpha"], note,
                        None if first is None else first.system.to_dict())


def ack_price_paper_basis(ctx: Context) -> ClaimResult:
    """margin = ``(T_paper - T_attainable_lower) / sum(beta)``: the paper's TCP-like design's beta'mu less the proven
    lower bound of the TCP-like design on the attainable cost (``allocate(..., target="attainable")``, certified to
    `DESIGN_GAP`), in units of the price of perfect channels. The UDP-like design is the same on both bases, so the
    break-even prices differ by exactly ``T_attainable - T_paper``: a negative margin proves the paper's price too
    high. Applies where a UDP-like design meets alpha (``J*_udp(1) <= alpha``: then so does an attainable TCP-like
    one, the UDP-like plan being a causal law) and m <= `DESIGN_MAX_M`.

    Examples
    --------
    One step of x' = x + v u at alpha = 0.8: the paper's TCP-like design buys 1/0.8 - 1 = 0.25, a loop attaining 0.8
    needs 1 - mu/2 <= 0.8, mu = 0.4:

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> r = ack_price_paper_basis(Context(paper={}, random=[s], seed=0))
    >>> r.verdict, round(r.worst, 2)              # alpha = sqrt(1/2): 1/alpha - 1 against 2 (1 - alpha)
    ('fails', -0.17)
    """
    from ..allocation.api import allocate

    tally = Tally()
    found: dict[str, tuple[float, float, float]] = {}     # label -> (alpha, paper design, attainable design)

    def margin(case: DesignCase) -> float | None:
        if case.alpha is None or case.system.m > DESIGN_MAX_M:
            return None
        if closed_form(case.system.with_mu(np.ones(case.system.m)), "udp").cost > case.alpha:
            return None
        paper = _paper_design(ctx, case).communication_cost
        try:
            attainable = allocate(case.system, "tcp", case.alpha, case.beta, target="attainable", gap=DESIGN_GAP)
        except InfeasibleError as err:
            raise SolverError("inconsistent", f"J*_udp(1) <= alpha = {case.alpha:g}, yet no TCP-like loop is "
                                              f"found to attain it: {err}") from None
        found[case.label] = (case.alpha, paper, attainable.communication_cost)
        return (paper - attainable.lower_bound) / float(np.sum(case.beta))

    cases = design_cases(ctx)
    for case in cases:
        tally.run(margin, case, case.label)
    rows = []
    two = ctx.paper.get("two_actuator")
    for label, (alpha, paper, attainable) in found.items():
        if not label.startswith("two_actuator"):
            continue
        try:
            udp = allocate(two, "udp", alpha, np.ones(two.m)).communication_cost
        except (*CASE_ERRORS, InfeasibleError) as err:      # the margin does not need it: the note says so
            rows.append(f"alpha = {alpha:g}: the UDP-like design raised {type(err).__name__}")
            continue
        rows.append(f"alpha = {alpha:g}: {udp - paper:.4g} (paper) against {udp - attainable:.4g} (attainable), "
                    f"TCP-like designs {paper:.4g} and {attainable:.4g}")
    others = [(paper, attainable) for label, (_, paper, attainable) in found.items()
              if not label.startswith("two_actuator")]
    dearer = sum(attainable > paper for paper, attainable in others)
    note = ("Margin = (the paper's TCP-like beta'mu - the proven lower bound of the TCP-like design on the attainable "
            "cost) / sum(beta): the UDP-like design is the same on both bases (its J*_udp is the exact expected cost "
            "of its plan), so the paper-basis break-even exceeds the attainable one by exactly the difference of the "
            f"TCP-like designs. The attainable design (allocate(..., target='attainable')) certified to a relative "
            f"gap of {DESIGN_GAP:g}; the cases of allocation-tcp-meets-alpha where a UDP-like design meets alpha and "
            f"m <= {DESIGN_MAX_M}. Two-actuator system, beta = (1, 1), the break-even price (UDP-like design at a "
            "gap of 1e-4): " + "; ".join(rows) + ". ")
    if others:
        note += (f"The pendulum and the other systems: the TCP-like design on the attainable cost is dearer than "
                 f"the paper's in {dearer} of {len(others)} cases. ")
    note += ("Price the link on the attainable basis: allocate FILE --protocol best prints both "
             "(allocation.ack.best_protocol).")
    first = next((c for c, o in zip(cases, tally.outcomes, strict=True) if o == "-"), None)
    return tally.result("ack-price-paper-basis", STATEMENTS["ack-price-paper-basis"], note,
                        None if first is None else first.system.to_dict())
