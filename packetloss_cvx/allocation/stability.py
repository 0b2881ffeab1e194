"""Design for stability: the cheapest delivery probabilities whose loop some linear law
holds with a margin, or whose DP law costs at most alpha.

.. math:: \\min_\\mu \\beta'\\mu \\quad\\text{s.t.}\\quad \\mu \\in S_\\rho = \\{\\mu : \\min_K \\rho(L_K) < \\rho\\}
   \\ (\\text{target "stable"}) \\quad\\text{or}\\quad J_{dp}(\\mu) \\le \\alpha\\ (\\text{target "dp-cost"}),
   \\quad \\mu \\in [lo, hi]^m,\\ G\\mu \\le h.

``rho(L_K)`` is the mean-square radius (the spectral radius of the second-moment operator,
simulation.stability.mean_square_radius, not its square root). ``S_rho`` of the plant (A, B) is S of the plant
``(A, B) / sqrt(rho)`` (``L_K`` is quadratic in (A, B)), so membership and both certificates are the stabilisable
set's (simulation.region.membership) on the scaled plant. ``J_dp`` is the DP law's stationary cost
(simulation.riccati.dp_riccati): the average stage cost ``tr(P Sigma_W)`` when the file has process noise, else
the total cost ``x0'P x0`` from the file's x0 (a noise-free loop's average cost is 0 wherever it is stable).

Neither feasible set is convex in mu (docs/mathematics.md §2, "Design for stability": the one-state example), and in
the odds, where the one-state S_rho is a half-space, the objective ``beta'mu = sum beta_i s_i / (1 + s_i)`` is
concave: no convex program in mu or the odds computes the optimum. Both sets are upper sets (proved there:
``min_K rho(L_K)`` and the DP cost-to-go P fall in each mu_i), so the search is the monotone branch and bound of
`.udp` on a verdict instead of a cost:

* a box is discarded when its upper corner is certified outside (an infeasibility certificate ``T(P) >= 0`` of
  the scaled plant checked in numpy, or a DP cost above ``alpha (1 + ALLOCATION_COST_RTOL)``);
* its lower corner is raised along each edge to the last point certified outside;
* its lower bound is the LP ``min beta'mu`` over the box and rows (`box_lp`, dual evaluated
  exactly);
* incumbents are points certified inside: a gain whose radius the operator proves ``< rho (1 - margin)``, or a
  DP solution whose cost is ``<= alpha``.

An undecided point (near the boundary, or a solver failure) is never a verdict: it discards
nothing, raises no corner and offers no incumbent. One channel is a bisection on verdicts instead (`_line`): its
set is an interval, and an undecided band wider than the gap is named, not split for ever. Worst case
``(1/gap)^(m-1)`` boxes, each an LP and ``O(m log(1/tol))`` memberships (a homogeneous Riccati eigenpair,
O(iterations (n^3 + m^3)); a DP solution for "dp-cost").
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from ..budgets import check, count_text
from ..closedloop.actuator import Actuator, parse_actuator
from ..closedloop.actuator_design import ActuatorDesign, actuator_dp, design_modes
from ..closedloop.actuator_region import actuator_membership, least_radius
from ..closedloop.region import LazyLmi, homogeneous_riccati, membership
from ..closedloop.riccati import dp_riccati
from ..closedloop.stability import mean_square_radius
from ..display import apart
from ..errors import InfeasibleError, InputError, NumericalError, SolverError
from ..model.system import System
from ..results.region import StabilityAllocation
from ..threads import blas_limited
from ..tolerances import (
    ALLOCATION_COST_RTOL,
    ALLOCATION_EDGE_ATOL,
    ALLOCATION_EDGE_RTOL,
    ALLOCATION_GAP_DEFAULT,
    ALLOCATION_INCUMBENT_SHARE,
    MEAN_SQUARE_MARGIN,
)
from .attainable import tcp_attainable_cost
from .boxes import Outcome, box_bound, box_lp, bracket, check_in_polytope, gap_unit, reported_gap, unit_prices
from .chains import ChainFamily, chain_family
from .grammar import (
    Constraint,
    Polytope,
    check_alpha,
    check_beta,
    check_bounds,
    check_count,
    check_gap,
    check_number,
    check_system,
    read_polytope,
)
from .tcp import interval
from .udp import SPLIT_WEIGHT_FLOOR, Search

__all__ = ["DP_COST_BOUNDARY", "TARGETS", "Point", "dp_cost", "stability_allocate", "strategy_dp_cost"]

#: The DP cost at an allocation's mu is reported only where the DP law's radius is below 1 by this much: the cheapest
#: stabilisable links lie on the stabilisable set's boundary, where the cost grows like 1 / (1 - radius) and the
#: Riccati solution is decided by rounding (two_actuator's --target stable: radius 1 - 1e-7, a cost of 7.8e8 under
#: OpenBLAS's Sandybridge kernel and no solution under Prescott; the pendulum's 3.1e10 moved 5.3e-5 between kernels).
#: A margin below 1 (--margin) keeps mu inside, where the cost is well conditioned.
DP_COST_BOUNDARY = 1e-6

#: what the design asks of the loop
TARGETS = ("stable", "dp-cost")

#: default cap on the boxes (as allocation.api.MAX_BOXES)
MAX_BOXES = 20000


class Point(NamedTuple):
    """One decided (or undecided) channel: ``verdict`` "in", "out" or "undecided"; for "in" the ``gain`` that
    proves it, its ``radius`` on the unscaled plant and, for "dp-cost", the DP ``cost``."""

    verdict: str
    gain: np.ndarray | None = None
    radius: float = float("nan")
    cost: float = float("nan")


def dp_cost(system: System, riccati) -> tuple[float, str]:
    """The DP law's stationary cost and its kind: ``tr(P Sigma_W)`` ("average") when the system has process
    noise, else ``x0'P x0`` ("total from x0"). O(n^2).

    Examples
    --------
    >>> from packetloss_cvx.closedloop.riccati import dp_riccati
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> cost, kind = dp_cost(s, dp_riccati(s))     # DARE: p = 1 + 4p - 4p^2/(1 + p), p = 2 + sqrt(5)
    >>> bool(np.isclose(cost, 2 + 5 ** 0.5)), kind
    (True, 'total from x0')
    """
    P = riccati.cost_to_go
    if np.any(system.noise_cov != 0):
        return float(np.sum(P * system.noise_cov)), "average"
    return float(system.x0 @ P @ system.x0), "total from x0"


def strategy_dp_cost(system: System, design: ActuatorDesign) -> tuple[float, str]:
    """A strategy's optimal TCP-like law's stationary cost (closedloop.actuator_design.actuator_dp) and its kind, as
    `dp_cost`: the average stage cost when the system has process noise ("average"), else the total noise-free cost
    from x0 ("total from x0"). For "zero" it is `dp_cost` of the channel's own DP. O(1).

    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> cost, kind = strategy_dp_cost(s, actuator_dp(s, "hold"))     # every packet arrives: the DARE, 2 + sqrt(5)
    >>> bool(np.isclose(cost, 2 + 5 ** 0.5)), kind
    (True, 'total from x0')
    """
    if np.any(system.noise_cov != 0):
        return float(design.cost), "average"
    return float(design.initial), "total from x0"


def _scaled(system: System, rho: float) -> System:
    """The plant (A, B) / sqrt(rho) with the same weights: its S is S_rho of ``system``. O(n^2 + n m)."""
    root = math.sqrt(rho)
    return System(A=system.A / root, B=system.B / root, horizon=1, x0=system.x0,
                  state_weight=system.state_weights[0], input_weight=system.input_weights[0],
                  mu=np.ones(system.m))


def _radius_bound(margin) -> float:
    if margin is None:
        return 1.0
    rho = check_number(margin, "margin")
    if not 0.0 < rho <= 1.0:
        raise InputError("margin", f"expected a bound rho on the mean-square radius with 0 < rho <= 1, found {rho:g}")
    return rho


#: the membership forms the search asks, the first that decides answering: the homogeneous Riccati eigenpair (cheap,
#: both certificates), then the LMI (where the eigenpair's gain misses a block, e.g. decoupled plants); and those
#: that decide the answer once more, all of them cross-checked
SEARCH_FORMS, CHECK_FORMS = ("riccati", "lmi"), ("riccati", "dp", "lmi")

#: a probe's value where the DP solution fails or the loop is outside S (log(J / alpha) is far below it)
_OUTSIDE = 40.0
#: how far (relative) beyond the boundary a line search aims: 100 MEAN_SQUARE_MARGIN, so that the point it
#: proposes is certified rather than undecided (the certificates' tolerances are 1e-9), and no rounding-level
#: LMI certificate (1e-12 of T's scale, which a large gain stretches) contradicts a point 1e-8 inside: with 10,
#: two_actuator at rho = 0.5 ended in CrossCheckError; the certificate's tolerance
#: is now a band on the radius, which a gain does not stretch, and the aim is kept as the search's margin)
_AIM = 100 * MEAN_SQUARE_MARGIN


class Target(NamedTuple):
    """A target's two views of a channel: ``decide(mu)``, a `Point` resting on a certificate checked in
    numpy, and ``probe(mu)``, an unchecked number that is monotone (non-increasing) in each mu_i and crosses
    ``level`` at the boundary (it only steers the line searches; every decision is taken on ``decide``). The
    line searches aim ``_AIM`` (relative) beyond the level, to the side they need certified, so that their
    point clears the certificate's own tolerance (MEAN_SQUARE_MARGIN, ALLOCATION_COST_RTOL)."""

    decide: Callable[[np.ndarray], Point]
    probe: Callable[[np.ndarray], float]
    level: float

    def inside(self) -> float:
        """The level a point proposed as inside aims below."""
        return self.level - _AIM * max(abs(self.level), 1.0)

    def outside(self) -> float:
        """The level a point proposed as outside aims above."""
        return self.level + _AIM * max(abs(self.level), 1.0)


class _Recent:
    """``f(mu)`` remembered for the last `_RECENT` channels (keyed by ``mu.tobytes()``; a raised
    NumericalError is remembered too): a line search's probe and the verdict that follows it at the same point
    share one homogeneous Riccati eigenpair and one DP solution (a third to two fifths of them on two_actuator).
    The same call on the same floats, so the same numbers. O(1) a look-up; memory O(_RECENT n^2)."""

    def __init__(self, f: Callable[[np.ndarray], object]) -> None:
        self.f = f
        self.kept: dict[bytes, object] = {}

    def __call__(self, mu: np.ndarray):
        key = np.asarray(mu, dtype=float).tobytes()
        if key not in self.kept:
            try:
                self.kept[key] = self.f(mu)
            except NumericalError as err:
                self.kept[key] = err
            if len(self.kept) > _RECENT:
                del self.kept[next(iter(self.kept))]
        found = self.kept[key]
        if isinstance(found, NumericalError):
            raise found
        return found


#: how many channels :class:`_Recent` keeps (the probe and the verdict at one point are a few calls apart)
_RECENT = 64


def _memos(system: System, rho: float) -> tuple[_Recent, _Recent]:
    """The scaled plant's homogeneous Riccati eigenpairs and the system's DP solutions, each a `_Recent`:
    kept by the search and handed to the final check, which asks them again at the answer's mu. Each eigenpair's
    power iteration starts from the last one's P (homogeneous_riccati's ``start``): the search asks along lines
    and edges, where consecutive channels are near. O(1)."""
    plant = _scaled(system, rho)
    last: list[np.ndarray] = []

    def eigenpair(mu: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        found = homogeneous_riccati(plant.A, plant.B, mu, start=last[0] if last else None)
        if np.all(np.isfinite(found[1])):
            last[:] = [found[1]]
        return found

    return _Recent(eigenpair), _Recent(lambda mu: dp_riccati(system, mu))


def _target(system: System, target: str, rho: float, alpha: float | None, check: bool = False,
            memos: tuple[_Recent, _Recent] | None = None) -> Target:
    """The target's `Target`: its verdicts from [`membership`][packetloss_cvx.closedloop.region.membership]'s
    SEARCH_FORMS, or with ``check`` its CHECK_FORMS cross-checked (forms that decide differently raise
    CrossCheckError). ``memos`` (`_memos`, made here when not given): the check shares the search's, so the
    answer's eigenpair and DP solution, the same calls on the same floats, are not computed twice."""
    plant = _scaled(system, rho)
    lmi = LazyLmi(plant.A, plant.B)
    A, B = system.A, system.B
    forms = CHECK_FORMS if check else SEARCH_FORMS
    eigenpairs, solutions = _memos(system, rho) if memos is None else memos

    def stable(mu: np.ndarray) -> Point:
        found = membership(plant, mu, forms=forms, cross_check=check, lmi=lmi, riccati=eigenpairs(mu))
        if found.verdict == "unstable":
            return Point("out")
        if found.verdict == "undecided":
            return Point("undecided")
        return Point("in", found.gain, rho * found.radius)

    def least_radius(mu: np.ndarray) -> float:
        """min_K rho(L_K) of the scaled plant (< 1 inside S_rho), unchecked."""
        return eigenpairs(mu)[0]

    if target == "stable":
        return Target(stable, least_radius, 1.0)

    def within(mu: np.ndarray) -> Point:
        if stable(mu).verdict == "out":        # no law holds the loop: no finite cost
            return Point("out")
        try:
            dp = solutions(mu)
        except NumericalError:                  # not a verdict
            return Point("undecided")
        cost, _ = dp_cost(system, dp)
        if cost <= alpha:
            return Point("in", dp.gain, mean_square_radius(A, B, dp.gain, mu), cost)
        if cost > alpha * (1.0 + ALLOCATION_COST_RTOL):
            return Point("out")
        return Point("undecided")

    def log_cost(mu: np.ndarray) -> float:
        """log(J_dp / alpha), unchecked; _OUTSIDE plus the least radius where no law holds the loop or the DP
        solution fails (still monotone: J_dp is infinite there)."""
        lam = least_radius(mu)
        if not lam < 1.0:
            return _OUTSIDE + lam
        try:
            cost, _ = dp_cost(system, solutions(mu))
        except NumericalError:
            return _OUTSIDE
        return math.log(max(cost, np.finfo(float).tiny) / alpha)

    return Target(within, log_cost, 0.0)


def _strategy_at(system: System, family: ChainFamily | None):
    """``mu -> (system, mu, channel)``: the arguments of actuator_dp and actuator_membership at the channel mu, and
    the channel design_modes takes: Bernoulli links ``(system, mu, mu)``; behind a chain the system moved to mean
    rates mu along its family (`.chains.chain_family`), ``(system at mu, None, its chain)``."""
    if family is None:
        return lambda mu: (system, mu, mu)

    def at(mu: np.ndarray):
        moved = system.with_channel(family.channel_at(np.asarray(mu, dtype=float)))
        return moved, None, moved.channel

    return at


def _strategy_memo(system: System, strategy: Actuator, at) -> _Recent:
    """The strategy's optimal TCP-like law per channel (actuator_dp), a `_Recent` shared by the search and the
    final check."""
    def design(mu: np.ndarray) -> ActuatorDesign:
        moved, rates, _ = at(mu)
        return actuator_dp(moved, strategy, rates)

    return _Recent(design)


def _strategy_target(system: System, strategy: Actuator, target: str, alpha: float | None,
                     designs: _Recent, at) -> Target:
    """The target's `Target` for an actuator strategy (closedloop.actuator*): "stable", a TCP-like law of the
    strategy proved mean-square stable (actuator_membership: exact certificates either way); "dp-cost", the
    strategy's optimal TCP-like law costs at most alpha (`strategy_dp_cost`), decided as for zero: a DP solution
    whose cost is ``<= alpha`` is inside, one above ``alpha (1 + ALLOCATION_COST_RTOL)`` or an exact certificate that
    no law of the strategy is stable is outside, anything else undecided. Both sets are upper sets: a TCP-like
    controller can make a delivered packet act as a loss (resending the held input, or the rest of the buffered
    plan), so with private coins it emulates any lower mu at the same cost (closedloop.actuator_region); behind a
    chain, along its family (``at``, `_strategy_at`), the coins thin the chain as in the critical mean rate's proof
    (docs/mathematics.md) or, deliveries scaled, erase packets independently."""

    def growth(mu: np.ndarray) -> float:
        return least_radius(design_modes(system.A, system.B, at(mu)[2], strategy)).growth

    def stable(mu: np.ndarray) -> Point:
        moved, rates, _ = at(mu)
        found = actuator_membership(moved, strategy, rates)
        if found.verdict == "unstable":
            return Point("out")
        if found.verdict == "undecided":
            return Point("undecided")
        return Point("in", found.gain, found.radius)

    if target == "stable":
        return Target(stable, growth, 1.0)

    def within(mu: np.ndarray) -> Point:
        try:
            design = designs(mu)
        except NumericalError:                  # no stabilising solution found: outside only on a certificate
            return Point("out") if stable(mu).verdict == "out" else Point("undecided")
        cost, _ = strategy_dp_cost(system, design)
        if cost <= alpha:
            return Point("in", design.K, design.radius, cost)
        if cost > alpha * (1.0 + ALLOCATION_COST_RTOL):
            return Point("out")
        return Point("undecided")

    def log_cost(mu: np.ndarray) -> float:
        """log(J / alpha), unchecked; _OUTSIDE plus the least radius where the DP solution fails."""
        try:
            cost, _ = strategy_dp_cost(system, designs(mu))
        except NumericalError:
            lam = growth(mu)
            return _OUTSIDE + (lam if np.isfinite(lam) else 0.0)
        return math.log(max(cost, np.finfo(float).tiny) / alpha)

    return Target(within, log_cost, 0.0)


#: how the one-channel bisection (`_line`) is reported as the answer's method
LINE_METHOD = "bisection on certified memberships along the one channel"


def _line(poly: Polytope, beta: np.ndarray, gap: float, goal: Target, time_limit: float | None,
          progress: bool | None) -> tuple[str, Search, dict[bytes, Point]]:
    """One channel: the target's set is an interval [mu_c, b] of the constraints' interval [a, b] (an upper set),
    and beta mu is least at its lower end, so the answer is a bisection on verdicts, as `_search` returns it.

    ``lo`` is the largest point certified outside (else a: every mu below it is outside, so ``beta lo`` is a
    proved bound), ``hi`` the least certified inside (the incumbent). An undecided point (the certificates do not
    check within their rounding of the boundary) is no verdict: the bisection continues on either side of the
    undecided points, to ``ALLOCATION_INCUMBENT_SHARE * gap`` (relative) of them, and stops there. The probe's
    crossings just inside and just outside the level (as `_search`'s line searches aim) are decided first. Where
    the undecided band is wider than the gap, the branch and bound split it for ever (the pendulum at margin 0.5:
    20000 boxes, 346 s, its gap stuck at 1.4e-4 by a band from 0.93736 to 0.9374989 about the boundary 0.9374126,
    1 - 1/M^2 of the scaled plant, M its unstable eigenvalues' product); here it ends "gap_not_certified" naming
    the band. O(log(1/(gap ALLOCATION_INCUMBENT_SHARE))) verdicts."""
    search = Search(gap, float(beta @ poly.lower()), 1, time_limit, progress)
    search.boxes = 1
    seen: dict[bytes, Point] = {}

    def verdict(x: float) -> str:
        point = np.array([x])
        key = point.tobytes()
        if key not in seen:
            seen[key] = goal.decide(point)
        return seen[key].verdict

    a, b = interval(poly)
    if a > b:
        return "exhausted", search, seen           # no mu meets the constraints
    if verdict(b) == "out":                        # an upper set: nothing below b is inside
        return "exhausted", search, seen
    lo, hi = a, (b if verdict(b) == "in" else None)
    if verdict(a) == "in":
        hi = a
    undecided: list[float] = [] if hi is not None else [b]
    tol = ALLOCATION_INCUMBENT_SHARE * gap * max(b, np.finfo(float).tiny)
    start = time.monotonic()

    def along(t: float) -> float:
        return goal.probe(np.array([t]))

    if hi is not None and hi > lo:     # the probe's crossings just inside and just outside, each then decided
        for level, side in ((goal.inside(), 0), (goal.outside(), 1)):
            x = bracket(along, level, lo, hi, tol)[side]
            if lo < x < hi:
                found = verdict(x)
                if found == "in":
                    hi = x
                elif found == "out":
                    lo = x

    def certified() -> bool:
        return hi is not None and beta[0] * (hi - lo) <= gap * gap_unit(beta[0] * hi, 1.0)

    while not certified():
        if time_limit is not None and time.monotonic() - start > time_limit:
            break
        below = min(undecided, default=hi if hi is not None else b)
        above = max(undecided, default=None)
        if below - lo > tol:                       # below the undecided points: look for one certified outside
            x = 0.5 * (lo + below)
        elif above is not None and hi is not None and hi - above > tol:    # above them: one certified inside
            x = 0.5 * (above + hi)
        elif hi is None and (widest := _widest_gap(undecided, b, tol)) is not None:
            # nothing certified inside yet and b itself undecided (a deadbeat law at mu = 1, whose radius is
            # rounding): one certified inside in the widest gap between the undecided points
            x = widest
        else:
            break
        found = verdict(x)
        if found == "out":
            lo = x
            undecided = [u for u in undecided if u > lo]
        elif found == "in":
            hi = x
            undecided = [u for u in undecided if u < hi]
        else:
            undecided.append(x)
    if hi is not None:
        search.offer(np.array([hi]), float(beta[0] * hi))
    search.unsplit = float(beta[0] * lo)           # the rest, [lo, hi]: bounded by beta lo (proved)
    if certified():
        return "certified", search, seen
    band = f"[{lo:.10g}, {hi if hi is not None else b:.10g}]"
    why = "" if not undecided else " (no certificate checks there: within the certificates' rounding of the boundary)"
    if time_limit is not None and time.monotonic() - start > time_limit:
        return f"stopped at the time limit of {time_limit:g} s with mu* in {band}", search, seen
    return f"the membership is undecided on {band}{why}", search, seen


def _widest_gap(undecided: list[float], b: float, tol: float) -> float | None:
    """The midpoint of the widest gap between consecutive undecided points (``b``, the interval's top, closing the
    last), or None where none is wider than ``tol``: where a point certified inside is likeliest, away from the
    band about the boundary, whose verdicts need not even be monotone (out above undecided under OpenBLAS's
    Sandybridge kernel on the pendulum). O(k log k).

    >>> _widest_gap([0.93701, 0.9375, 0.93702, 1.0], 1.0, 1e-5)     # the gaps 1e-5 and 4.8e-4 are narrower
    0.96875
    """
    points = sorted(set(undecided) | {b})
    widths = np.diff(points)
    if widths.size == 0 or not widths.max() > tol:
        return None
    k = int(np.argmax(widths))
    return 0.5 * (points[k] + points[k + 1])


def _search(poly: Polytope, beta: np.ndarray, gap: float, goal: Target, max_boxes: int,
            time_limit: float | None, progress: bool | None) -> tuple[str, Search, dict[bytes, Point]]:
    """The monotone branch and bound on verdicts (module docstring); returns how it ended, the search and every
    point decided (keyed by ``mu.tobytes()``: the incumbent's certificate is there). One channel: `_line`."""
    m = beta.size
    if m == 1:
        return _line(poly, beta, gap, goal, time_limit, progress)
    weights = np.maximum(beta, SPLIT_WEIGHT_FLOOR)
    search = Search(gap, float(beta @ poly.lower()), max_boxes, time_limit, progress)
    seen: dict[bytes, Point] = {}

    def verdict(mu: np.ndarray) -> str:
        key = mu.tobytes()
        if key not in seen:
            seen[key] = goal.decide(mu)
        return seen[key].verdict

    def halving(point: np.ndarray, i: int, out: float, top: float, tol: float) -> float:
        """Bisection on verdicts from ``out`` (certified outside) to ``top``: the last point certified outside."""
        while top - out > tol:
            point[i] = 0.5 * (out + top)
            found = verdict(point)
            if found == "undecided":
                break
            if found == "out":
                out = float(point[i])
            else:
                top = float(point[i])
        return out

    def edge(u: np.ndarray, i: int, a: float) -> float:
        """The last point of edge i (the others at u) certified outside, from a (kept when nothing is): the
        probe's regula falsi proposes it, a certificate confirms it, else a bisection on verdicts finds it."""
        point = u.copy()
        point[i] = a
        if goal.probe(point) <= goal.outside():
            return a
        top = float(u[i])
        tol = ALLOCATION_EDGE_ATOL + ALLOCATION_EDGE_RTOL * (top - a)

        def along(s: float) -> float:
            point[i] = s
            return goal.probe(point)

        _, proposed = bracket(along, goal.outside(), a, top, tol)
        point[i] = proposed
        if proposed > a and verdict(point) == "out":
            return proposed
        point[i] = a
        if verdict(point) != "out":
            return a
        return halving(point, i, a, top, tol)

    def bound(l: np.ndarray, u: np.ndarray):
        if verdict(u) == "out":                  # every point of the box is dominated by u
            return None
        l, u = l.copy(), u.copy()
        for i in range(m):
            if l[i] < u[i]:
                l[i] = edge(u, i, float(l[i]))
        return box_bound(beta, poly, l, u, search.best)

    def incumbent(p: np.ndarray, q: np.ndarray) -> np.ndarray | None:
        """A point certified inside on the segment from p (not inside) to q (inside), near the boundary."""
        tol = ALLOCATION_INCUMBENT_SHARE * gap
        s_in, _ = bracket(lambda t: goal.probe(p + t * (q - p)), goal.inside(), 0.0, 1.0, tol)
        point = p + s_in * (q - p)
        if verdict(point) == "in":
            return point
        lo, hi = 0.0, 1.0
        while hi - lo > tol:
            mid = 0.5 * (lo + hi)
            if verdict(p + mid * (q - p)) == "in":
                hi = mid
            else:
                lo = mid
        return p + hi * (q - p)

    def visit(lb: float, l: np.ndarray, u: np.ndarray, p: np.ndarray) -> None:
        if verdict(p) == "in":
            search.offer(p, float(beta @ p))
        else:
            q, _ = box_lp(-np.ones(m), poly, l, u)          # a maximal point of the box and rows
            if q is not None and verdict(q) == "in":
                point = incumbent(p, q)
                search.offer(point, float(beta @ point))
        search.branch(l, u, lb, weights, bound)

    root = bound(poly.lower(), poly.upper())
    if root is not None:
        search.push(*root)
    return search.run(visit), search, seen


@blas_limited
def stability_allocate(system: System, target: str, beta, margin=None, alpha=None, bounds=(0.0, 1.0),
                       constraints: Sequence[Constraint] = (), gap: float = ALLOCATION_GAP_DEFAULT,
                       max_boxes: int = MAX_BOXES, time_limit: float | None = None,
                       progress: bool | None = None, actuator: str | Actuator | None = None) -> StabilityAllocation:
    """The cheapest channel qualities (min beta'mu) for which some linear law has mean-square radius below
    ``margin`` (target "stable"), or whose DP law costs at most ``alpha`` (target "dp-cost").

    Parameters
    ----------
    system : System
        Full state, a stationary Bernoulli channel (its own mu is ignored).
    target : {"stable", "dp-cost"}
    beta : array_like, shape (m,)
        Non-negative price of each channel's delivery probability.
    margin : float, optional
        Target "stable": the bound rho on the mean-square radius, ``0 < rho <= 1``; the answer's gain is proved
        to have radius ``< rho (1 - MEAN_SQUARE_MARGIN)``. Default 1: what the product calls stable.
    alpha : float
        Target "dp-cost": bound on the DP law's stationary cost (`dp_cost`), > 0.
    bounds, constraints, gap, max_boxes, time_limit, progress
        As [`allocate`][packetloss_cvx.allocation.api.allocate].
    actuator : str, optional
        Design for an actuator strategy on a loss ("zero", "hold", "buffer:L"; closedloop.actuator): the laws are
        the strategy's TCP-like laws over its information modes, "stable" some such law proved stable
        (closedloop.actuator_region.actuator_membership, margin 1 only), "dp-cost" the strategy's optimal law's
        stationary cost (`strategy_dp_cost`, closedloop.actuator_design.actuator_dp) at most alpha. The answer's
        ``gain`` is per information mode (S, r, N), ``actuator`` its membership at mu, ``attainable_cost`` None.
        Behind a stationary Markov chain mu is each channel's mean rate along its family (`.chains.chain_family`,
        its top added as rows), the law knowing the current channel state. None (default): the channel's own laws
        u = -K x on Bernoulli links, as before (the same region and cost as "zero").

    Returns
    -------
    StabilityAllocation
        ``mu`` certified inside (its ``gain`` and ``radius`` re-checked by the operator), ``lower_bound``
        proved (LP bounds of the boxes not discarded by a certificate), ``status`` "optimal" or
        "gap_not_certified" (a cap was hit; ``gap`` the gap reached).

    Raises
    ------
    InputError
        A bad argument, named by its field (``margin`` outside (0, 1], a Gilbert-Elliott ``channel``, a
        noise-free system with x0 = 0 for "dp-cost").
    InfeasibleError
        Every box was discarded by a certificate: no mu within the bounds and rows meets the target.
    SolverError
        A cap hit before any point was certified inside, or a final check failed.

    Notes
    -----
    Monotone branch and bound (module docstring); per box an LP and O(m log(1/tol)) memberships, each a
    homogeneous Riccati eigenpair, O(iterations (n^3 + m^3)), plus a DP solution for "dp-cost".

    Examples
    --------
    One state, x+ = 2 x + v u: some law holds the loop with radius below rho iff 4 (1 - mu) < rho.

    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> a = stability_allocate(s, "stable", [1.0], margin=0.5)
    >>> a.status, bool(abs(a.mu[0] - 0.875) <= 1e-4), bool(a.radius < 0.5)
    ('optimal', True, True)
    """
    system = check_system(system)
    if system.channel is not None and actuator is None:
        raise InputError("channel", "design for stability chooses independent (Bernoulli) delivery probabilities; "
                                    "this system has a Markov chain ([channel] model)")
    if system.sensor is not None:   # the loop then also needs the sensor links (gamma > gamma_c): not designed here
        raise InputError("sensor", "design for stability designs the actuator links of the full-state loop; this "
                                   "system measures its state over lossy [sensor] links, whose rates it would "
                                   "ignore: map the (gamma, mu) region with `packetloss-cvx region FILE "
                                   "--sensor-grid K`, or remove [sensor]")
    if target not in TARGETS:
        raise InputError("target", f"expected one of {', '.join(TARGETS)}, found {target!r}")
    beta = check_beta(beta, system.m)
    lo, hi = check_bounds(bounds)
    gap = check_gap(gap)
    max_boxes = check_count(max_boxes, "max_boxes")
    check("allocation_boxes", max_boxes, "max_boxes", f"{count_text(max_boxes)} boxes")
    if time_limit is not None:
        time_limit = check_number(time_limit, "time_limit")
        if time_limit <= 0:
            raise InputError("time_limit", f"expected a positive number of seconds (None: no limit), found "
                                           f"{time_limit:g}")
    strategy = None if actuator is None else parse_actuator(actuator, system.horizon)
    if strategy is not None and margin is not None and _radius_bound(margin) != 1.0:
        raise InputError("margin", f"a radius bound below 1 is designed for the channel's own laws only; {strategy}'s "
                                   "memory (the held input, the plan) does not scale with the plant")
    if target == "stable":
        if alpha is not None:
            raise InputError("alpha", "the target 'stable' bounds the radius (margin), not a cost")
        rho = _radius_bound(margin)
    else:
        if margin is not None:
            raise InputError("margin", "the target 'dp-cost' bounds the DP cost (alpha), not the radius")
        if alpha is None:
            raise InputError("alpha", "the target 'dp-cost' needs a bound alpha on the DP law's cost")
        alpha = check_alpha(alpha)
        if not (np.any(system.noise_cov != 0) or np.any(system.x0 != 0)):
            raise InputError("noise_cov", "the DP cost is 0 wherever the loop is stable when there is neither "
                                          "process noise nor an initial state: ask for the target 'stable'")
        rho = 1.0
    family = None if system.channel is None else chain_family(system)
    if family is not None and lo > family.top.min():
        raise InfeasibleError(f"the chain's family reaches mean rates up to {family.top.min():.6g} only, below the "
                              f"lower bound {lo:g}", None)
    try:
        poly = read_polytope([*constraints, *([] if family is None else family.rows())], system.m, lo, hi)
    except InfeasibleError as err:
        raise InfeasibleError(f"the constraints admit no mu: {err}", None) from None
    prices, unit = unit_prices(beta)
    if strategy is not None:
        at = _strategy_at(system, family)
        designs = _strategy_memo(system, strategy, at)
        goal = _strategy_target(system, strategy, target, alpha, designs, at)
    else:
        memos = _memos(system, rho)
        goal = _target(system, target, rho, alpha, memos=memos)
    ended, search, seen = _search(poly, prices, gap, goal, max_boxes, time_limit, progress)
    what = ("design for stability" if target == "stable" else "design for the DP cost") + (
        "" if strategy is None else f" of {strategy}")
    if search.best_mu is None:
        if ended == "exhausted":
            goal = (f"mean-square radius below {rho:g}" if target == "stable" else f"DP cost <= {alpha:g}")
            raise InfeasibleError(f"{what}: no mu within the bounds and constraints gives a {goal} (every box "
                                  f"discarded by a certificate at its upper corner, or empty; {search.boxes} boxes)",
                                  None)
        raise SolverError("gap_not_certified", f"{what}: no mu certified inside and infeasibility not proven; "
                                               f"{ended}")
    out = search.outcome(ended, LINE_METHOD if system.m == 1 else
                         "monotone branch and bound on certified memberships (LP bounds)", what)
    mu = check_in_polytope(out.mu, poly, what)
    if strategy is not None:
        return _strategy_verified(system, strategy, target, alpha, mu, beta, out, unit, seen[out.mu.tobytes()],
                                  designs, at, family)
    return _verified(system, target, rho, alpha, mu, beta, out, unit, seen[out.mu.tobytes()],
                     _target(system, target, rho, alpha, check=True, memos=memos).decide)


def _verified(system: System, target: str, rho: float, alpha: float | None, mu: np.ndarray, beta: np.ndarray,
              out: Outcome, unit: float, point: Point, decide: Callable[[np.ndarray], Point]) -> StabilityAllocation:
    """The result, after re-checking the incumbent's gain by the operator (its radius < rho) and deciding mu once
    more by every form, cross-checked: a form that finds mu outside contradicts the gain (SolverError), one that
    cannot decide (within about 1e-9 of the boundary) is no verdict."""
    again = decide(mu)
    if point.verdict != "in" or again.verdict == "out":
        raise SolverError("inconsistent", f"the allocation mu = {np.round(mu, 9).tolist()} was certified inside, "
                                          f"yet decided {again.verdict} by a second look")
    radius = mean_square_radius(system.A, system.B, point.gain, mu)
    if not radius < rho:
        raise SolverError("inconsistent", f"the gain found at mu = {np.round(mu, 9).tolist()} has mean-square "
                                          f"radius {radius:.9g}, not below rho = {rho:g}")
    note = ""
    try:
        dp = dp_riccati(system, mu, gain=point.gain)       # the policy iteration from the proved gain
        cost, kind = dp_cost(system, dp)
        if 1.0 - mean_square_radius(system.A, system.B, dp.gain, mu) < DP_COST_BOUNDARY:
            cost, kind = float("nan"), ""                  # on the boundary: a cost of ~1 / (1 - radius), unresolved
            note = BOUNDARY_NOTE
    except NumericalError as err:
        cost, kind = float("nan"), ""
        note = BOUNDARY_NOTE if 1.0 - radius < DP_COST_BOUNDARY else f"not reported: the DP solution failed ({err})"
    try:
        attainable, attained_note = (tcp_attainable_cost(system.with_mu(mu), mu),
                                     "finite-horizon DP with acknowledgements")
    except NumericalError as err:
        attainable, attained_note = None, str(err)
    return StabilityAllocation(
        target=target, mu=mu, cost=float(beta @ mu), lower_bound=out.lower_bound * unit,
        gap=reported_gap(out.value, out.lower_bound, out.scale), status=out.status, radius=radius,
        radius_bound=rho, gain=point.gain, dp_cost=cost, dp_cost_kind=kind, alpha=alpha, beta=beta,
        boxes=out.boxes, method=out.note, attainable_cost=attainable, attainable_note=attained_note, stabilisable=True,
        stability_note=_radius_note("the design's gain", radius, rho), dp_cost_note=note)


def _radius_note(what: str, radius: float, bound: float) -> str:
    """"<what> has mean-square radius r < bound (certified)", r and the bound to the digits that tell them apart (at
    least 6; "radius 1 < 1" read as a contradiction), and no more: the note is compared as text across BLAS
    kernels. O(1).

    >>> _radius_note("the gain", 0.9999998998999412, 1.0)
    'the gain has mean-square radius 0.9999999 < 1 (certified)'
    """
    shown, bound_shown = apart(radius, bound)
    return f"{what} has mean-square radius {shown} < {bound_shown} (certified)"


#: why the DP cost at mu* is not reported on the boundary, the same text whether the DP solution there found a radius
#: within DP_COST_BOUNDARY of 1 or failed (BLAS kernels differ on which, DP_COST_BOUNDARY's note)
BOUNDARY_NOTE = (f"not reported: mu* lies on the stabilisable set's boundary (a radius within {DP_COST_BOUNDARY:g} "
                 "of 1), where the DP law's cost, about 1 / (1 - radius), is decided by rounding and its iterations "
                 "may not converge; a margin below 1 keeps mu* inside")



def _strategy_verified(system: System, strategy: Actuator, target: str, alpha: float | None, mu: np.ndarray,
                       beta: np.ndarray, out: Outcome, unit: float, point: Point, designs: _Recent, at,
                       family: ChainFamily | None) -> StabilityAllocation:
    """The strategy's result: the incumbent's law's radius recomputed by the engine (below 1, else SolverError),
    the strategy's DP cost at mu (``<= alpha`` for "dp-cost", else SolverError; nan on the boundary as
    `_verified`), and mu's membership decided once more in exact arithmetic (``stabilisable`` True on its
    certificate, None with the reason where it is undecided, a proof of instability contradicting the design)."""
    where = f"mu = {np.round(mu, 9).tolist()}"
    if point.verdict != "in":
        raise SolverError("inconsistent", f"the allocation {where} of {strategy} was not certified inside")
    moved, rates, channel = at(mu)
    modes = design_modes(system.A, system.B, channel, strategy)
    radius = modes.loop(point.gain).radius()
    if not radius < 1.0:
        raise SolverError("inconsistent", f"{strategy}'s law found at {where} has mean-square radius {radius:.9g}")
    cost, kind, dp_note = float("nan"), "", ""
    try:
        design = designs(mu)
        cost, kind = strategy_dp_cost(system, design)
        if target == "dp-cost" and not cost <= alpha:
            raise SolverError("inconsistent", f"{strategy}'s DP cost at {where} is {cost:.9g} > alpha = {alpha:g}")
        if 1.0 - design.radius < DP_COST_BOUNDARY:
            cost, kind, dp_note = float("nan"), "", BOUNDARY_NOTE
    except NumericalError as err:
        if target == "dp-cost":
            raise SolverError("inconsistent", f"{strategy}'s DP solution at {where} failed on a second look") from None
        dp_note = (BOUNDARY_NOTE if 1.0 - radius < DP_COST_BOUNDARY
                   else f"not reported: {strategy}'s DP solution failed ({err})")
    found = actuator_membership(moved, strategy, rates)
    if found.verdict == "unstable":
        raise SolverError("inconsistent", f"the allocation {where} was certified inside, yet no law of {strategy} "
                                          "is stable there (exact certificate)")
    stable = True if found.verdict == "stable" else None
    note = (_radius_note(f"a TCP-like law of {strategy}", found.radius, 1.0) if stable
            else f"undecided: {found.reason}")
    membership_radius = float(found.radius) if np.isfinite(found.radius) else None
    return StabilityAllocation(
        target=target, mu=mu, cost=float(beta @ mu), lower_bound=out.lower_bound * unit,
        gap=reported_gap(out.value, out.lower_bound, out.scale), status=out.status, radius=radius, radius_bound=1.0,
        gain=point.gain, dp_cost=cost, dp_cost_kind=kind, alpha=alpha, beta=beta, boxes=out.boxes,
        method=f"{out.note}; designed for the actuator strategy {strategy} (its TCP-like laws)" + (
            "" if family is None else f", mean rates {family.describe()}"),
        attainable_cost=None, attainable_note=f"not computed for {strategy} (dp_cost is its optimal law's cost)",
        stabilisable=stable, stability_note=note,
        actuator=((str(strategy), found.verdict, membership_radius, found.reason),), dp_cost_note=dp_note)
