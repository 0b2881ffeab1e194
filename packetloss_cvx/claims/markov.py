"""plug-in-markov: are the paper's laws, fed the chain's predicted mu_t, still optimal when losses
come in bursts? Each case is put behind Gilbert channels with its own average delivery rates and
burstiness lambda = 1 - p - r in `CORRELATIONS`, and the UDP-like plug-in law's exact expected
cost is compared with the exact minimum ([`packetloss_cvx.lq.markov_cost`][packetloss_cvx.lq.markov_cost]).
"""

from __future__ import annotations

import numpy as np

from ..lq.costs import closed_form
from ..lq.markov_cost import exact_closed_form, exact_cost
from ..model.system import System
from ..model.twins import bursty_twin
from ..results import ClaimResult
from ..tolerances import CROSS_CHECK_COST_RTOL
from .context import Context
from .evaluate import Tally, shrink, simple_systems

__all__ = ["CORRELATIONS", "STATEMENT", "plug_in_markov", "plugin_loss"]

#: The burstiness levels lambda = 1 - p - r each case is checked at (0 would be memoryless).
CORRELATIONS = (0.5, 0.9)

STATEMENT = ("Under bursty Gilbert-Elliott losses (lambda = 1 - p - r in {0.5, 0.9}, the same average delivery "
             "rate) the paper's UDP-like law with the chain's predicted mu_t (the plug-in law) minimises the "
             "expected cost.")


def plugin_loss(system: System, correlation: float | None, plans: dict[bytes, np.ndarray] | None = None
                ) -> float | None:
    """E[cost] of the UDP-like plug-in plan over the exact minimum, minus 1, on the bursty twin of
    ``system`` (on ``system`` itself with ``correlation=None``; None when the minimum is 0: nothing to
    lose). ``plans``: the plug-in plans of ``system``'s twins computed so far, by schedule, filled in here (the
    twins at two burstiness levels of one case usually predict the same mu_t to the bit, and then have the same
    plug-in plan: the paper's law on the same data). Time O(N (D^3 + m^3)), D = n (1 + m) (the augmented
    recursion).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> plugin_loss(s, None), plugin_loss(s, 0.9)    # N = 1: the one input sees the stationary channel either way
    (0.0, 0.0)
    """
    twin = system if correlation is None else bursty_twin(system, correlation)
    exact = exact_closed_form(twin, "udp")
    if exact.cost <= 0:
        return None
    plans = {} if plans is None else plans
    key = twin.mu_schedule.tobytes()
    if key not in plans:
        plans[key] = closed_form(twin.with_mu(twin.mu_schedule), "udp").inputs
    return exact_cost(twin, plans[key], "udp") / exact.cost - 1.0


def _losses(system: System) -> list[float | None]:
    """`plugin_loss` behind the system's own Gilbert-Elliott channel if it has one, else at each of
    `CORRELATIONS` (a plug-in plan computed once per schedule the twins predict)."""
    plans: dict[bytes, np.ndarray] = {}
    return [plugin_loss(system, lam, plans) for lam in ((None,) if system.channel is not None else CORRELATIONS)]


def _margin(system: System, losses: list[float | None] | None = None) -> float | None:
    """A system with its own Gilbert-Elliott channel is checked behind it; any other behind its twins.
    ``losses``: `_losses` of ``system`` when the caller has them."""
    losses = _losses(system) if losses is None else losses
    if any(loss is None for loss in losses):
        return None
    return CROSS_CHECK_COST_RTOL - max(losses)


def plug_in_markov(ctx: Context) -> ClaimResult:
    """The check: margin = 1e-7 - (largest relative loss of the plug-in law over `CORRELATIONS`).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> plug_in_markov(Context(paper={}, random=[s], seed=0)).verdict
    'holds'
    """
    tally = Tally()
    shown: dict[int, list[float | None]] = {}      # the paper's systems' losses at CORRELATIONS, kept for the note

    def margin(s: System) -> float | None:
        losses = _losses(s)
        if s.channel is None:
            shown[id(s)] = losses
        return _margin(s, losses)

    for s in ctx.cases:
        tally.run(margin, s, ctx.label(s))
    paper = []
    for name, s in ctx.paper.items():
        try:        # the tally's numbers (computed again only where they raised there)
            losses = shown[id(s)] if id(s) in shown else [plugin_loss(s, lam) for lam in CORRELATIONS]
            paper.append(f"{name} " + ", ".join(f"{100 * loss:.3g}% at lambda = {lam}"
                                                for loss, lam in zip(losses, CORRELATIONS, strict=True)))
        except ArithmeticError as err:     # reported in the tally already
            paper.append(f"{name}: {type(err).__name__}")
    counterexample = None
    if tally.violations:
        found = shrink(_margin, ctx.seed, fallback=ctx.cases, candidates=simple_systems(ctx))
        counterexample = None if found is None else bursty_twin(found, max(CORRELATIONS)).to_dict()
    note = ("Each case behind stationary Gilbert channels (h_good = 1, h_bad = 0) with its own time-averaged "
            "delivery rates mu and p = (1 - mu)(1 - lambda), r = mu (1 - lambda); margin = 1e-7 - (E[cost] of the "
            "UDP-like plug-in plan / exact minimum - 1), the worse of the two lambdas (a caller's system with its own "
            "Gilbert-Elliott channel: behind that channel). The exact minimum uses "
            "R = E[v v'] (closed form, cross-checked against a QP in the tests). Loss of the plug-in law on the "
            f"paper's systems: {'; '.join(paper)}. The TCP-like cost holds only mu_t, so its plug-in law is its "
            "exact minimiser.")
    return tally.result("plug-in-markov", STATEMENT, note, counterexample)
