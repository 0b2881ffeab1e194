"""An independent reference allocator for two channels, by exhaustive search.

For each mu1 on a grid, the least feasible mu2 by bisection (J* falls in mu2, Theorem 3;
bisection keeps the feasible end), then a finer grid around the best mu1. Shares nothing
with the SOCP or the branch and bound, and evaluates J* by the backward recursion (the
allocation's "auto" takes the dense form on small systems), so the audit and the tests use it
to check them. Every value it returns is beta'mu at a point the recursion finds feasible, so
it is never below the optimum. Grid points that cannot beat the best so far are settled by
one evaluation (monotonicity), made for up to SPECULATE grid points in one batch. Time
O((coarse + fine) · log(1/tol)) recursions of O(N (n^3 + m^3)) at worst.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..evaluator import CostEvaluator
from ..model import System
from ..threads import blas_limited
from ..tolerances import BRUTE_FORCE_BISECTION_TOL, BRUTE_FORCE_ROW_ATOL

__all__ = ["SPECULATE", "bisect", "brute_force_allocation", "midpoints"]

#: How many grid points ahead J*(mu1, top) is evaluated in one batch (decisions as point by point).
SPECULATE = 16


@blas_limited
def brute_force_allocation(system: System, protocol: str, alpha: float, beta: Sequence[float],
                           G: np.ndarray | None = None, h: np.ndarray | None = None, coarse: int = 61,
                           fine: int = 61, tol: float = BRUTE_FORCE_BISECTION_TOL) -> tuple[float, float, float] | None:
    """min beta'mu over feasible points of [0, 1]^2 with G mu <= h: returns (beta'mu, mu1, mu2),
    or None when no grid point of mu1 admits a feasible mu2.

    At most (coarse + fine) (log2(1/tol) + 2) recursions of O(N (n^3 + m^3)); most grid points
    cost one.

    Examples
    --------
    Two decoupled copies of x' = x + v u (N = 1): J*_tcp = sum 1/(1 + mu_i), J*_udp = sum (1 - mu_i/2).

    J*_tcp <= 1.5 costs mu1 + mu2 >= 2/3 (at 1/3, 1/3); J*_udp <= 1.5 is mu1 + mu2 >= 1, bought at (1, 0)
    when mu2 costs twice as much.

    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> value, mu1, mu2 = brute_force_allocation(t, "tcp", 1.5, [1, 1], coarse=11, fine=11)
    >>> 2 / 3 <= value < 2 / 3 + 1e-3, abs(mu1 - 1 / 3) < 0.02
    (True, True)
    >>> brute_force_allocation(t, "udp", 1.5, [1, 2], coarse=11, fine=11)
    (1.0, 1.0, 0.0)
    """
    if system.m != 2:
        raise InputError("system", f"the brute-force allocator needs m = 2 channels, found m = {system.m}")
    beta = np.asarray(beta, dtype=float)
    G = np.zeros((0, 2)) if G is None else np.atleast_2d(G)
    h = np.zeros(0) if h is None else np.atleast_1d(h)

    evaluator = CostEvaluator(system, protocol, "recursion")     # the recursion, its structure built once
    known: dict[tuple[float, float], float] = {}

    def costs(points: list[tuple[float, float]]) -> list[float]:
        """J*(mu1, mu2) at each point: the points not evaluated before in one batched recursion, the others
        read back (the scan evaluates J*(mu1, 1) again after each new best, when the cap is above 1). A
        point's cost does not depend on the batch it is evaluated in (batches of fewer than 64 points)."""
        new = list(dict.fromkeys(p for p in points if p not in known))
        if new:
            known.update(zip(new, evaluator.costs(np.array(new, dtype=float)).tolist(), strict=True))
        return [known[p] for p in points]

    def feasible(mu1: float, mu2s: list[float]) -> list[bool]:
        """J*(mu1, mu2) <= alpha for several mu2 at once: one batched recursion."""
        return [c <= alpha for c in costs([(mu1, mu2) for mu2 in mu2s])]

    def bounds(mu1: float, cap: float) -> tuple[float, float] | None:
        """The mu2 interval [lo, top] the constraints and ``cap`` leave, or None: above cap a point
        cannot beat the best so far, so one evaluation at top settles most grid points. O(rows)."""
        lo, hi = 0.0, 1.0
        for g, c in zip(G, h, strict=True):    # g1 mu1 + g2 mu2 <= c
            if g[1] > 0:
                hi = min(hi, (c - g[0] * mu1) / g[1])
            elif g[1] < 0:
                lo = max(lo, (c - g[0] * mu1) / g[1])
            elif g[0] * mu1 > c + BRUTE_FORCE_ROW_ATOL:
                return None
        top = min(hi, cap)
        return None if lo > top else (lo, top)

    def best_mu2(mu1: float, lo: float, top: float, top_ok: bool) -> float | None:
        """The least feasible mu2 in [lo, top] (to tol, feasible end), or None; ``top_ok``: whether
        J*(mu1, top) <= alpha. J*(mu1, lo) and the bisection's first 2^4 - 1 midpoints are evaluated
        in one batch. O(log2(1/tol)) recursions at most."""
        if not top_ok:
            return None
        tree = midpoints(lo, top) if top - lo > tol else []
        ok = feasible(mu1, [lo, *tree])
        if ok[0]:
            return lo
        return bisect(lambda mu2s: feasible(mu1, mu2s), lo, top, tol, first=ok[1:])

    def scan(points: np.ndarray, best: tuple[float, float, float] | None) -> tuple[float, float, float] | None:
        """Walk ``points`` in order, as one would point by point; J*(mu1, top) of up to SPECULATE
        points ahead is evaluated in one batch with the current best, again after the best changes, and
        with it the first bisection batch of the first of them (read back if its top is feasible)."""
        k = 0
        while k < len(points):
            ahead = []                           # (mu1, lo, top) or (mu1, None) up to the batch's end
            for mu1 in points[k:k + SPECULATE]:
                cap = np.inf if best is None or beta[1] <= 0 else (best[0] - beta[0] * mu1) / beta[1]
                ahead.append((float(mu1), bounds(float(mu1), cap)))
            tops = [(mu1, span[1]) for mu1, span in ahead if span is not None]
            spans = [(mu1, span) for mu1, span in ahead if span is not None]
            first: list[tuple[float, float]] = []
            if spans:            # the first bisection batch of the first point, in case its top is feasible
                mu1, (lo, top) = spans[0]
                first = [(mu1, v) for v in [lo, *(midpoints(lo, top) if top - lo > tol else [])]]
            top_ok = iter([c <= alpha for c in costs(tops + first)[:len(tops)]])
            for mu1, span in ahead:
                k += 1
                mu2 = None if span is None else best_mu2(mu1, span[0], span[1], next(top_ok))
                if mu2 is not None and (best is None or beta[0] * mu1 + beta[1] * mu2 < best[0]):
                    best = (float(beta[0] * mu1 + beta[1] * mu2), float(mu1), float(mu2))
                    break                        # the caps ahead change: speculate again
        return best

    best = scan(np.linspace(0, 1, coarse), None)
    if best is None:
        return None
    step = 1 / (coarse - 1)
    return scan(np.clip(np.linspace(best[1] - step, best[1] + step, fine), 0, 1), best)


def midpoints(a: float, b: float, depth: int = 4) -> list[float]:
    """The 2^depth - 1 midpoints the next ``depth`` bisection steps on [a, b] could visit, in heap
    order (node k has children 2k + 1, 2k + 2). O(2^depth).

    Examples
    --------
    >>> midpoints(0.0, 1.0, depth=2)                # the root, then its left and right children
    [0.5, 0.25, 0.75]
    """
    tree: list[float] = []
    spans = [(a, b)]
    for _ in range(2**depth - 1):
        lo, hi = spans.pop(0)
        mid = 0.5 * (lo + hi)
        tree.append(mid)
        spans += [(lo, mid), (mid, hi)]
    return tree


def bisect(feasible, a: float, b: float, tol: float, depth: int = 4, first: list[bool] | None = None) -> float:
    """The feasible end of ``while b - a > tol: mid = (a + b) / 2; a, b = (a, mid) if feasible else
    (mid, b)``, with the same midpoints and decisions, ``depth`` levels per call of
    ``feasible(points) -> list of bool``: the 2^depth - 1 midpoints the next ``depth`` steps could
    visit are evaluated in one batch, then walked; ``first``: the decisions at ``midpoints(a, b,
    depth)`` when already known. O(log2((b - a) / tol) / depth) calls of 2^depth - 1 points.

    Examples
    --------
    >>> calls = []
    >>> def feasible(points):                       # feasible from 0.3 on
    ...     calls.append(len(points))
    ...     return [p >= 0.3 for p in points]
    >>> b = bisect(feasible, 0.0, 1.0, 1e-3)
    >>> 0.3 <= b <= 0.3 + 1e-3, calls               # 10 bisection steps in 3 batches of 15 points
    (True, [15, 15, 15])
    """
    while b - a > tol:
        tree = midpoints(a, b, depth)
        ok = feasible(tree) if first is None else first
        first = None
        k = 0
        while k < len(tree) and b - a > tol:
            a, b = (a, tree[k]) if ok[k] else (tree[k], b)
            k = 2 * k + 1 if ok[k] else 2 * k + 2
    return b
