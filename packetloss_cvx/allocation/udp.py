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

import numpy as np

from ..errors import InfeasibleError, SolverError
from ..model.system import System
from ..progress import progress_bar
from ..tolerances import (
    ALLOCATION_COST_RTOL,
    ALLOCATION_EDGE_ATOL,
    ALLOCATION_EDGE_RTOL,
    ALLOCATION_INCUMBENT_SHARE,
    ALLOCATION_LP_FEASIBILITY,
    ALLOCATION_MIN_BOX_WIDTH,
    MIN_COST_RTOL,
)
from .boxes import (
    Outcome,
    boundary,
    box_bound,
    box_lp,
    bracket,
    check_in_polytope,
    cost_function,
    gap_unit,
    polytope_excess,
    reported_gap,
)
from .grammar import Polytope
from .tcp import constant_cost

__all__ = ["MonotoneCost", "Search", "gap_unit", "reported_gap", "row_caps", "split", "udp_allocate", "udp_min_cost"]

#: Channels with a price below this still get their sides split (scaled by it), so a free
#: channel does not stall the search.
SPLIT_WEIGHT_FLOOR = 1e-3


class MonotoneCost:
    """The function the searches minimise or bound: ``x -> J*(mu(x))`` on ``x`` in [0, 1]^m, with
    ``mu(x) = (phi_1(x_1), .., phi_m(x_m))`` a non-decreasing map per channel into [0, 1] (identity: the
    delivery probabilities themselves; :mod:`.power`: the delivery that a power ``top_i x_i`` buys). J*
    falls in every mu_i (Theorem 3), so this function falls in every x_i: every argument of the searches
    (corners, edges, dominated points) holds for it unchanged. ``probe`` is the unchecked value
    (:meth:`CostEvaluator.cost` ``checked=False``), ``checked`` the checked one, ``line`` the evaluator's
    line with the other channels factored once. Each call O(m) plus the evaluator's.

    Examples
    --------
    J*_udp = 1 - mu/2 (one step of x' = x + v u from x0 = 1); through phi(x) = x^2 at x = 0.5 it is 1 - 1/8:

    >>> from packetloss_cvx.lq.evaluator import CostEvaluator
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> f = MonotoneCost(CostEvaluator(s, "udp"), lambda x: x ** 2, lambda i, t: t ** 2)
    >>> f.checked(np.array([0.5])), f.probe(np.array([0.5])), f.line(np.array([1.0]), 0, True)(0.5)
    (0.875, 0.875, 0.875)
    """

    def __init__(self, evaluator, to_mu: Callable[[np.ndarray], np.ndarray] | None = None,
                 channel: Callable[[int, float], float] | None = None) -> None:
        self.evaluator = evaluator
        self.identity = to_mu is None
        self.to_mu = (lambda x: x) if to_mu is None else to_mu
        self.channel = (lambda i, t: t) if channel is None else channel
        # the checked values already computed, by the bytes of the clipped x: the searches check the same point
        # again (udp_min_cost's LP vertex is shared by boxes; a box's upper corner is its upper half's). A checked
        # value also answers a probe (the probe's number wherever the check passes, the better one where it
        # fails). Probes are not remembered: a probe is allowed to be wrong, and asking again is what lets a
        # search steered by a wrong probe recover (tests/allocation/test_allocation_certificates.py's wrong probes)
        self.known: dict[bytes, float] = {}

    def mu(self, x: np.ndarray) -> np.ndarray:
        """mu(x) for x clipped to [0, 1]^m, clipped to [0, 1] (the identity: clipped once, the same floats; the
        array method that np.clip calls, without its wrapper). O(m)."""
        return self._of_clipped(np.asarray(x, dtype=float).clip(0.0, 1.0))

    def _of_clipped(self, x: np.ndarray) -> np.ndarray:
        """mu(x) for x already in [0, 1]^m (:meth:`mu` after its clip). O(m)."""
        return x if self.identity else np.clip(self.to_mu(x), 0.0, 1.0)

    def checked(self, x: np.ndarray) -> float:
        """J*(mu(x)), self-checked; a point asked before answered from memory (the same float). O(m) then."""
        x = np.asarray(x, dtype=float).clip(0.0, 1.0)
        key = x.tobytes()
        value = self.known.get(key)
        if value is None:
            value = self.evaluator.cost(self._of_clipped(x))
            remember(self.known, key, value)
        return value

    def probe(self, x: np.ndarray) -> float:
        """J*(mu(x)) without the one-point self-check (searches only); a point checked before answered from
        memory."""
        x = np.asarray(x, dtype=float).clip(0.0, 1.0)
        value = self.known.get(x.tobytes())
        if value is None:
            value = self.evaluator.cost(self._of_clipped(x), checked=False)
        return value

    def line(self, x: np.ndarray, i: int, checked: bool) -> Callable[[float], float]:
        """``t -> J*(mu(x with x_i = t))`` for t in [0, 1]."""
        along = self.evaluator.line(self.mu(x), i, checked)
        return lambda t: along(min(max(float(self.channel(i, min(max(t, 0.0), 1.0))), 0.0), 1.0))


#: the most checked values a :class:`MonotoneCost` keeps: about 100 bytes each at m = 2;
#: beyond it the memory starts again (the values are the same; only the repeats cost again)
MEMORY_MAX = 2**16


def remember(memory: dict, key: bytes, value: float) -> None:
    """``memory[key] = value``, the memory emptied first when it holds ``MEMORY_MAX`` values. O(1) amortised."""
    if len(memory) >= MEMORY_MAX:
        memory.clear()
    memory[key] = value


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
    certificate is ``incumbent - max(least open bound, floor) <= gap * incumbent``, the incumbent floored at
    ``ALLOCATION_GAP_FLOOR * scale`` (``scale`` the problem's own size, e.g. its largest cost: an absolute floor
    certified anything where every cost is below 1e-12, as with weights of 1e-20). Heap
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
                 progress: bool | None = False, scale: float = 1.0) -> None:
        self.gap, self.floor, self.max_boxes, self.time_limit = gap, floor, max_boxes, time_limit
        self.scale = scale
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

    def branch(self, l: np.ndarray, u: np.ndarray, lb: float, weights: np.ndarray,
               bound: Callable[[np.ndarray, np.ndarray], tuple | None]) -> None:
        """Split the box [l, u] (proven bound ``lb``) and open each half that ``bound`` does not discard; a box
        too small to split keeps ``lb`` in ``unsplit``. O(m) plus ``bound``'s work per half."""
        halves = split(l, u, weights)
        if not halves:
            self.unsplit = min(self.unsplit, lb)
            return
        for nl, nu in halves:
            child = bound(nl, nu)
            if child is not None:
                self.push(*child)

    def lower_bound(self) -> float:
        """The proven bound: no admissible point beats the least open or unsplit box's bound,
        the incumbent, or the floor. O(1)."""
        open_ = self.heap[0][0] if self.heap else np.inf
        return max(min(open_, self.unsplit, self.best), self.floor)

    def certified(self) -> bool:
        """Whether the incumbent is within ``gap`` of the proven bound. O(1)."""
        return bool(np.isfinite(self.best) and self.best - self.lower_bound() <= self.gap * gap_unit(self.best,
                                                                                                    self.scale))

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
        return Outcome(self.best_mu, self.best, lower, status, self.boxes, note, scale=self.scale)


def udp_allocate(system: System, poly: Polytope, alpha: float, beta: np.ndarray, gap: float, floor: float,
                 max_boxes: int, time_limit: float | None, progress: bool | None = False,
                 cost: MonotoneCost | None = None, incumbent: np.ndarray | None = None,
                 what: str = "UDP-like allocation") -> Outcome:
    """min beta'mu over the polytope with J*_udp(mu) <= alpha, to a relative ``gap``.

    ``floor`` is a proven lower bound from elsewhere (the TCP-like relaxation, Theorem 2).
    ``cost``: any falling function of the coordinates in place of J*_udp (:class:`MonotoneCost`; the
    power allocation of :mod:`.power`); ``incumbent``: a point to offer first (kept only if the
    checked cost says it is feasible and it meets the polytope).
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
    f = MonotoneCost(cost_function(system, "udp")[1]) if cost is None else cost
    J = f.checked
    prune_above = alpha * (1 + ALLOCATION_COST_RTOL)
    weights = np.maximum(beta, SPLIT_WEIGHT_FLOOR)
    search = Search(gap, max(floor, float(beta @ poly.lower())), max_boxes, time_limit, progress)
    if incumbent is not None and polytope_excess(incumbent, poly) <= ALLOCATION_LP_FEASIBILITY \
            and J(incumbent) <= alpha:
        search.offer(incumbent, float(beta @ incumbent))

    def probe(mu: np.ndarray) -> float:
        """J*(mu) without the one-point self-check (the same number wherever the check passes): a probe
        only steers; :func:`J` (checked) confirms each value a decision rests on."""
        return f.probe(mu)

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
        return box_bound(beta, poly, l, u, search.best)

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
            line = f.line(corner, i, checked)

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
        search.branch(l, u, lb, weights, bound)

    root = bound(poly.lower(), poly.upper())
    if root is not None:
        search.push(root[0], root[1], root[2], root[3])
    ended = search.run(visit)
    out = search.outcome(ended, "monotonic branch and bound (certified LP bounds)", what)
    check_in_polytope(out.mu, poly, what)
    return out


def row_caps(poly: Polytope, l: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The upper corner of [l, u] lowered to what each row allows a coordinate alone: for a row ``g'mu <= h``
    with ``g_i > 0``, ``mu_i <= (h - sum_{j != i} min(g_j l_j, g_j u_j)) / g_i``. Every point of the box that
    meets the rows lies below it, so J* there (Theorem 3) bounds the box as the corner does, tighter where
    the box straddles a row (a budget's face). O(m r).

    Examples
    --------
    >>> from packetloss_cvx.allocation.grammar import read_polytope
    >>> poly = read_polytope([([[1.0, 1.0]], [1.0])], 2, 0.0, 1.0)        # mu1 + mu2 <= 1
    >>> row_caps(poly, np.array([0.25, 0.5]), np.ones(2)).tolist()
    [0.5, 0.75]
    """
    cap = u.copy()
    if not poly.G.shape[0]:
        return cap
    least = np.minimum(poly.G * l, poly.G * u)            # (r, m)
    rest = least.sum(axis=1, keepdims=True) - least       # the other coordinates' least contribution
    with np.errstate(divide="ignore", invalid="ignore"):
        limit = np.where(poly.G > 0, (poly.h[:, None] - rest) / np.where(poly.G > 0, poly.G, 1.0), np.inf)
    return np.maximum(np.minimum(cap, limit.min(axis=0)), l)


def udp_min_cost(system: System, poly: Polytope, max_boxes: int, time_limit: float | None,
                 cost: MonotoneCost | None = None, incumbent: np.ndarray | None = None, floor: float = -np.inf,
                 what: str = "UDP-like minimum cost", gap: float = MIN_COST_RTOL) -> Outcome:
    """min J*_udp over the polytope, to ``MIN_COST_RTOL``: the minimum sits at a maximal point;
    boxes are bounded by J*(upper corner) (Theorem 3) and incumbents are maximal LP points.
    ``cost``, ``incumbent``: as for :func:`udp_allocate`; ``floor``: a proven lower bound from elsewhere;
    ``gap``: the relative gap to certify.

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
    J = (MonotoneCost(cost_function(system, "udp")[1]) if cost is None else cost).checked
    lower, upper = poly.lower(), poly.upper()
    q, _ = box_lp(-np.ones(m), poly, lower, upper)
    if q is None:
        raise InfeasibleError("the linear constraints and bounds admit no mu", None)
    if not poly.G.shape[0]:                                # the box alone: its upper corner
        value = J(upper)
        return Outcome(upper, value, value, "optimal", 0, "upper corner of the box (Theorem 3)")
    # the gap's floor in the problem's own size, J* at the lower corner (the largest cost on the box)
    search = Search(gap, max(constant_cost(system), floor), max_boxes, time_limit, scale=abs(J(lower)))
    search.offer(q, J(q))
    if incumbent is not None and polytope_excess(incumbent, poly) <= ALLOCATION_LP_FEASIBILITY:
        search.offer(incumbent, J(incumbent))
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
            nu = row_caps(poly, nl, nu)
            bound = J(nu)
            if bound < search.best:
                search.push(bound, nl, nu, None)

    ended = search.run(visit)
    out = search.outcome(ended, "branch and bound on maximal points (bound J* at the corner the rows allow)", what)
    check_in_polytope(out.mu, poly, what)
    return out
