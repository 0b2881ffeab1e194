"""UDP-like allocation by monotonic branch and bound.

J*_udp falls in each mu_i (Theorem 3), so its sublevel set ``{J* <= alpha}`` is an upper set:
whatever dominates a feasible point is feasible. It is not convex in general, so the search
runs over boxes [l, u] of the constraint set, best bound first:

* a box is *infeasible* when its upper corner is (``J*(u) > alpha (1 + ALLOCATION_COST_RTOL)``):
  every point of the box is dominated by u, so costs at least as much (Theorem 3);
* its lower corner is raised along each edge to the last point proven infeasible (the points
  below it are dominated by an infeasible point), and where an incumbent exists the upper
  corner is lowered to where beta'mu could still beat it;
* its lower bound is the LP ``min beta'mu`` over the box and the rows, proved by the exactly
  evaluated dual (:func:`~packetloss_cvx.allocation.boxes.box_lp`);
* incumbents are points the closed form finds feasible: the LP point, or the bisection
  between it and the box's maximal point.

Probes and checks: the bisections (edges, the incumbent's line) and the first look at a corner or LP point
evaluate J* without the one-point self-check (CostEvaluator.cost(checked=False): the same number wherever the
check passes). A wrong probe could (a) discard a feasible box, (b) raise l_i past a feasible point, or (c)
offer an infeasible incumbent, and so break the certificate; so each of these three decisions is taken only
on a checked value: the corner that discards, the point l_i is raised to (else the edge is bisected again,
checked), and every incumbent. Anything else a wrong probe can do only makes a bound weaker or an
incumbent worse (a box kept, l_i raised less, an incumbent missed), never wrong.

The search stops when ``(incumbent - lower bound) / incumbent <= gap`` (status "optimal"), or
at a cap (boxes, time; status "gap_not_certified" with the gap reached). It proves
infeasibility only when every box was discarded as infeasible (corner) or empty (LP).
Worst case the number of boxes grows like (1/gap)^(m-1); each costs an LP and
O(m log(1/tol)) closed forms of O(N (n^3 + m^3)).
"""

from __future__ import annotations

import heapq
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import InfeasibleError, SolverError
from ..model import System
from ..progress import progress_bar
from ..tolerances import (
    ALLOCATION_COST_RTOL,
    ALLOCATION_EDGE_ATOL,
    ALLOCATION_EDGE_RTOL,
    ALLOCATION_GAP_FLOOR,
    ALLOCATION_INCUMBENT_SHARE,
    ALLOCATION_MIN_BOX_WIDTH,
    MIN_COST_RTOL,
)
from .boxes import Outcome, boundary, box_lp, bracket, check_in_polytope, cost_function
from .grammar import Polytope
from .tcp import constant_cost

__all__ = ["Search", "split", "udp_allocate", "udp_min_cost"]

#: Channels with a price below this still get their sides split (scaled by it), so a free
#: channel does not stall the search.
SPLIT_WEIGHT_FLOOR = 1e-3


def split(l: np.ndarray, u: np.ndarray, weights: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """The two halves of the box [l, u] cut across its widest side, widths scaled by ``weights``;
    no halves when that side is narrower than ``ALLOCATION_MIN_BOX_WIDTH``. The one
    child-building routine of both searches. O(m).

    Examples
    --------
    >>> low, high = split(np.zeros(2), np.array([1.0, 0.5]), np.ones(2))      # cut across mu1 at 0.5
    >>> [v.tolist() for v in low + high]
    [[0.0, 0.0], [0.5, 0.5], [0.5, 0.0], [1.0, 0.5]]
    >>> split(np.zeros(2), np.array([1.0, 0.5]), np.array([0.1, 1.0]))[0][1].tolist()   # mu1 is cheap: cut mu2
    [1.0, 0.25]
    """
    i = int(np.argmax((u - l) * weights))
    if u[i] - l[i] < ALLOCATION_MIN_BOX_WIDTH:
        return ()
    mid = 0.5 * (l[i] + u[i])
    low_u, high_l = u.copy(), l.copy()
    low_u[i], high_l[i] = mid, mid
    return (l, low_u), (high_l, u)


class Search:
    """Best-first search over boxes for a minimum: the incumbent, the open boxes and the caps.

    ``floor`` is a lower bound known from elsewhere (the TCP-like relaxation, C). The
    certificate is ``incumbent - max(least open bound, floor) <= gap * incumbent``. Heap
    operations O(log boxes); the work is in ``visit``.

    Examples
    --------
    min mu over [0, 1] with mu >= 1/4 feasible: a box is bounded by max(l, 1/4), its upper corner is
    offered when feasible, and the search halves the boxes until the incumbent meets the bound.

    >>> search = Search(gap=1e-3, floor=0.0, max_boxes=100, time_limit=None)
    >>> def visit(bound, l, u, data):
    ...     if u[0] >= 0.25:
    ...         search.offer(u, float(u[0]))
    ...         for cl, cu in split(l, u, np.ones(1)):
    ...             search.push(max(float(cl[0]), 0.25), cl, cu, None)
    >>> search.push(0.25, np.zeros(1), np.ones(1), None)
    >>> out = search.outcome(search.run(visit), "bisection", "example")
    >>> out.mu.tolist(), out.value, out.lower_bound, out.status
    ([0.25], 0.25, 0.25, 'optimal')
    """

    def __init__(self, gap: float, floor: float, max_boxes: int, time_limit: float | None,
                 progress: bool | None = False) -> None:
        self.gap, self.floor, self.max_boxes, self.time_limit = gap, floor, max_boxes, time_limit
        self.progress = progress
        self.best, self.best_mu = np.inf, None
        self.heap: list = []
        self.counter = 0
        self.boxes = 0
        self.unsplit = np.inf    # least bound among boxes too small to split

    def offer(self, mu: np.ndarray, value: float) -> None:
        """Keep ``mu`` if it beats the incumbent (the caller has checked it is feasible)."""
        if value < self.best:
            self.best, self.best_mu = float(value), mu

    def push(self, bound: float, l: np.ndarray, u: np.ndarray, data) -> None:
        """Open the box [l, u] with its proven lower ``bound``. O(log boxes)."""
        heapq.heappush(self.heap, (bound, self.counter, l, u, data))
        self.counter += 1

    def lower_bound(self) -> float:
        """The proven bound: no admissible point beats the least open or unsplit box's bound,
        the incumbent, or the floor. O(1)."""
        open_ = self.heap[0][0] if self.heap else np.inf
        return max(min(open_, self.unsplit, self.best), self.floor)

    def certified(self) -> bool:
        """Whether the incumbent is within ``gap`` of the proven bound. O(1)."""
        return bool(np.isfinite(self.best)
                    and self.best - self.lower_bound() <= self.gap * max(abs(self.best), ALLOCATION_GAP_FLOOR))

    def run(self, visit: Callable[[float, np.ndarray, np.ndarray, object], None]) -> str:
        """Pop and visit boxes until certified, out of boxes, or at a cap (the first box is always
        visited); returns how it ended. ``visit(bound, l, u, data)`` offers incumbents and
        pushes children."""
        start = time.monotonic()
        with progress_bar(desc=f"branch and bound (boxes, cap {self.max_boxes})", progress=self.progress) as bar:
            while self.heap and not self.certified():
                if self.boxes >= self.max_boxes:
                    return f"stopped at the cap of {self.max_boxes} box{'es' if self.max_boxes != 1 else ''}"
                if self.boxes and self.time_limit is not None and time.monotonic() - start > self.time_limit:
                    return f"stopped at the time limit of {self.time_limit:g} s"
                bound, _, l, u, data = heapq.heappop(self.heap)
                self.boxes += 1
                visit(bound, l, u, data)
                bar.update()
        if self.certified():
            return "certified"
        if not np.isfinite(self.unsplit):
            return "exhausted"
        return f"boxes narrower than {ALLOCATION_MIN_BOX_WIDTH:g} left unresolved"

    def outcome(self, ended: str, method: str, what: str) -> Outcome:
        """The result, or InfeasibleError when every box was discarded by proof, or SolverError
        when no feasible point was found and infeasibility is not proven either."""
        if self.best_mu is None:
            if ended == "exhausted":
                raise InfeasibleError(f"{what}: every box was proven infeasible, its upper corner costing more "
                                      f"than alpha (Theorem 3) or the LP finding no point of the constraints in it "
                                      f"({self.boxes} box{'es' if self.boxes != 1 else ''} explored)", None)
            raise SolverError("gap_not_certified", f"{what}: no feasible mu found and infeasibility not proven; "
                              f"{ended}")
        lower = min(self.lower_bound(), self.best)
        status = "optimal" if ended in ("certified", "exhausted") else "gap_not_certified"
        note = method if status == "optimal" else f"{method}; {ended}"
        return Outcome(self.best_mu, self.best, lower, status, self.boxes, note)


def udp_allocate(system: System, poly: Polytope, alpha: float, beta: np.ndarray, gap: float, floor: float,
                 max_boxes: int, time_limit: float | None, progress: bool | None = False,
                 evaluator: Any = None) -> Outcome:
    """min beta'mu over the polytope with J*_udp(mu) <= alpha, to a relative ``gap``.

    ``floor`` is a proven lower bound from elsewhere (the TCP-like relaxation, Theorem 2). ``evaluator``: another
    cost nonincreasing in each mu_i with the ``cost(mu, checked)`` / ``line(mu, i, checked)`` interface of
    :class:`~packetloss_cvx.evaluator.CostEvaluator` (:class:`~packetloss_cvx.allocation.chains.ChainEvaluator`:
    the exact cost behind chains); default the system's J*_udp.
    Cost per box and worst-case box count: see the module docstring.

    Raises
    ------
    InfeasibleError
        Every box discarded by proof (upper corner infeasible, or LP empty).
    SolverError
        An LP failure, or a cap reached before any feasible point was found.

    Examples
    --------
    Two decoupled copies of x' = x + v u (N = 1): J*_udp = sum (1 - mu_i/2), so J*_udp <= 1.5 is
    mu1 + mu2 >= 1; with mu2 twice as dear the cheapest point is (1, 0).

    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> out = udp_allocate(t, read_polytope([], 2, 0.0, 1.0), 1.5, np.array([1.0, 2.0]), 1e-3, -np.inf, 1000, None)
    >>> out.status, bool(out.lower_bound <= 1 <= out.value <= 1 + 1e-3), bool(np.allclose(out.mu, [1, 0], atol=1e-3))
    ('optimal', True, True)
    """
    m = system.m
    J, evaluator = _cost(system, evaluator)
    prune_above = alpha * (1 + ALLOCATION_COST_RTOL)
    weights = np.maximum(beta, SPLIT_WEIGHT_FLOOR)
    search = Search(gap, max(floor, float(beta @ poly.lower())), max_boxes, time_limit, progress)

    def probe(mu: np.ndarray) -> float:
        """J*(mu) without the one-point self-check (the same number wherever the check passes): a probe
        only steers; :func:`J` (checked) confirms each value a decision rests on."""
        return evaluator.cost(np.clip(mu, 0.0, 1.0), checked=False)

    def bound(l: np.ndarray, u: np.ndarray):
        """Reduce the box; (lower bound, l, u, LP point), or None when proven infeasible or empty
        or unable to beat the incumbent."""
        if probe(u) > prune_above and J(u) > prune_above:       # discarding needs the checked value
            return None
        l, u = l.copy(), u.copy()
        corner = np.clip(u, 0.0, 1.0)
        for i in range(m):                       # raise l_i to the last point proven infeasible on edge i
            if l[i] < u[i]:
                l[i] = edge(corner, i, l[i], u[i])
        if np.isfinite(search.best):             # lower u where beta'mu would not beat the incumbent
            rest = beta @ l - beta * l
            positive = beta > 0
            u[positive] = np.minimum(u[positive], (search.best - rest[positive]) / beta[positive])
            if np.any(u < l):
                return None
        p, lb = box_lp(beta, poly, l, u)
        if p is None:
            return None
        return lb, l, u, p

    def edge(corner: np.ndarray, i: int, a: float, b: float) -> float:
        """The last point of edge i (the other channels at the corner, the other channels factored once) that
        is infeasible, found by unchecked probes; the one point l_i is raised to is then confirmed by a
        checked evaluation (a wrong probe could only move it: if the checked value is not above the bound,
        the bisection is run again with checked values, as before)."""
        tol = ALLOCATION_EDGE_ATOL + ALLOCATION_EDGE_RTOL * (b - a)
        start = corner.copy()
        start[i] = min(max(a, 0.0), 1.0)
        if probe(start) <= prune_above:          # nothing to raise: one point, no line factored
            return a
        for checked in (False, True):
            line = evaluator.line(corner, i, checked)

            def along(s: float, line=line) -> float:
                return line(min(max(s, 0.0), 1.0))

            out = bracket(along, prune_above, a, b, tol)[1]
            start[i] = min(max(out, 0.0), 1.0)
            if out == a or checked or J(start) > prune_above:
                return out
        raise AssertionError("unreachable")

    def visit(lb: float, l: np.ndarray, u: np.ndarray, p: np.ndarray) -> None:
        if probe(p) <= alpha and J(p) <= alpha:               # an incumbent needs the checked value
            search.offer(p, float(beta @ p))
        else:
            q, _ = box_lp(-np.ones(m), poly, l, u)          # a maximal point of the box and rows
            Jq = None if q is None else probe(q)
            if Jq is not None and Jq <= alpha:
                t = boundary(lambda s: probe(p + s * (q - p)), alpha, 0.0, 1.0, ALLOCATION_INCUMBENT_SHARE * gap, Jq)
                point = p + t * (q - p)
                if J(point) <= alpha:
                    search.offer(point, float(beta @ point))
        halves = split(l, u, weights)
        if not halves:
            search.unsplit = min(search.unsplit, lb)
            return
        for nl, nu in halves:
            child = bound(nl, nu)
            if child is not None:
                search.push(child[0], child[1], child[2], child[3])

    root = bound(poly.lower(), poly.upper())
    if root is not None:
        search.push(root[0], root[1], root[2], root[3])
    ended = search.run(visit)
    out = search.outcome(ended, "monotonic branch and bound (certified LP bounds)", "UDP-like allocation")
    check_in_polytope(out.mu, poly, "UDP-like allocation")
    return out


def _cost(system: System, evaluator: Any) -> tuple[Callable[[np.ndarray], float], Any]:
    """``(J, evaluator)``: the system's J*_udp, or the given evaluator's checked cost."""
    if evaluator is None:
        return cost_function(system, "udp")
    return (lambda mu: evaluator.cost(np.clip(mu, 0.0, 1.0))), evaluator


def udp_min_cost(system: System, poly: Polytope, max_boxes: int, time_limit: float | None,
                 evaluator: Any = None) -> Outcome:
    """min J*_udp over the polytope, to ``MIN_COST_RTOL``: the minimum sits at a maximal point;
    boxes are bounded by J*(upper corner) (Theorem 3) and incumbents are maximal LP points.

    Raises
    ------
    InfeasibleError
        The constraints admit no mu.

    Notes
    -----
    One closed form without rows; otherwise up to ``max_boxes`` boxes, each two LPs and two
    closed forms of O(N (n^3 + m^3)).

    Examples
    --------
    J*_udp = 1 - mu/2 (one step of x' = x + v u from x0 = 1) is least at the box's upper end:

    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> out = udp_min_cost(s, read_polytope([], 1, 0.0, 0.5), 10, None)
    >>> out.mu.tolist(), out.value, out.lower_bound, out.status
    ([0.5], 0.75, 0.75, 'optimal')
    """
    m = system.m
    J, _ = _cost(system, evaluator)
    lower, upper = poly.lower(), poly.upper()
    q, _ = box_lp(-np.ones(m), poly, lower, upper)
    if q is None:
        raise InfeasibleError("the linear constraints and bounds admit no mu", None)
    if not poly.G.shape[0]:                                # the box alone: its upper corner
        value = J(upper)
        return Outcome(upper, value, value, "optimal", 0, "upper corner of the box (Theorem 3)")
    search = Search(MIN_COST_RTOL, constant_cost(system), max_boxes, time_limit)
    search.offer(q, J(q))
    search.push(J(upper), lower, upper, None)

    def visit(lb: float, l: np.ndarray, u: np.ndarray, _data) -> None:
        halves = split(l, u, np.ones(m))
        if not halves:
            search.unsplit = min(search.unsplit, lb)
            return
        for nl, nu in halves:
            point, _ = box_lp(-np.ones(m), poly, nl, nu)
            if point is None:
                continue
            search.offer(point, J(point))
            bound = J(nu)
            if bound < search.best:
                search.push(bound, nl, nu, None)

    ended = search.run(visit)
    out = search.outcome(ended, "branch and bound on maximal points (bound J*(upper corner))",
                         "UDP-like minimum cost")
    check_in_polytope(out.mu, poly, "UDP-like minimum cost")
    return out
