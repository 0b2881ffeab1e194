"""zero-vs-hold-paper-systems (the paper's remark): the paper models a lost packet as a zero input and remarks in
passing that the actuator could hold its last input instead. Made precise: does zeroing lose nothing against
holding, i.e. is the optimal TCP-like law under zero (closedloop.actuator_design: the modified Riccati equation)
no more expensive than the optimal TCP-like law under hold (the coupled Riccati equation over the state and the
held input)? On each paper system at its own channel, the infinite-horizon cost from x0 (the paper's systems
have no noise) of both optima; margin ``(J_hold - J_zero) / J_zero``. Schenato (IEEE TAC 2009) found that neither
strategy dominates in general."""

from __future__ import annotations

from ..closedloop.actuator_design import actuator_dp
from ..model.system import System
from ..results import ClaimResult
from .context import Context
from .evaluate import Tally

__all__ = ["STATEMENT", "zero_vs_hold"]

STATEMENT = ("(The paper's remark that the actuator could hold its last input instead of applying zero.) On the "
             "paper's systems at their channels, applying zero on a loss loses nothing against holding: the optimal "
             "TCP-like law under zero costs no more than the optimal TCP-like law under hold (infinite-horizon cost "
             "from x0).")


def _costs(system: System) -> tuple[float, float]:
    """The optimal TCP-like laws' costs from x0, zero and hold. O(iterations (n + m)^3)."""
    return actuator_dp(system, "zero").initial, actuator_dp(system, "hold").initial


def zero_vs_hold(ctx: Context) -> ClaimResult:
    """The check on the paper's systems (the random cases are not run).

    Examples
    --------
    >>> from packetloss_cvx.claims.context import paper_systems
    >>> r = zero_vs_hold(Context(paper=paper_systems(), random=[], seed=0))
    >>> r.verdict, r.checked, r.violations
    ('fails', 2, 1)
    """
    tally = Tally()
    rows = []
    counterexample = None
    for name, s in ctx.paper.items():
        def margin(case: System) -> float:
            zero, hold = _costs(case)
            return (hold - zero) / zero
        found = tally.run(margin, s, ctx.label(s))
        if found is not None:
            zero, hold = _costs(s)
            rows.append(f"{name}: zero {zero:.6g}, hold {hold:.6g} ({100 * (hold - zero) / zero:+.2f} %)")
            if found < 0 and counterexample is None:
                counterexample = s.to_dict()
    note = ("Optimal TCP-like laws (closedloop.actuator_design; hold: the coupled Riccati equation over (x, w), w the "
            "held input), infinite-horizon cost x0'P x0 from the system's x0 at its channel; margin = (J_hold - "
            "J_zero) / J_zero: " + "; ".join(rows) + ". Neither strategy dominates: holding is cheaper on the "
            "pendulum, zeroing on the two-actuator system (`packetloss-cvx compare FILE`).")
    return tally.result("zero-vs-hold-paper-systems", STATEMENT, note, counterexample)
