"""UDP-like allocation by monotonic branch and bound: J*_udp falls in each mu_i (Theorem 3),
so its sublevel set is an upper set, though in general not convex."""

from __future__ import annotations

import heapq

import numpy as np

from ..errors import InfeasibleError, SolverError
from .boxes import BoxLP, boundary, bracket, cost_at

__all__ = ["split", "udp_allocate", "udp_min_cost"]


def split(l: np.ndarray, u: np.ndarray, weights: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """The two halves of the box [l, u] cut across its widest side, widths scaled by ``weights``;
    no halves when that side is narrower than 1e-12. The one child-building routine of both
    branch-and-bound loops. O(m)."""
    i = int(np.argmax((u - l) * weights))
    if u[i] - l[i] < 1e-12:
        return ()
    mid = 0.5 * (l[i] + u[i])
    m = len(l)
    return (l, np.where(np.arange(m) == i, mid, u)), (np.where(np.arange(m) == i, mid, l), u)


def udp_allocate(system, alpha, beta, lo, hi, G, h, calls, gap, max_boxes, tcp_bound):
    m = system.m
    lp = BoxLP(m, G, h, calls)
    J = lambda mu: cost_at(system, "udp", mu)  # noqa: E731
    slack = alpha * (1 + 1e-9)   # prune only when clearly infeasible: the certificate stays valid
    best_mu, best = None, np.inf
    explored = 0

    def incumbent(l, u, p) -> None:
        nonlocal best_mu, best
        q = lp.solve(-np.ones(m), l, u)          # a maximal point of the box and constraints
        if q is None or J(q) > alpha:
            return
        t = boundary(lambda s: J(p + s * (q - p)), alpha, 0.0, 1.0, 1e-3 * gap)
        point = p + t * (q - p)
        if J(point) <= alpha and beta @ point < best:
            best_mu, best = point, float(beta @ point)

    def bound(l, u):
        """Reduce the box and return (lower bound, l, u, LP point) or None if empty/infeasible."""
        if J(u) > slack:
            return None
        l = l.copy()
        for i in range(m):                       # raise l_i to the feasible boundary along edge i
            if l[i] < u[i]:
                edge = u.copy()
                # every point of the box with mu_i below a point known infeasible on this edge is
                # infeasible (it is dominated by that point): raise l_i to the infeasible side
                l[i] = bracket(lambda s, i=i, e=edge: J(np.where(np.arange(m) == i, s, e)), slack,
                                l[i], u[i], 1e-9 + 1e-6 * (u[i] - l[i]))[1]
        if np.isfinite(best):                    # lower u where beta'mu would exceed the incumbent
            for i in range(m):
                if beta[i] > 0:
                    u[i] = min(u[i], (best - (beta @ l - beta[i] * l[i])) / beta[i] + 1e-12)
            if np.any(u < l):
                return None
        p = lp.solve(beta, l, u)
        if p is None:
            return None
        return float(beta @ p), l, u, p

    root = bound(np.full(m, lo), np.full(m, hi))
    if root is None:
        return None, None, 0
    heap = [(root[0], 0, root[1], root[2], root[3])]
    counter = 1
    pruned = np.inf   # least lower bound among boxes set aside as within the gap of the incumbent

    def close_enough(lb: float) -> bool:
        return np.isfinite(best) and lb >= best * (1 - gap)

    while heap:
        lb, _, l, u, p = heapq.heappop(heap)
        if np.isfinite(best) and best - max(min(lb, pruned), tcp_bound) <= gap * max(best, 1e-12):
            heapq.heappush(heap, (lb, -1, l, u, p))
            break
        if close_enough(lb):
            pruned = min(pruned, lb)
            continue
        explored += 1
        if explored > max_boxes:
            raise SolverError("max_boxes", f"UDP-like branch and bound stopped after {max_boxes} boxes "
                              f"(incumbent {best:.6g}, bound {lb:.6g}); raise gap or max_boxes")
        if J(p) <= alpha and beta @ p < best:
            best_mu, best = p, float(beta @ p)
        else:
            incumbent(l, u, p)
        halves = split(l, u, np.maximum(beta, 1e-3))
        if not halves:
            pruned = min(pruned, lb)
            continue
        for nl, nu in halves:
            child = bound(nl, nu.copy())
            if child is None:
                continue
            if close_enough(child[0]):
                pruned = min(pruned, child[0])
            else:
                heapq.heappush(heap, (child[0], counter, child[1], child[2], child[3]))
                counter += 1
    if best_mu is None:
        return None, None, explored
    lower = min([best, pruned] + [item[0] for item in heap])
    if tcp_bound <= best:
        lower = max(lower, tcp_bound)
    return best_mu, lower, explored


def udp_min_cost(system, lo, hi, G, h, calls, tol: float = 1e-6) -> float:
    """min J*_udp over the bounds and constraints: J falls in mu, so the minimum sits at a maximal
    point; a B&B on boxes with bound J(u) (monotone) and incumbents at maximal LP points."""
    m = system.m
    lp = BoxLP(m, G, h, calls)
    J = lambda mu: cost_at(system, "udp", mu)  # noqa: E731
    l0, u0 = np.full(m, lo), np.full(m, hi)
    q = lp.solve(-np.ones(m), l0, u0)
    if q is None:
        raise InfeasibleError("the linear constraints and bounds admit no mu", None)
    if G.shape[0] == 0 and not calls:
        return J(u0)
    best = J(q)
    heap, counter = [(J(u0), 0, l0, u0)], 1
    for _ in range(2000):
        if not heap:
            break
        lb, _, l, u = heapq.heappop(heap)
        if best - lb <= tol * max(best, 1e-12):
            break
        for nl, nu in split(l, u, np.ones(m)):
            point = lp.solve(-np.ones(m), nl, nu)
            if point is None:
                continue
            best = min(best, J(point))
            bound_ = J(nu)
            if bound_ < best:
                heapq.heappush(heap, (bound_, counter, nl, nu))
                counter += 1
    return best
