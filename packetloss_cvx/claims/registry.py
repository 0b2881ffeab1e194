"""Every claim by id, and the audit that runs them."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..budgets import check, count_text
from ..errors import InputError
from ..model.random_systems import random_system
from ..model.system import System
from ..progress import progress_bar
from ..results import ClaimResult
from ..threads import blas_limited
from .actuator import STATEMENT as ZERO_VS_HOLD
from .actuator import zero_vs_hold
from .attainable import STATEMENTS as ATTAINABLE
from .attainable import ack_price_paper_basis, allocation_tcp_meets_alpha
from .chain_tcp import STATEMENT as TCP_PRIOR_MEAN_CHAIN
from .chain_tcp import tcp_prior_mean_chain
from .channel_allocation import allocation_udp_perfect
from .closed_loop import protocol_ranking
from .context import Context, paper_systems
from .cost_difference import lemma_2, lemma_3, theorem_4
from .evaluate import CASE_ERRORS
from .expectation_mpc import STATEMENT as EXPECTATION_MPC
from .expectation_mpc import expectation_mpc
from .markov import STATEMENT as PLUG_IN_MARKOV
from .markov import plug_in_markov
from .mpc_vs_dp import mpc_vs_dp
from .ordering import corollary_1, corollary_2, theorem_2, theorem_3
from .paper import STATEMENTS
from .power import STATEMENT as POWER_WATER_FILLING
from .power import power_water_filling
from .region import STATEMENT as STABILITY_REGION
from .region import stability_region
from .sensing import STATEMENT as COST_SPLIT_SENSOR
from .sensing import cost_split_sensor
from .tables import pendulum_maximiser, table_1, table_2
from .theorem1 import expected_cost_tcp, lemma_1, lemma_quad, theorem_1_costs, theorem_1_laws

__all__ = ["CHAIN_CLAIMS", "CLAIMS", "audit", "run_claim"]

_CHECKS: dict[str, Callable[[Context], ClaimResult]] = {
    "theorem-1-laws": theorem_1_laws,
    "theorem-1-costs": theorem_1_costs,
    "lemma-1": lemma_1,
    "lemma-quad-expectation": lemma_quad,
    "expected-cost-tcp": expected_cost_tcp,
    "theorem-2": theorem_2,
    "corollary-1": corollary_1,
    "theorem-3": theorem_3,
    "corollary-2": corollary_2,
    "lemma-2": lemma_2,
    "lemma-3": lemma_3,
    "theorem-4": theorem_4,
    "table-1": table_1,
    "table-2": table_2,
    "pendulum-maximiser": pendulum_maximiser,
    "allocation-udp-perfect-channel": allocation_udp_perfect,
    "protocol-ranking-closed-loop": protocol_ranking,
    "mpc-vs-dp": mpc_vs_dp,
}

#: Claim id -> (statement, check). The order is the audit's and the report's.
CLAIMS: dict[str, tuple[str, Callable[[Context], ClaimResult]]] = {
    claim_id: (statement, _CHECKS[claim_id]) for claim_id, statement in STATEMENTS.items()
}
CLAIMS["plug-in-markov"] = (PLUG_IN_MARKOV, plug_in_markov)   # not the paper's: its laws under bursty losses
CLAIMS["cost-split-sensor"] = (COST_SPLIT_SENSOR, cost_split_sensor)   # not the paper's: lossy sensors
CLAIMS["stability-region-paper-systems"] = (STABILITY_REGION, stability_region)   # the paper's open problem
CLAIMS["power-water-filling"] = (POWER_WATER_FILLING, power_water_filling)   # the paper's conjecture
CLAIMS["expectation-mpc-feasibility"] = (EXPECTATION_MPC, expectation_mpc)   # Trodden & Li's constrained loop
CLAIMS["allocation-tcp-meets-alpha"] = (ATTAINABLE["allocation-tcp-meets-alpha"],    # the paper's design, attained
                                        allocation_tcp_meets_alpha)
CLAIMS["ack-price-paper-basis"] = (ATTAINABLE["ack-price-paper-basis"], ack_price_paper_basis)   # its conclusion
CLAIMS["zero-vs-hold-paper-systems"] = (ZERO_VS_HOLD, zero_vs_hold)   # the paper's remark on holding the input
CLAIMS["tcp-prior-mean-chain"] = (TCP_PRIOR_MEAN_CHAIN, tcp_prior_mean_chain)   # the TCP-like cost behind chains


#: claims about Gilbert-Elliott chains: they check a caller's chain file behind its own chain
CHAIN_CLAIMS = frozenset({"plug-in-markov", "tcp-prior-mean-chain"})


@blas_limited
def audit(systems: Sequence[System] | None = None, random: int = 50, seed: int = 0,
          only: Sequence[str] | None = None, progress: bool | None = None) -> list[ClaimResult]:
    """Check every claim (or those in ``only``) on the paper's systems, on ``systems`` and on
    ``random`` seeded random systems (n, m <= 4, N <= 8, stable and unstable).

    Parameters
    ----------
    systems : sequence of System, optional
        More systems to check the claims on (after the paper's, before the random ones).
    random : int
        How many seeded random systems to add.
    seed : int
        Seeds the random systems, the Monte Carlo samples and the shrinking.
    only : sequence of str, optional
        Claim ids to check (default: all of `CLAIMS`, in order).
    progress : bool or None
        A bar on stderr, one step per claim (None: when stderr is a terminal).

    Returns
    -------
    list of ClaimResult

    Raises
    ------
    InputError
        An unknown claim id, a negative seed or count.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> [r] = audit([s], random=0, only=["theorem-2"], progress=False)   # the paper's 2 systems, then s
    >>> r.verdict, r.checked, bool(np.isclose(r.worst, 0.125))   # s: J*_udp - J*_tcp = 3/4 - 2/3 = J*_tcp / 8
    ('holds', 3, True)
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise InputError("seed", f"expected an integer >= 0, found {seed!r}")
    if isinstance(random, bool) or not isinstance(random, int | np.integer) or random < 0:
        raise InputError("random", f"expected a count >= 0, found {random!r}")
    check("audit_cases", random, "random", f"{count_text(int(random))} random systems")     # before any is drawn
    rng = np.random.default_rng(seed)
    paper = paper_systems()
    given = _given_systems(systems)
    cases = [random_system(rng) for _ in range(random)]
    # the paper's claims are stated for independent losses: a caller's system behind a Gilbert-Elliott chain
    # is audited at its plug-in mu_t, except by the claims about chains, which see the chain itself
    plug_in = [s.with_mu(s.mu_schedule) if s.channel is not None else s for s in given]
    ctx = Context(paper=paper, random=plug_in + cases, seed=seed, extra=len(given))
    chain_ctx = (Context(paper=paper, random=given + cases, seed=seed, extra=len(given))
                 if any(s.channel is not None for s in given) else ctx)
    ids = list(CLAIMS) if only is None else list(only)
    for claim_id in ids:
        if claim_id not in CLAIMS:
            raise InputError("claim", f"unknown claim id {claim_id!r}; expected one of {', '.join(CLAIMS)}")
    results = []
    with progress_bar(total=len(ids), desc="audit", progress=progress) as bar:
        for claim_id in ids:
            bar.set_postfix_str(claim_id)        # the claim being checked (one can take most of the time)
            results.append(run_claim(claim_id, chain_ctx if claim_id in CHAIN_CLAIMS else ctx))
            bar.update()
    return results


def run_claim(claim_id: str, ctx: Context) -> ClaimResult:
    """Run one claim's check; if the check itself raises one of `CASE_ERRORS` (outside its
    per-case loop), the claim is "inconclusive" with one error, and the note names it.

    Parameters
    ----------
    claim_id : str
        A key of `CLAIMS`.
    ctx : Context

    Returns
    -------
    ClaimResult

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> r = run_claim("corollary-1", Context(paper={}, random=[s], seed=0))
    >>> r.verdict, bool(np.isclose(r.worst, 0.25))   # ||U*|| = 2/3 (TCP-like), 1/2 (UDP-like): margin 1/4
    ('holds', True)
    """
    try:
        return CLAIMS[claim_id][1](ctx)
    except CASE_ERRORS as err:
        detail = str(err).splitlines()[0] if str(err) else ""
        return ClaimResult(claim_id, CLAIMS[claim_id][0], "inconclusive", 0, 0, None, None,
                           f"The check raised {type(err).__name__}: {detail}. Nothing was checked.", errors=1)


def _given_systems(systems: object) -> list[System]:
    """``audit``'s ``systems``: None or an iterable of [`System`][packetloss_cvx.model.system.System] (a name or a lone
    System is refused, not taken letter by letter or failing on ``.channel``). O(len).

    >>> _given_systems(None), len(_given_systems(tuple(paper_systems().values())))
    ([], 2)
    """
    if systems is None:
        return []
    given = None
    if not isinstance(systems, str | bytes | System):
        try:
            given = list(systems)
        except TypeError:
            given = None
    if given is None or not all(isinstance(s, System) for s in given):
        raise InputError("systems", f"expected a sequence of System objects (load_system, load_example), found "
                                    f"{systems!r:.60}")
    return given
