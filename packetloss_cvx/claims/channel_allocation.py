"""§VI: the cheapest UDP-like channel allocation of the two-actuator system, by the
independent brute-force allocator: one case per price vector beta and cost bound alpha."""

from __future__ import annotations

from ..lq.costs import closed_form
from ..model.system import System
from ..results import ClaimResult
from .context import Context
from .evaluate import CASE_ERRORS, Tally
from .paper import ALLOCATION_ALPHA, ALLOCATION_BETAS, STATEMENTS

__all__ = ["GRID", "allocation_udp_perfect", "alpha_levels", "brute_force_allocation", "brute_force_allocations",
           "perfect_channel_case"]

#: The brute-force grid: 101 points on mu1, refined by 21 around the best; bisection on mu2.
#: mu1 on 101 points refined by 21; mu2 by bisection to 1e-8 (the margin resolves 1e-6: a perfect channel
#: is mu_i = 1 to within 1e-6, so a finer bisection would not change a verdict)
GRID = {"coarse": 101, "fine": 21, "tol": 1e-8}


def brute_force_allocation(*args, **kwargs):
    """:func:`~packetloss_cvx.allocation.brute_force.brute_force_allocation`, imported on first use: the
    allocation package imports cvxpy (its SOCP and constraint grammar), which the audit's other claims never
    need (``tests/cli/test_closed_form_imports.py``).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1, 1]], horizon=1, state_weight=[1], input_weight=[1, 1], mu=[.5, .5], x0=[1])
    >>> [round(v, 6) for v in brute_force_allocation(s, "udp", 1.01, (1.0, 1.0), **GRID)]   # J*_udp(0, 0) = 1
    [0.0, 0.0, 0.0]
    """
    from ..allocation.brute_force import brute_force_allocation as run

    return run(*args, **kwargs)


def brute_force_allocations(*args, **kwargs):
    """:func:`~packetloss_cvx.allocation.brute_force.brute_force_allocations`, imported on first use (as
    :func:`brute_force_allocation`).

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1, 1]], horizon=1, state_weight=[1], input_weight=[1, 1], mu=[.5, .5], x0=[1])
    >>> [[round(v, 6) for v in found] for found in brute_force_allocations(s, "udp", [(1.01, (1.0, 1.0))], **GRID)]
    [[0.0, 0.0, 0.0]]
    """
    from ..allocation.brute_force import brute_force_allocations as run

    return run(*args, **kwargs)


def alpha_levels(system: System) -> tuple[list[float], float, float]:
    """The cost bounds tried, with J*_udp at mu = (1, 1) and at mu = (0, 0).

    The paper's 4.78 and 6, 8, 12, 20 where they lie strictly between the two, and 1.01 J*_udp(0)
    (rounded to 0.01), where doing nothing is affordable.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1, 1]], horizon=1, state_weight=[1], input_weight=[1, 1], mu=[.5, .5], x0=[1])
    >>> alphas, full, none = alpha_levels(s)         # J*_udp: min (1 + u1 + u2)^2 + u1^2 + u2^2 = 1/3; mu = 0: 1
    >>> alphas, round(full, 12), none
    ([1.01], 0.333333333333, 1.0)
    """
    full = closed_form(system.with_mu([1.0, 1.0]), "udp").cost
    none = closed_form(system.with_mu([0.0, 0.0]), "udp").cost
    alphas = [a for a in (ALLOCATION_ALPHA, 6.0, 8.0, 12.0, 20.0) if full < a < none] + [round(none * 1.01, 2)]
    return alphas, full, none


def perfect_channel_case(system: System, beta: tuple[float, float], alpha: float,
                         found: tuple[float, float, float] | Exception | None = ...) -> tuple[float | None, str]:
    """One case: the margin (< 0 when neither channel of the cheapest allocation is perfect, None when
    the brute force finds no feasible allocation) and the note's entry for it. ``found``: the brute
    force's answer for this case when the caller ran it (an exception is raised here), else it is run.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1, 1]], horizon=1, state_weight=[1], input_weight=[1, 1], mu=[.5, .5], x0=[1])
    >>> perfect_channel_case(s, (1.0, 1.0), 1.01)    # alpha >= J*_udp(0, 0) = 1: buy nothing
    (-0.999999, 'beta=(1.0, 1.0), alpha=1.01: mu*=(0.000, 0.000)')
    >>> perfect_channel_case(s, (1.0, 1.0), 0.5)[0] >= 0     # J*_udp(0, 1) = 1/2: one perfect channel
    True
    """

    best = brute_force_allocation(system, "udp", alpha, beta, **GRID) if found is ... else found
    if isinstance(best, Exception):
        raise best
    if best is None:
        return None, f"beta={beta}, alpha={alpha}: no feasible grid point"
    return max(best[1], best[2]) - 1.0 + 1e-6, f"beta={beta}, alpha={alpha}: mu*=({best[1]:.3f}, {best[2]:.3f})"


def allocation_udp_perfect(ctx: Context) -> ClaimResult:
    """For alpha >= 4.78 the cheapest allocation has a perfect channel (mu_i = 1 for some i); one case
    per (beta, alpha) pair, betas outer.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1, 1]], horizon=1, state_weight=[1], input_weight=[1, 1], mu=[.5, .5], x0=[1])
    >>> r = allocation_udp_perfect(Context(paper={"two_actuator": s}, random=[], seed=0))
    >>> r.verdict, r.outcomes                        # only alpha = 1.01 >= J*_udp(0, 0) = 1: mu* = (0, 0) for each beta
    ('fails', '---')
    """

    s = ctx.paper["two_actuator"]
    alphas, full, none = alpha_levels(s)
    pairs = [(beta, alpha) for beta in ALLOCATION_BETAS for alpha in alphas]
    # the 18 searches side by side, their requests pooled (each takes the decisions it takes alone)
    try:
        answers = brute_force_allocations(s, "udp", [(alpha, beta) for beta, alpha in pairs], **GRID)
    except CASE_ERRORS as err:          # before any search (the evaluator's construction): every case errs
        answers = [err] * len(pairs)
    found = dict(zip(pairs, answers, strict=True))
    rows = []

    def margin(pair: tuple[tuple[float, float], float]) -> float | None:
        value, row = perfect_channel_case(s, *pair, found=found[pair])
        if value is not None:
            rows.append(row)
        return value

    tally = Tally()
    for pair in pairs:
        tally.run(margin, pair, f"beta={pair[0]}, alpha={pair[1]}")
    note = (f"Two-actuator system with our x0 = (1, 1), Q = 0, no noise (the paper gives none); "
            f"J*_udp ranges from {full:.3f} (mu = 1) to {none:.3f} (mu = 0). Brute force: grid on mu1 "
            f"(101 points, refined by 21 around the best), bisection on mu2. "
            f"As stated (every alpha >= {ALLOCATION_ALPHA}) the claim cannot hold for any "
            f"x0: once alpha >= J*_udp(mu = 0) = C the cheapest allocation is mu = (0, 0). "
            + "; ".join(rows) + tally.error_note())
    return ClaimResult("allocation-udp-perfect-channel", STATEMENTS["allocation-udp-perfect-channel"],
                       tally.verdict(), tally.checked, int(tally.violations), tally.worst,
                       s.to_dict() if tally.violations else None, note, errors=tally.errors,
                       outcomes="".join(tally.outcomes))
