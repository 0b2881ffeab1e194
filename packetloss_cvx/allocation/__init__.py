"""Channel allocation M* (§VI): the cheapest delivery probabilities that keep J* <= alpha.

.. math:: \\min_{\\mu} \\beta'\\mu \\quad\\text{s.t.}\\quad J^*(\\mu) \\le \\alpha,\\
   \\mu \\in [lo, hi]^m,\\ \\text{extra linear constraints}

(eq:alpha_channels, eq:channel-opt, eq:opt_M), stationary channels.

* TCP-like: with ``Z = Vbar U`` the expected cost ``C + 2Z'g + Z'Omega_g Z + sum psi z^2 / mu``
  is jointly convex in (Z, mu) (quad-over-lin terms), so the sublevel set is convex and the
  program is an SOCP, solved by Clarabel (sparse: mean states as variables) to its default 1e-8
  duality gap; the reported lower bound allows 1e-6 relative for that tolerance.
* UDP-like: the sublevel set is not convex in general. It is an *upper set*: J*_udp falls in
  each mu_i (Theorem 3), so whatever dominates a feasible point is feasible. We run a
  monotonic branch and bound over boxes [l, u]: a box is infeasible when its upper corner is;
  its lower bound is the LP ``min beta'mu`` over the box and the linear constraints (after
  the lower corner is raised coordinate-wise to the feasible boundary, a valid reduction by
  monotonicity); incumbents come from bisection between the LP point and the box's maximal
  point. The TCP-like program over the whole set is a second, global lower bound (Theorem 2).
  The returned mu is verified feasible by the closed form and ``(cost - lower_bound) / cost
  <= gap``. Worst case the number of boxes grows like (1/gap)^(m-1); each box costs two LPs
  and O(m log(1/tol)) closed forms of O(N (n^3 + m^3)).
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence

import numpy as np

from ..errors import InfeasibleError, InputError, SolverError
from ..model import System
from ..protocols import check_protocol
from ..results import Allocation
from .boxes import BoxLP, boundary, bracket, cost_at
from .grammar import Constraint, check_inputs, parse_constraint, polytope
from .tcp import tcp_allocate, tcp_min_cost

__all__ = [
    "Allocation", "allocate", "best_cost_within_budget", "contour_allocations", "min_cost", "parse_constraint",
    "pareto_curve",
]

# ------------------------------------------------------------------ UDP-like: monotonic B&B

def _udp_allocate(system, alpha, beta, lo, hi, G, h, calls, gap, max_boxes, tcp_bound):
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
        widths = (u - l) * np.maximum(beta, 1e-3)
        i = int(np.argmax(widths))
        if u[i] - l[i] < 1e-12:
            pruned = min(pruned, lb)
            continue
        mid = 0.5 * (l[i] + u[i])
        for nl, nu in ((l, np.where(np.arange(m) == i, mid, u)), (np.where(np.arange(m) == i, mid, l), u)):
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


def _udp_min_cost(system, lo, hi, G, h, calls, tol: float = 1e-6) -> float:
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
        i = int(np.argmax(u - l))
        mid = 0.5 * (l[i] + u[i])
        for nl, nu in ((l, np.where(np.arange(m) == i, mid, u)), (np.where(np.arange(m) == i, mid, l), u)):
            point = lp.solve(-np.ones(m), nl, nu)
            if point is None:
                continue
            best = min(best, J(point))
            bound_ = J(nu)
            if bound_ < best:
                heapq.heappush(heap, (bound_, counter, nl, nu))
                counter += 1
    return best


# ------------------------------------------------------------------ public API

def min_cost(system: System, protocol: str, bounds=(0.0, 1.0), constraints: Sequence[Constraint] = ()) -> float:
    """The least optimal cost J*(mu) reachable within the bounds and constraints."""
    protocol = check_protocol(protocol)
    _, _, lo, hi = check_inputs(system, 1.0, np.zeros(system.m), bounds)
    G, h, calls = polytope(constraints, system.m)
    if protocol == "tcp":
        return tcp_min_cost(system, lo, hi, G, h, calls)
    return _udp_min_cost(system, lo, hi, G, h, calls)


def allocate(system: System, protocol: str, alpha: float, beta, bounds=(0.0, 1.0),
             constraints: Sequence[Constraint] = (), gap: float = 1e-4, max_boxes: int = 20000) -> Allocation:
    """The cheapest channel qualities mu (min beta'mu) with J*(mu) <= alpha.

    Parameters
    ----------
    system : System (stationary channel; its mu is ignored)
    protocol : {"tcp", "udp"}
    alpha : float
        Bound on the optimal expected cost.
    beta : array_like, shape (m,)
        Non-negative price of each channel's delivery probability.
    bounds : (lo, hi)
        Box for every mu_i, 0 <= lo <= hi <= 1.
    constraints : sequence
        Callables ``f(mu) -> cvxpy constraints`` or pairs ``(G, h)`` meaning ``G mu <= h``.
    gap : float
        Relative optimality gap certified for the UDP-like branch and bound.

    Raises
    ------
    InfeasibleError
        alpha is below the least reachable cost; ``min_cost`` carries that cost.
    SolverError
        A solver status other than optimal, or the B&B box budget exhausted.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0],
    ...            mu=[0.5], x0=[1.0])
    >>> a = allocate(s, "tcp", alpha=1.5, beta=[1.0])
    >>> bool(a.cost <= 1.5 * (1 + 1e-7))
    True
    """
    protocol = check_protocol(protocol)
    alpha, beta, lo, hi = check_inputs(system, alpha, beta, bounds)
    if not 0 < gap < 1:
        raise InputError("gap", f"expected a number in (0, 1), found {gap}")
    G, h, calls = polytope(constraints, system.m)

    def infeasible() -> InfeasibleError:
        least = min_cost(system, protocol, (lo, hi), constraints)
        return InfeasibleError(f"alpha = {alpha:g} is below the least reachable {protocol}-like cost "
                               f"{least:.6g} within the bounds and constraints", least)

    if protocol == "tcp":
        mu, status = tcp_allocate(system, alpha, beta, lo, hi, G, h, calls)
        if mu is None:
            raise infeasible()
        cost = cost_at(system, "tcp", mu)
        method = "convex SOCP (Clarabel)"
        if cost > alpha * (1 + 1e-7):   # solver tolerance: move towards a maximal point, say so
            q = BoxLP(system.m, G, h, calls).solve(-np.ones(system.m), np.full(system.m, lo), np.full(system.m, hi))
            t = boundary(lambda s: cost_at(system, "tcp", mu + s * (q - mu)), alpha, 0.0, 1.0, 1e-12)
            mu = mu + t * (q - mu)
            cost = cost_at(system, "tcp", mu)
            method += ", then pushed onto the feasible set by bisection"
        value = float(beta @ mu)
        # exact up to the solver's tolerances (1e-8 gap): the bound allows 1e-6 relative
        lower = value * (1 - 1e-6) - 1e-10
        return Allocation(mu=mu, communication_cost=value, cost=cost, lower_bound=lower,
                          gap=(value - lower) / max(value, 1e-12),
                          status="optimal", method=method, protocol=protocol, alpha=alpha, beta=beta)
    try:
        tcp_mu, _ = tcp_allocate(system, alpha, beta, lo, hi, G, h, calls)
    except SolverError:
        tcp_mu = None
    tcp_bound = float(beta @ tcp_mu) * (1 - 1e-7) if tcp_mu is not None else np.inf
    if tcp_mu is None:   # the relaxation is infeasible, so is the UDP-like problem (Theorem 2)
        raise infeasible()
    mu, lower, boxes = _udp_allocate(system, alpha, beta, lo, hi, G, h, calls, gap, max_boxes, tcp_bound)
    if mu is None:
        raise infeasible()
    value = float(beta @ mu)
    lower = min(lower, value)
    return Allocation(mu=mu, communication_cost=value, cost=cost_at(system, "udp", mu), lower_bound=lower,
                      gap=(value - lower) / max(value, 1e-12), status="optimal",
                      method="monotonic branch and bound (LP bounds, TCP-like relaxation)", protocol=protocol,
                      alpha=alpha, beta=beta, boxes=boxes)


def pareto_curve(system: System, protocol: str, beta, alphas: Sequence[float], **kwargs) -> list[dict]:
    """alpha -> (communication cost, mu) along the trade-off; infeasible alphas get None."""
    out = []
    for alpha in alphas:
        try:
            a = allocate(system, protocol, alpha, beta, **kwargs)
            out.append({"alpha": float(alpha), "communication_cost": a.communication_cost, "mu": a.mu.tolist()})
        except InfeasibleError:
            out.append({"alpha": float(alpha), "communication_cost": None, "mu": None})
    return out


def contour_allocations(system: System, protocol: str, alphas: Sequence[float],
                        betas: Sequence[Sequence[float]] = ((1, 1), (0.05, 1), (1, 0.05))) -> dict:
    """Figs. 6–7: the optimal allocation point on each cost contour alpha, for each beta."""
    return {tuple(beta): pareto_curve(system, protocol, beta, alphas) for beta in betas}


def best_cost_within_budget(system: System, protocol: str, beta, budget: float, bounds=(0.0, 1.0),
                            constraints: Sequence[Constraint] = ()) -> float:
    """The other side of the trade-off: min J*(mu) s.t. beta'mu <= budget (convex for TCP-like)."""
    beta = np.asarray(beta, dtype=float)
    if beta.shape != (system.m,) or np.any(beta < 0):
        raise InputError("beta", f"expected {system.m} non-negative numbers")
    return min_cost(system, protocol, bounds, [*constraints, (beta[None, :], np.array([float(budget)]))])
