"""An independent reference allocator for two channels, by exhaustive search.

For each mu1 on a grid, the least feasible mu2 by bisection (`J*` falls in mu2, Theorem 3;
bisection keeps the feasible end), then a finer grid around the best mu1. Shares nothing
with the SOCP or the branch and bound, and evaluates `J*` by the backward recursion (the
allocation's "auto" takes the dense form on small systems), so the audit and the tests use it
to check them. Every value it returns is beta'mu at a point the recursion finds feasible, so
it is never below the optimum. Grid points that cannot beat the best so far are settled by
one evaluation (monotonicity), made for up to SPECULATE grid points in one batch. Time
O((coarse + fine) · log(1/tol)) recursions of O(N (n^3 + m^3)) at worst.

The search is a generator that asks for the costs of lists of points and decides on what it
gets back; `brute_force_allocations` runs several searches of one system side by side,
their requests pooled into batched recursions (a point's cost does not depend on the batch it is
in, below 64 points), each search taking the decisions it takes alone.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Sequence

import numpy as np

from ..errors import InputError
from ..lq.evaluator import CostEvaluator
from ..lq.recursion import FLAT_MIN
from ..model.system import System
from ..threads import blas_limited
from ..tolerances import BRUTE_FORCE_BISECTION_TOL, BRUTE_FORCE_ROW_ATOL
from .grammar import check_alpha, check_beta

__all__ = ["SPECULATE", "bisect", "bisect_steps", "brute_force_allocation", "brute_force_allocations", "midpoints"]

#: How many grid points ahead J*(mu1, top) is evaluated in one batch (decisions as point by point).
SPECULATE = 16
#: Bisection levels per batch: alone, 2^4 - 1 midpoints a batched recursion (its fixed cost dominates);
#: side by side, where the cases share each recursion's fixed cost, fewer wasted midpoints pay more.
DEPTH, POOLED_DEPTH = 4, 3

Point = tuple[float, float]
Answer = tuple[float, float, float] | None
#: A search: yields the points whose J* it needs, is sent their costs, returns its answer.
Search = Generator[list[Point], list[float], Answer]


@blas_limited
def brute_force_allocation(system: System, protocol: str, alpha: float, beta: Sequence[float],
                           G: np.ndarray | None = None, h: np.ndarray | None = None, coarse: int = 61,
                           fine: int = 61, tol: float = BRUTE_FORCE_BISECTION_TOL) -> Answer:
    """min beta'mu over feasible points of [0, 1]^2 with G mu <= h: returns (beta'mu, mu1, mu2),
    or None when no grid point of mu1 admits a feasible mu2.

    At most (coarse + fine) (log2(1/tol) + 2) recursions of O(N (n^3 + m^3)); most grid points
    cost one.

    Examples
    --------
    Two decoupled copies of x' = x + v u (N = 1): `J*_tcp` = sum 1/(1 + mu_i), `J*_udp` = sum (1 - mu_i/2).

    `J*_tcp` <= 1.5 costs mu1 + mu2 >= 2/3 (at 1/3, 1/3); `J*_udp` <= 1.5 is mu1 + mu2 >= 1, bought at (1, 0)
    when mu2 costs twice as much.

    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> value, mu1, mu2 = brute_force_allocation(t, "tcp", 1.5, [1, 1], coarse=11, fine=11)
    >>> 2 / 3 <= value < 2 / 3 + 1e-3, abs(mu1 - 1 / 3) < 0.02
    (True, True)
    >>> brute_force_allocation(t, "udp", 1.5, [1, 2], coarse=11, fine=11)
    (1.0, 1.0, 0.0)
    """
    (answer,) = brute_force_allocations(system, protocol, [(alpha, beta, G, h)], coarse, fine, tol)
    if isinstance(answer, Exception):
        raise answer
    return answer


@blas_limited
def brute_force_allocations(system: System, protocol: str, cases: Sequence[tuple], coarse: int = 61, fine: int = 61,
                            tol: float = BRUTE_FORCE_BISECTION_TOL) -> list[Answer | Exception]:
    """`brute_force_allocation` for several cases ``(alpha, beta)`` or ``(alpha, beta, G, h)`` of one
    system and protocol, the searches run side by side: each round pools every search's request into
    batched recursions of fewer than 64 points, points asked before read back. Each answer is what the
    case gives alone (the same decisions); a case whose evaluations raise gets the exception in its place
    (its own request evaluated alone, as it would be alone). Time as the cases one by one, in about as
    many batched recursions as the longest of them needs.

    Examples
    --------
    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> brute_force_allocations(t, "udp", [(1.5, [1, 2]), (1.5, [2, 1])], coarse=11, fine=11)
    [(1.0, 1.0, 0.0), (1.0, 0.0, 1.0)]
    """
    if system.m != 2:
        raise InputError("system", f"the brute-force allocator needs m = 2 channels, found m = {system.m}")
    evaluator = CostEvaluator(system, protocol, "recursion")     # the recursion, its structure built once
    known: dict[Point, float] = {}

    def evaluate(points: list[Point]) -> None:
        """J* at the points not known yet, in batched recursions of fewer than FLAT_MIN points (batches
        where a point's cost does not depend on the others)."""
        new = list(dict.fromkeys(p for p in points if p not in known))
        for start in range(0, len(new), FLAT_MIN - 1):
            part = new[start:start + FLAT_MIN - 1]
            known.update(zip(part, evaluator.costs(np.array(part, dtype=float)).tolist(), strict=True))

    answers: list[Answer | Exception] = [None] * len(cases)
    requests: dict[int, tuple[Search, list[Point]]] = {}

    def advance(k: int, search: Search, values: list[float] | None) -> None:
        try:
            requests[k] = (search, next(search) if values is None else search.send(values))
        except StopIteration as done:
            answers[k] = done.value
            requests.pop(k, None)

    for k, case in enumerate(cases):
        alpha, beta, G, h = (*case, None, None)[:4]
        advance(k, _search(alpha, beta, G, h, coarse, fine, tol, DEPTH if len(cases) == 1 else POOLED_DEPTH), None)
    while requests:
        try:
            evaluate([p for _, points in requests.values() for p in points])
        except Exception:
            if len(cases) == 1:           # alone: its error as it is (brute_force_allocation raises it)
                raise
            for k, (_, points) in list(requests.items()):      # each request alone: only its own case fails
                try:
                    evaluate(points)
                except Exception as err:  # noqa: BLE001 - handed to the case it belongs to
                    answers[k] = err
                    requests.pop(k)
        for k, (search, points) in list(requests.items()):
            advance(k, search, [known[p] for p in points])
    return answers


def _search(alpha: float, beta: Sequence[float], G: np.ndarray | None, h: np.ndarray | None, coarse: int,
            fine: int, tol: float, depth: int = 4) -> Search:
    """One case's search: yields lists of points, is sent their costs J*(mu1, mu2), returns the answer."""
    alpha, beta = check_alpha(alpha), check_beta(beta, 2)      # NaN alpha or a 3-vector beta: an error, not None
    G = np.zeros((0, 2)) if G is None else np.atleast_2d(np.asarray(G, dtype=float))
    h = np.zeros(0) if h is None else np.atleast_1d(np.asarray(h, dtype=float))
    if G.ndim != 2 or G.shape[1] != 2 or h.shape != (G.shape[0],) or not (np.all(np.isfinite(G))
                                                                         and np.all(np.isfinite(h))):
        raise InputError("G, h", f"expected finite rows G (k, 2) and h (k,) of G mu <= h, found shapes {G.shape} "
                                 f"and {h.shape}")

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

    def best_mu2(mu1: float, lo: float, top: float, top_ok: bool) -> Generator[list[Point], list[float], float | None]:
        """The least feasible mu2 in [lo, top] (to tol, feasible end), or None; ``top_ok``: whether
        `J*`(mu1, top) <= alpha. `J*`(mu1, lo) and the bisection's first 2^4 - 1 midpoints are asked in
        one batch. O(log2(1/tol)) batches at most."""
        if not top_ok:
            return None
        tree = midpoints(lo, top, depth) if top - lo > tol else []
        ok = [c <= alpha for c in (yield [(mu1, v) for v in [lo, *tree]])]
        if ok[0]:
            return lo
        steps = bisect_steps(lo, top, tol, depth, first=ok[1:])
        try:
            tree = next(steps)
            while True:
                tree = steps.send([c <= alpha for c in (yield [(mu1, v) for v in tree])])
        except StopIteration as done:
            return done.value

    def scan(points: np.ndarray, best: Answer) -> Generator[list[Point], list[float], Answer]:
        """Walk ``points`` in order, as one would point by point; J*(mu1, top) of up to SPECULATE
        points ahead is asked in one batch with the current best, again after the best changes, and
        with it the first bisection batch of the first of them (read back if its top is feasible)."""
        k = 0
        while k < len(points):
            ahead = []                           # (mu1, lo, top) or (mu1, None) up to the batch's end
            for mu1 in points[k:k + SPECULATE]:
                cap = np.inf if best is None or beta[1] <= 0 else (best[0] - beta[0] * mu1) / beta[1]
                ahead.append((float(mu1), bounds(float(mu1), cap)))
            spans = [(mu1, span) for mu1, span in ahead if span is not None]
            tops = [(mu1, span[1]) for mu1, span in spans]
            first: list[Point] = []
            if spans:            # the first bisection batch of the first point, in case its top is feasible
                mu1, (lo, top) = spans[0]
                first = [(mu1, v) for v in [lo, *(midpoints(lo, top, depth) if top - lo > tol else [])]]
            values = (yield tops + first) if tops else []
            top_ok = iter([c <= alpha for c in values[:len(tops)]])
            for mu1, span in ahead:
                k += 1
                mu2 = None if span is None else (yield from best_mu2(mu1, span[0], span[1], next(top_ok)))
                if mu2 is not None and (best is None or beta[0] * mu1 + beta[1] * mu2 < best[0]):
                    best = (float(beta[0] * mu1 + beta[1] * mu2), float(mu1), float(mu2))
                    break                        # the caps ahead change: speculate again
        return best

    best = yield from scan(np.linspace(0, 1, coarse), None)
    if best is None:
        return None
    step = 1 / (coarse - 1)
    return (yield from scan(np.clip(np.linspace(best[1] - step, best[1] + step, fine), 0, 1), best))


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


def bisect_steps(a: float, b: float, tol: float, depth: int = 4,
                 first: list[bool] | None = None) -> Generator[list[float], list[bool], float]:
    """`bisect` as a generator: yields each batch of midpoints, is sent their decisions, returns
    the feasible end. O(log2((b - a) / tol) / depth) batches of 2^depth - 1 points.

    Examples
    --------
    >>> steps = bisect_steps(0.0, 1.0, 0.2, depth=2)
    >>> next(steps)                                 # the first two levels' midpoints
    [0.5, 0.25, 0.75]
    >>> steps.send([True, False, True])             # feasible at 0.5, not at 0.25: [0.25, 0.5]
    [0.375, 0.3125, 0.4375]
    """
    while b - a > tol:
        tree = midpoints(a, b, depth)
        ok = (yield tree) if first is None else first
        first = None
        k = 0
        while k < len(tree) and b - a > tol:
            a, b = (a, tree[k]) if ok[k] else (tree[k], b)
            k = 2 * k + 1 if ok[k] else 2 * k + 2
    return b


def bisect(feasible: Callable[[list[float]], list[bool]], a: float, b: float, tol: float, depth: int = 4,
           first: list[bool] | None = None) -> float:
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
    steps = bisect_steps(a, b, tol, depth, first)
    try:
        tree = next(steps)
        while True:
            tree = steps.send(feasible(tree))
    except StopIteration as done:
        return done.value
