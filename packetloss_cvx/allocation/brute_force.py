"""An independent reference allocator for two channels, by exhaustive search.

For each mu1 on a grid, the least feasible mu2 by bisection (J* falls in mu2, Theorem 3;
bisection keeps the feasible end), then a finer grid around the best mu1. Shares nothing
with the SOCP or the branch and bound, and evaluates J* by the backward recursion (the
allocation's "auto" takes the dense form on small systems), so the audit and the tests use it
to check them. Every value it returns is beta'mu at a point the recursion finds feasible, so
it is never below the optimum. Grid points that cannot beat the best so far are settled by
one evaluation (monotonicity). Time O((coarse + fine) · log(1/tol)) recursions of
O(N (n^3 + m^3)) at worst.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..evaluator import CostEvaluator
from ..model import System
from ..tolerances import BRUTE_FORCE_BISECTION_TOL, BRUTE_FORCE_ROW_ATOL

__all__ = ["bisect", "brute_force_allocation"]


def brute_force_allocation(system: System, protocol: str, alpha: float, beta: Sequence[float],
                           G: np.ndarray | None = None, h: np.ndarray | None = None, coarse: int = 61,
                           fine: int = 61, tol: float = BRUTE_FORCE_BISECTION_TOL) -> tuple[float, float, float] | None:
    """min beta'mu over feasible points of [0, 1]^2 with G mu <= h: returns (beta'mu, mu1, mu2),
    or None when no grid point of mu1 admits a feasible mu2.

    At most (coarse + fine) (log2(1/tol) + 2) recursions of O(N (n^3 + m^3)); most grid points
    cost one.
    """
    if system.m != 2:
        raise InputError("system", f"the brute-force allocator needs m = 2 channels, found m = {system.m}")
    beta = np.asarray(beta, dtype=float)
    G = np.zeros((0, 2)) if G is None else np.atleast_2d(G)
    h = np.zeros(0) if h is None else np.atleast_1d(h)

    evaluator = CostEvaluator(system, protocol, "recursion")     # the recursion, its structure built once

    def J(mu1: float, mu2: float) -> float:
        return evaluator.cost(np.array([mu1, mu2]))

    def feasible(mu1: float, mu2s: list[float]) -> list[bool]:
        """J*(mu1, mu2) <= alpha for several mu2 at once: one batched recursion."""
        points = np.column_stack([np.full(len(mu2s), mu1), mu2s])
        return list(evaluator.costs(points) <= alpha)

    def best_mu2(mu1: float, cap: float) -> float | None:
        """The least feasible mu2 (to tol, feasible end) below ``cap``, or None: above cap a
        point cannot beat the best so far, so one evaluation at cap settles most grid points.
        O(log2(1/tol)) recursions at most."""
        lo, hi = 0.0, 1.0
        for g, c in zip(G, h, strict=True):    # g1 mu1 + g2 mu2 <= c
            if g[1] > 0:
                hi = min(hi, (c - g[0] * mu1) / g[1])
            elif g[1] < 0:
                lo = max(lo, (c - g[0] * mu1) / g[1])
            elif g[0] * mu1 > c + BRUTE_FORCE_ROW_ATOL:
                return None
        top = min(hi, cap)
        if lo > top or J(mu1, top) > alpha:
            return None
        if J(mu1, lo) <= alpha:
            return lo
        return bisect(lambda mu2s: feasible(mu1, mu2s), lo, top, tol)

    def scan(points: np.ndarray, best: tuple[float, float, float] | None) -> tuple[float, float, float] | None:
        for mu1 in points:
            cap = np.inf if best is None or beta[1] <= 0 else (best[0] - beta[0] * mu1) / beta[1]
            mu2 = best_mu2(float(mu1), cap)
            if mu2 is not None and (best is None or beta[0] * mu1 + beta[1] * mu2 < best[0]):
                best = (float(beta[0] * mu1 + beta[1] * mu2), float(mu1), float(mu2))
        return best

    best = scan(np.linspace(0, 1, coarse), None)
    if best is None:
        return None
    step = 1 / (coarse - 1)
    return scan(np.clip(np.linspace(best[1] - step, best[1] + step, fine), 0, 1), best)


def bisect(feasible, a: float, b: float, tol: float, depth: int = 4) -> float:
    """The feasible end of ``while b - a > tol: mid = (a + b) / 2; a, b = (a, mid) if feasible else
    (mid, b)``, with the same midpoints and decisions, ``depth`` levels per call of
    ``feasible(points) -> list of bool``: the 2^depth - 1 midpoints the next ``depth`` steps could
    visit are evaluated in one batch, then walked. O(log2((b - a) / tol) / depth) calls of
    2^depth - 1 points."""
    while b - a > tol:
        tree: list[float] = []                   # heap order: node k has children 2k + 1, 2k + 2
        bounds = [(a, b)]
        for _ in range(2**depth - 1):
            lo, hi = bounds.pop(0)
            mid = 0.5 * (lo + hi)
            tree.append(mid)
            bounds += [(lo, mid), (mid, hi)]
        ok = feasible(tree)
        k = 0
        while k < len(tree) and b - a > tol:
            a, b = (a, tree[k]) if ok[k] else (tree[k], b)
            k = 2 * k + 1 if ok[k] else 2 * k + 2
    return b
