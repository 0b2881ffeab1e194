"""tcp-prior-mean-chain: is the paper's TCP-like cost at a chain's prior mean rates a lower bound on what a TCP-like
law attains behind the chain? Each case is put behind Gilbert channels with its own average delivery rates and
burstiness lambda = 1 - p - r in `CORRELATIONS` (a caller's system with its own chain: behind that chain), and the
cost the product reports there (`exact_closed_form(..., "tcp")`, the paper's J*_tcp at the chain's predicted rates)
is compared with the least expected cost of any law with acknowledgements, the chain DP
([`chain_attainable`][packetloss_cvx.closedloop.chain_dp.chain_attainable]). The same comparison without process
noise (`noise_free`) is reported beside it: it says which violations are the noise's (the paper's plan is fixed in
advance, the DP reacts to the noise, so with noise the value is no lower bound even for independent losses).
"""

from __future__ import annotations

import numpy as np

from ..closedloop.chain_dp import chain_attainable
from ..lq.markov_cost import exact_closed_form
from ..model.files import load_example, system_from_dict
from ..model.system import System
from ..model.twins import bursty_twin
from ..results import ClaimResult
from ..tolerances import SELF_CHECK_RTOL
from .context import Context
from .evaluate import Tally, shrink, simple_systems

__all__ = ["CORRELATIONS", "STATEMENT", "noise_free", "prior_mean_ratio", "tcp_prior_mean_chain"]

#: The burstiness levels lambda = 1 - p - r each case is put behind (Gilbert channels: the acknowledgements reveal
#: the state, so the chain DP is exact and cheap: 2^m beliefs a step).
CORRELATIONS = (0.5, 0.9)

STATEMENT = ("Behind a Markov chain the paper's TCP-like cost at the chain's prior mean rates (what the product "
             "reports as the TCP-like cost under the chain) is a lower bound on the attainable TCP-like cost, the "
             "least expected cost of any law with acknowledgements.")


def prior_mean_ratio(system: System) -> float | None:
    """The paper's TCP-like cost at the prior mean rates over the attainable TCP-like cost behind ``system``'s chain;
    where the chain DP gives only bounds (beyond its budget), the ratio to the bound that decides the claim (above
    the upper: a violation; below the lower: it holds), None where neither does or both costs are 0. Time
    O(`chain_attainable`).

    Examples
    --------
    One step behind a stationary chain at mean rate 0.8: the paper's J*_tcp = 1 / (1 + mu) against the least cost
    of a law that knows only the mean, 1 - mu / 2: (1 / 1.8) / 0.6 = 25 / 27.

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.4]))
    >>> bool(abs(prior_mean_ratio(s) - 25 / 27) < 1e-12)
    True
    """
    reported = float(exact_closed_form(system, "tcp").cost)
    found = chain_attainable(system)
    if found.cost is not None:
        return None if found.cost <= 0 else reported / found.cost
    if reported > found.upper > 0:
        return reported / found.upper
    if 0 < found.lower and reported <= found.lower:
        return reported / found.lower
    return None


def noise_free(system: System) -> System:
    """``system`` without process noise (everything else as given). O(n^2).

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0], mu=[0.5],
    ...            noise_cov=[[2.0]])
    >>> noise_free(s).noise_cov.tolist()
    [[0.0]]
    """
    if not np.any(system.noise_cov):
        return system
    table = system.to_dict()
    table["plant"]["noise_cov"] = np.zeros((system.n, system.n)).tolist()
    return system_from_dict(table)


def _twins(system: System) -> list[tuple[float | None, System]]:
    """The chains a case is checked behind: its own (lambda None), else its Gilbert twins at `CORRELATIONS`."""
    if system.channel is not None:
        return [(None, system)]
    return [(lam, bursty_twin(system, lam)) for lam in CORRELATIONS]


def _ratios(system: System) -> list[float | None]:
    return [prior_mean_ratio(twin) for _, twin in _twins(system)]


def _margin(system: System, ratios: list[float | None] | None = None) -> float | None:
    """SELF_CHECK_RTOL - (the largest ratio over the case's chains - 1): >= 0 where the reported cost is below the
    attainable one to the accuracy the chain DP is checked to (an equality to rounding is no violation)."""
    ratios = _ratios(system) if ratios is None else ratios
    decided = [r for r in ratios if r is not None]
    return SELF_CHECK_RTOL - (max(decided) - 1.0) if decided else None


def tcp_prior_mean_chain(ctx: Context) -> ClaimResult:
    """The check: margin = 1e-9 - (reported / attainable - 1), the worse of the case's chains.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> tcp_prior_mean_chain(Context(paper={}, random=[s], seed=0)).verdict   # one step: (1 / 1.5) / 0.75 < 1
    'holds'
    """
    tally = Tally()
    seen: list[float] = []
    quiet: list[float] = []          # the same chains without process noise

    def margin(s: System) -> float | None:
        ratios = _ratios(s)
        seen.extend(r for r in ratios if r is not None)
        quiet.extend(r for r in (_ratios(noise_free(s)) if np.any(s.noise_cov) else ratios) if r is not None)
        return _margin(s, ratios)

    for s in ctx.cases:
        tally.run(margin, s, ctx.label(s))
    counterexample = None
    if tally.violations:
        found = shrink(_margin, ctx.seed, fallback=ctx.cases, candidates=simple_systems(ctx))
        if found is not None:
            worst = max(_twins(found), key=lambda item: prior_mean_ratio(item[1]) or 0.0)[1]
            counterexample = worst.to_dict()

    def spread(values: list[float]) -> str:
        if not values:
            return "no chain decided"
        above = sum(r > 1.0 + SELF_CHECK_RTOL for r in values)
        below = sum(r < 1.0 - SELF_CHECK_RTOL for r in values)
        return (f"reported / attainable from {min(values):.3g} to {max(values):.3g} over {len(values)} chains, above "
                f"1 on {above}, below on {below}")

    try:
        bursty = load_example("pendulum_bursty")
        example = (f"pendulum_bursty: {exact_closed_form(bursty, 'tcp').cost:.6g} reported against "
                   f"{chain_attainable(bursty).cost:.6g} attainable")
    except ArithmeticError as err:        # reported in the note, not a verdict
        example = f"pendulum_bursty: {type(err).__name__}"
    note = ("Each case behind stationary Gilbert channels (h_good = 1, h_bad = 0) with its own time-averaged "
            "delivery rates mu and p = (1 - mu)(1 - lambda), r = mu (1 - lambda), lambda in "
            f"{list(CORRELATIONS)} (a caller's system with its own chain: behind it); margin = 1e-9 "
            "(SELF_CHECK_RTOL) - (the paper's J*_tcp at the chain's predicted rates / the exact TCP-like DP with "
            f"acknowledgements behind the chain - 1), the worse of the case's chains. As given: {spread(seen)}. "
            f"Without process noise: {spread(quiet)}. {example}. So the reported value bounds the attainable cost in "
            "neither direction: below it by up to the factor above (the bursts cost more than the first-moment "
            "value at the mean allows), above it only where there is process noise (the paper's plan is fixed in "
            "advance, the DP reacts to the noise, as for independent losses). The product shows the chain DP's "
            "cost as the attainable one and the paper's value labelled as such.")
    return tally.result("tcp-prior-mean-chain", STATEMENT, note, counterexample)
