"""§VI: the cheapest UDP-like channel allocation of the two-actuator system, by the
independent brute-force allocator."""

from __future__ import annotations

from ..allocation.brute_force import brute_force_allocation
from ..costs import closed_form
from ..results import ClaimResult
from .context import Context
from .evaluate import Tally
from .paper import ALLOCATION_ALPHA, ALLOCATION_BETAS, STATEMENTS

__all__ = ["allocation_udp_perfect"]


def allocation_udp_perfect(ctx: Context) -> ClaimResult:
    """For alpha >= 4.78 the cheapest allocation has a perfect channel (mu_i = 1 for some i); one case per
    (beta, alpha) pair, betas outer."""
    s = ctx.paper["two_actuator"]
    full = closed_form(s.with_mu([1.0, 1.0]), "udp").cost
    none = closed_form(s.with_mu([0.0, 0.0]), "udp").cost
    alphas = [a for a in (ALLOCATION_ALPHA, 6.0, 8.0, 12.0, 20.0) if full < a < none] + [round(none * 1.01, 2)]
    pairs = [(beta, alpha) for beta in ALLOCATION_BETAS for alpha in alphas]
    found = {}

    def margin(pair: tuple[tuple[float, float], float]) -> float | None:
        beta, alpha = pair
        best = brute_force_allocation(s, "udp", alpha, beta, coarse=101, fine=21)
        if best is None:
            return None  # no grid point of mu1 admits a feasible mu2
        found[pair] = best
        return max(best[1], best[2]) - 1.0 + 1e-6   # < 0: neither channel perfect

    tally = Tally()
    for pair in pairs:
        tally.run(margin, pair, f"beta={pair[0]}, alpha={pair[1]}")
    rows = [f"beta={beta}, alpha={alpha}: mu*=({found[beta, alpha][1]:.3f}, {found[beta, alpha][2]:.3f})"
            for beta, alpha in pairs if (beta, alpha) in found]
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
