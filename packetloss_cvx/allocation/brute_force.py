"""An independent reference allocator for two channels, by exhaustive search.

For each mu1 on a grid, the least feasible mu2 by bisection (J* falls in mu2, Theorem 3;
bisection keeps the feasible end), then a finer grid around the best mu1. Shares nothing
with the SOCP or the branch and bound but the closed form, so the audit and the tests
use it to check them. Time O((coarse + fine) · log(1/tol)) closed forms.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..costs import closed_form
from ..errors import InputError
from ..model import System

__all__ = ["brute_force_allocation"]


def brute_force_allocation(system: System, protocol: str, alpha: float, beta: Sequence[float],
                           G: np.ndarray | None = None, h: np.ndarray | None = None, coarse: int = 61,
                           fine: int = 61, tol: float = 1e-10) -> tuple[float, float, float] | None:
    """min beta'mu over feasible points of [0, 1]^2 with G mu <= h: returns (beta'mu, mu1, mu2),
    or None when no grid point of mu1 admits a feasible mu2."""
    if system.m != 2:
        raise InputError("system", f"the brute-force allocator needs m = 2 channels, found m = {system.m}")
    beta = np.asarray(beta, dtype=float)
    G = np.zeros((0, 2)) if G is None else np.atleast_2d(G)
    h = np.zeros(0) if h is None else np.atleast_1d(h)

    def J(mu1: float, mu2: float) -> float:
        return closed_form(system.with_mu([mu1, mu2]), protocol).cost

    def best_mu2(mu1: float) -> float | None:
        lo, hi = 0.0, 1.0
        for g, c in zip(G, h, strict=True):    # g1 mu1 + g2 mu2 <= c
            if g[1] > 0:
                hi = min(hi, (c - g[0] * mu1) / g[1])
            elif g[1] < 0:
                lo = max(lo, (c - g[0] * mu1) / g[1])
            elif g[0] * mu1 > c + 1e-12:
                return None
        if lo > hi or J(mu1, hi) > alpha:
            return None
        if J(mu1, lo) <= alpha:
            return lo
        a, b = lo, hi
        while b - a > tol:
            mid = 0.5 * (a + b)
            a, b = (a, mid) if J(mu1, mid) <= alpha else (mid, b)
        return b

    def scan(points: np.ndarray) -> tuple[float, float, float] | None:
        best = None
        for mu1 in points:
            mu2 = best_mu2(float(mu1))
            if mu2 is not None and (best is None or beta[0] * mu1 + beta[1] * mu2 < best[0]):
                best = (float(beta[0] * mu1 + beta[1] * mu2), float(mu1), float(mu2))
        return best

    best = scan(np.linspace(0, 1, coarse))
    if best is None:
        return None
    step = 1 / (coarse - 1)
    refined = scan(np.clip(np.linspace(best[1] - step, best[1] + step, fine), 0, 1))
    return best if refined is None else min(best, refined)
