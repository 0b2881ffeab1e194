"""§VI: the cheapest UDP-like channel allocation of the two-actuator system, by the
independent brute-force allocator."""

from __future__ import annotations

import numpy as np

from ..allocation.brute_force import brute_force_allocation
from ..costs import closed_form
from ..results import ClaimResult
from .context import Context
from .paper import ALLOCATION_ALPHA, ALLOCATION_BETAS, STATEMENTS

__all__ = ["allocation_udp_perfect"]


def allocation_udp_perfect(ctx: Context) -> ClaimResult:
    """For alpha >= 4.78 the cheapest allocation has a perfect channel (mu_i = 1 for some i)."""
    s = ctx.paper["two_actuator"]
    full = closed_form(s.with_mu([1.0, 1.0]), "udp").cost
    none = closed_form(s.with_mu([0.0, 0.0]), "udp").cost
    alphas = [a for a in (ALLOCATION_ALPHA, 6.0, 8.0, 12.0, 20.0) if full < a < none] + [round(none * 1.01, 2)]
    rows, violations, worst = [], 0, np.inf
    for beta in ALLOCATION_BETAS:
        for alpha in alphas:
            best = brute_force_allocation(s, "udp", alpha, beta, coarse=101, fine=21)
            if best is None:
                continue
            perfect = max(best[1], best[2])
            worst = min(worst, perfect - 1.0 + 1e-6)
            violations += perfect < 1.0 - 1e-6
            rows.append(f"beta={beta}, alpha={alpha}: mu*=({best[1]:.3f}, {best[2]:.3f})")
    note = (f"Two-actuator system with our x0 = (1, 1), Q = 0, no noise (the paper gives none); "
            f"J*_udp ranges from {full:.3f} (mu = 1) to {none:.3f} (mu = 0). Brute force: grid on mu1 "
            f"(101 points, refined by 21 around the best), bisection on mu2. "
            f"As stated (every alpha >= {ALLOCATION_ALPHA}) the claim cannot hold for any "
            f"x0: once alpha >= J*_udp(mu = 0) = C the cheapest allocation is mu = (0, 0). "
            + "; ".join(rows))
    verdict = "fails" if violations else "holds"
    return ClaimResult("allocation-udp-perfect-channel", STATEMENTS["allocation-udp-perfect-channel"], verdict,
                       len(rows), int(violations), float(worst) if rows else None,
                       s.to_dict() if violations else None, note)
