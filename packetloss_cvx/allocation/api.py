"""Channel allocation `M*` (§VI): the cheapest delivery probabilities that keep `J*` <= alpha.

.. math:: \\min_{\\mu} \\beta'\\mu \\quad\\text{s.t.}\\quad J^*(\\mu) \\le \\alpha,\\
   \\mu \\in [lo, hi]^m,\\ G\\mu \\le h

(eq:alpha_channels, eq:channel-opt, eq:opt_M), stationary channels. The TCP-like problem is
an SOCP (`.tcp`), the UDP-like one a monotonic branch and bound (`.udp`) that also
uses the TCP-like optimum as a lower bound (Theorem 2: `J*_udp` >= `J*_tcp`).

What the results promise:

* ``mu`` is feasible: the closed form gives ``J*(mu) <= alpha``, and mu meets the bounds and
  rows (to ``ALLOCATION_LP_FEASIBILITY``);
* ``lower_bound`` is proved: no feasible mu has ``beta'mu < lower_bound`` (LP duals evaluated
  exactly, tangent cuts of the convex `J*_tcp`, monotonicity of `J*_udp`; the closed form trusted
  to ``ALLOCATION_COST_RTOL``);
* status "optimal" means ``gap <= `` the requested gap; "gap_not_certified" means a cap was
  hit (or the bound could not be tightened) and ``gap`` is the gap actually reached;
* [`InfeasibleError`][packetloss_cvx.errors.InfeasibleError] only on a proof: Clarabel's infeasibility
  certificate, or every box discarded because its upper corner is infeasible (Theorem 3) or
  it holds no point of the constraints; never while a feasible point is known.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..budgets import check, count_text, duration_text, estimated_seconds, limit, udp_box_work
from ..closedloop.actuator import Actuator, parse_actuator, parse_actuators
from ..closedloop.actuator_design import actuator_dp
from ..closedloop.actuator_region import actuator_membership
from ..display import apart
from ..errors import BudgetError, InfeasibleError, InputError, NumericalError, SolverError
from ..model.protocols import check_protocol
from ..model.system import System
from ..results import Allocation, MinCost, StabilityAllocation
from ..threads import blas_limited
from ..tolerances import ALLOCATION_GAP_DEFAULT
from .attainable import AttainableEvaluator, ChainAttainableEvaluator, attainment
from .boxes import Outcome, cost_at, reported_gap, unit_prices
from .chains import ChainEvaluator, ChainFamily, chain_family, chain_rates
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
from .stability import stability_allocate, strategy_dp_cost
from .tcp import tcp_allocate, tcp_min_cost
from .udp import MonotoneCost, udp_allocate, udp_min_cost

__all__ = ["ALLOCATION_TARGETS", "MAX_BOXES", "MinCost", "allocate", "best_cost_within_budget", "cheapest_links",
           "min_cost"]

#: what :func:`allocate` designs on: the paper's program (J*(mu) <= alpha, the default), a loop some linear law
#: holds ("stable"), the DP law's stationary cost ("dp-cost"), the attainable finite-horizon cost ("attainable")
ALLOCATION_TARGETS = ("paper", "stable", "dp-cost", "attainable")

#: Default cap on the boxes a branch and bound explores before it reports "gap_not_certified".
MAX_BOXES = 20000


def _max_boxes(value: Any, system: System | None = None) -> int:
    """The cap on the branch and bound's boxes: a positive count within the ``allocation_boxes`` budget (budgets.py),
    checked before the search. Given a ``system`` (the UDP-like search on its closed-form cost), the boxes' work is
    priced too (`udp_box_work`, a box's cost grows with the horizon): a cap the caller
    gave beyond the ``allocation_work`` budget is refused under ``max_boxes``; the default (None) is
    `MAX_BOXES`, or as many boxes as that budget affords at this horizon (the search then ends
    "gap_not_certified" at that cap, within the budget's time); a horizon where not one box fits is refused under
    ``horizon``. O(1)."""
    box = None if system is None else udp_box_work(system.horizon, system.n, system.m)
    size = "" if system is None else f"at N = {system.horizon} (n = {system.n}, m = {system.m}: about " \
                                     f"{duration_text(estimated_seconds('allocation_work', box))} a box)"
    if value is None:
        if box is None:
            return MAX_BOXES
        check("allocation_work", box, "horizon", f"one box of the UDP-like search {size}")
        afford = limit("allocation_work") / box
        return MAX_BOXES if afford >= MAX_BOXES else max(1, int(afford))
    count = check_count(value, "max_boxes")
    check("allocation_boxes", count, "max_boxes", f"{count_text(count)} boxes")
    if box is not None:
        check("allocation_work", count * box, "max_boxes", f"{count_text(count)} boxes {size}")
    return count


def _time_limit(value: Any) -> float | None:
    if value is None:
        return None
    seconds = check_number(value, "time_limit")
    if seconds <= 0:
        raise InputError("time_limit", f"expected a positive number of seconds (None: no limit), found {seconds:g}")
    return seconds


def _polytope(constraints: Sequence[Constraint], m: int, lo: float, hi: float) -> Polytope:
    try:
        return read_polytope(constraints, m, lo, hi)
    except InfeasibleError as err:
        raise InfeasibleError(f"the constraints admit no mu: {err}", None) from None


def _min_cost(system: System, protocol: str, poly: Polytope, max_boxes: int, time_limit: float | None,
              evaluator: Any = None) -> MinCost:
    out: Outcome = (tcp_min_cost(system, poly) if protocol == "tcp"
                    else udp_min_cost(system, poly, max_boxes, time_limit,
                                      cost=None if evaluator is None else MonotoneCost(evaluator)))
    return MinCost(protocol=protocol, cost=out.value, lower_bound=out.lower_bound,
                   gap=reported_gap(out.value, out.lower_bound, out.scale), status=out.status,
                   mu=out.mu, method=out.note, basis="paper" if evaluator is None else "attainable")


@blas_limited
def min_cost(system: System, protocol: str, bounds=(0.0, 1.0), constraints: Sequence[Constraint] = (),
             max_boxes: int | None = None, time_limit: float | None = None) -> MinCost:
    """The least optimal cost J*(mu) reachable within the bounds and constraints.

    Parameters
    ----------
    system, protocol, bounds, constraints
        As for [`allocate`][packetloss_cvx.allocation.api.allocate].
    max_boxes, time_limit
        Caps of the UDP-like branch and bound (the TCP-like one is a single SOCP); ``max_boxes`` as for
        [`allocate`][packetloss_cvx.allocation.api.allocate] (None: what the ``allocation_work`` budget affords, at most
        `MAX_BOXES`).

    Returns
    -------
    MinCost
        A reachable cost with a proven lower bound; status "gap_not_certified" if a cap stopped
        the search before ``tolerances.MIN_COST_RTOL``.

    Raises
    ------
    InfeasibleError
        The constraints admit no mu (``min_cost`` attribute None).
    SolverError
        A solver failure.

    Notes
    -----
    TCP-like: one SOCP with O(N (n + m)) variables, two LPs. UDP-like: the upper corner when
    there are no rows; otherwise a branch and bound over maximal points, two LPs and two
    closed forms per box.

    Examples
    --------
    One step of x' = x + v u from x0 = 1: `J*_udp` = 1 - mu/2, least at the top of the box; two such
    channels with mu1 + mu2 <= 1: `J*_tcp` = 1/(1 + mu1) + 1/(1 + mu2), least (4/3) at (1/2, 1/2).

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> least = min_cost(s, "udp", bounds=(0.0, 0.5))
    >>> least.cost, least.lower_bound, least.status
    (0.75, 0.75, 'optimal')
    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> least = min_cost(t, "tcp", constraints=[([[1.0, 1.0]], [1.0])])
    >>> bool(np.isclose(least.cost, 4 / 3) and np.allclose(least.mu, 0.5, atol=1e-4)), least.lower_bound <= 4 / 3
    (True, True)
    """
    protocol = check_protocol(protocol)
    system, evaluator = _behind_chain(system, protocol)
    system = check_system(system)
    lo, hi = check_bounds(bounds)
    poly = _polytope([*constraints, *_family_rows(evaluator, lo)], system.m, lo, hi)
    boxes = _max_boxes(max_boxes, system if protocol == "udp" and evaluator is None else None)
    return _min_cost(system, protocol, poly, boxes, _time_limit(time_limit), evaluator)


def _behind_chain(system: System, protocol: str) -> tuple[System, ChainEvaluator | None]:
    """``(system at its chain's mean rates, the exact-cost evaluator)`` behind a chain (UDP-like; TCP-like: None,
    its cost holds only the mean rates); ``(system, None)`` without one. Refusals: allocation/chains.py."""
    if not isinstance(system, System) or system.channel is None:
        return system, None
    evaluator = ChainEvaluator(system, chain_family(system)) if protocol == "udp" else None
    return system.with_mu(chain_rates(system)), evaluator


def _family_rows(evaluator: ChainEvaluator | ChainAttainableEvaluator | None, lo: float) -> list:
    """The rows ``mu_i <= top_i`` of the channels whose family stops below 1 (deliveries scaled: chains.py); a lower
    bound above a top is infeasible, said here with the reason rather than as rows that admit no mu."""
    if evaluator is None:
        return []
    top = evaluator.family.top
    if lo > top.min():
        i = int(np.argmin(top))
        raise InfeasibleError(f"channel {i + 1}'s chain reaches mean rates up to {top[i]:.6g} only (its deliveries "
                              f"scaled, transition held), below the lower bound {lo:g}", None)
    return evaluator.family.rows()


def _infeasible(system: System, protocol: str, alpha: float, poly: Polytope, proof: str, max_boxes: int,
                time_limit: float | None, evaluator: Any = None) -> InfeasibleError:
    """The InfeasibleError for a proven infeasibility, with the least reachable cost; a known
    feasible point contradicts the proof and is a SolverError instead."""
    try:
        least = _min_cost(system, protocol, poly, max_boxes, time_limit, evaluator)
    except InfeasibleError as err:
        return InfeasibleError(f"{proof}; {err}", None)
    if least.cost <= alpha:
        raise SolverError("inconsistent", f"{protocol}-like allocation: {proof}, yet mu = "
                          f"{np.round(least.mu, 6).tolist()} reaches J* = {least.cost:.6g} <= alpha = {alpha:g}")
    shown, lower = apart(alpha, least.lower_bound if least.status != "optimal" else least.cost)
    where = (lower if least.status == "optimal"
             else f"in [{lower}, {apart(least.cost, alpha)[0]}] (not certified: {least.method})")
    return InfeasibleError(f"alpha = {shown} is below the least reachable {protocol}-like cost {where} within the "
                           f"bounds and constraints ({proof})", least.cost)


def _strategies(text: str, system: System) -> tuple[Actuator, ...]:
    """The strategies ``actuator=`` names, checked before any work (field ``actuator``). O(len(text))."""
    if not isinstance(text, str):
        raise InputError("actuator", f"expected zero, hold, buffer[:L] (comma-separated) or all, found {text!r}"[:200])
    return parse_actuators(text, check_system(system).horizon)


def _actuator_verdict(system: System, strategy: Actuator, mu: np.ndarray) -> tuple[str, str, float | None, str]:
    """``(name, verdict, radius, reason)``: is mu stabilisable under the strategy (actuator_membership)?"""
    found = actuator_membership(system, strategy, mu)
    return str(strategy), found.verdict, float(found.radius) if np.isfinite(found.radius) else None, found.reason


@blas_limited
def allocate(system: System, protocol: str, alpha: float | None, beta, bounds=(0.0, 1.0),
             constraints: Sequence[Constraint] = (), gap: float = ALLOCATION_GAP_DEFAULT,
             max_boxes: int | None = None, time_limit: float | None = None, progress: bool | None = None,
             target: str = "paper", margin: float | None = None,
             actuator: str | None = None) -> Allocation | StabilityAllocation:
    """The cheapest channel qualities mu (min beta'mu) with `J*(mu) <= alpha`, with a certificate.
    The paper's eq:alpha_channels (`J* <= alpha`), eq:channel-cost (beta' mu), eq:channel-opt and eq:opt_M.

    The paper's `J*_tcp` is a first-moment value no causal law attains: the result says, at its mu, what a loop
    attains (``attainable_cost``, the finite-horizon DP with acknowledgements, TCP-like) and whether any linear law
    holds it mean-square stable (``stabilisable``); ``warning`` is one line when either misleads. To design on the
    loop instead, ask for ``target="stable"`` or ``"dp-cost"``.

    Parameters
    ----------
    system : System
        Stationary channel; its own mu is ignored. Behind a Markov chain (``system.channel``, stationary start):
        mu is each channel's mean delivery rate; UDP-like, the cost is the exact expected cost under the chains,
        Gilbert channels with their burstiness held, any other chain with its deliveries scaled (mean rates up to
        ``mubar / max(d)``, added as rows; `.chains`, which also lists what is refused); TCP-like, the
        cost holds only the mean rates, so any stationary chain's allocation is the Bernoulli one.
    protocol : {"tcp", "udp"}
    alpha : float
        Bound on the optimal expected cost, > 0.
    beta : array_like, shape (m,)
        Non-negative price of each channel's delivery probability.
    bounds : (lo, hi)
        Box for every mu_i, 0 <= lo <= hi <= 1.
    constraints : sequence
        Pairs ``(G, h)`` meaning ``G mu <= h``, or callables ``f(mu)`` returning affine cvxpy
        constraints on the variable mu (read into rows once).
    gap : float
        Relative optimality gap to certify, ``tolerances.ALLOCATION_GAP_MIN <= gap < 1``.
    max_boxes : int or None
        Cap on the UDP-like branch and bound's boxes; within the ``allocation_boxes`` budget, and on the
        closed-form cost its work (boxes x `udp_box_work`, which grows with the
        horizon) within ``allocation_work``. None: `MAX_BOXES`, or as many boxes as ``allocation_work``
        affords at this horizon.
    time_limit : float or None
        Cap on the UDP-like branch and bound's seconds (None: no limit).
    progress : bool or None
        A bar on stderr for the UDP-like branch and bound (None: when stderr is a terminal).
    target : {"paper", "attainable", "stable", "dp-cost"}
        What the design meets: "paper" (default), the paper's program ``J*(mu) <= alpha`` for ``protocol``;
        "attainable", the attainable cost over the horizon is at most ``alpha`` (TCP-like: the finite-horizon DP
        with acknowledgements, a monotone branch and bound, full state; behind a chain the chain DP with each
        channel along its family, `.attainable.ChainAttainableEvaluator`, refused beyond the ``chain_dp_nodes``
        budget; UDP-like: J*_udp is the attainable cost, so the paper's program); "stable", some linear law
        u = -K x has mean-square radius
        below ``margin`` (``alpha`` None); "dp-cost", the DP law's stationary cost is at most ``alpha``
        ([`stability_allocate`][packetloss_cvx.allocation.stability.stability_allocate]; as ``--target`` on the command
        line: the
        law measures the state each step, so ``protocol`` is checked but does not enter).
    margin : float, optional
        Target "stable" only: the bound on the mean-square radius, ``0 < margin <= 1`` (default 1).
    actuator : str, optional
        Actuator strategies on a loss ("zero", "hold", "buffer:L", comma-separated, or "all"; checked before any
        work): the result's ``actuator`` says, per strategy, whether mu* is stabilisable by a TCP-like law of it
        (closedloop.actuator_region.actuator_membership at mu*, Bernoulli links), as ``allocate --actuator``.

    Returns
    -------
    Allocation
        ``mu`` feasible by the closed form; ``lower_bound`` proven; ``status`` "optimal" (gap
        certified) or "gap_not_certified" (a cap was hit; ``gap`` is the gap reached);
        ``boxes`` explored; ``attainable_cost`` and ``stabilisable`` at mu (`.attainable`).
        A `StabilityAllocation` for the targets "stable" and "dp-cost".

    Raises
    ------
    InputError
        A bad argument, named by its field.
    InfeasibleError
        Proven infeasible; ``min_cost`` carries the least reachable cost (None when the
        constraints admit no mu at all).
    SolverError
        A solver status other than optimal (never turned into "infeasible"), or a cap hit
        before any feasible mu was found.

    Notes
    -----
    TCP-like: one SOCP with O(N (n + m)) variables, one LP, O(log(1/gap)) closed forms.
    UDP-like: the TCP-like SOCP, then up to ``max_boxes`` boxes, each an LP and
    O(m log(1/tol)) closed forms of O(N (n^3 + m^3)); worst case (1/gap)^(m-1) boxes.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0],
    ...            mu=[0.5], x0=[1.0])
    >>> a = allocate(s, "tcp", alpha=1.5, beta=[1.0])
    >>> bool(a.cost <= 1.5), a.status, bool(a.lower_bound <= a.communication_cost)
    (True, 'optimal', True)
    """
    if actuator is not None:
        strategies = _strategies(actuator, system)
        result = allocate(system, protocol, alpha, beta, bounds, constraints, gap, max_boxes, time_limit, progress,
                          target, margin)
        return dataclasses.replace(result, actuator=tuple(_actuator_verdict(system, s, result.mu)
                                                          for s in strategies))
    protocol = check_protocol(protocol)
    if target == "attainable" and protocol == "tcp":
        return _attainable_allocate(system, alpha, beta, bounds, constraints, gap, max_boxes, time_limit, progress,
                                    margin)
    if target not in ("paper", "attainable"):      # UDP-like, J*_udp is the attainable cost: the paper's program
        return _loop_target(system, target, alpha, beta, bounds, constraints, gap, max_boxes, time_limit, progress,
                            margin)
    if margin is not None:
        raise InputError("margin", "applies to target='stable' only (the paper's program bounds J*: alpha)")
    given = system                                            # with its chain, for what the loop attains
    system, evaluator = _behind_chain(system, protocol)       # a chain: its mean rates (chains.py)
    system = check_system(system)
    alpha = check_alpha(alpha)
    beta = check_beta(beta, system.m)
    lo, hi = check_bounds(bounds)
    gap = check_gap(gap)
    max_boxes = _max_boxes(max_boxes, system if protocol == "udp" and evaluator is None else None)
    time_limit = _time_limit(time_limit)
    poly = _polytope([*constraints, *_family_rows(evaluator, lo)], system.m, lo, hi)
    if evaluator is not None:
        return _chain_allocate(system, evaluator, alpha, beta, poly, gap, max_boxes, time_limit, progress)
    # the problem is invariant to the scale of the prices: solve with max(beta) = 1 and scale back,
    # so that no floor of the gap can certify it at tiny prices (boxes.unit_prices, boxes.gap_unit)
    prices, unit = unit_prices(beta)

    def infeasible(proof: str) -> InfeasibleError:
        return _infeasible(system, protocol, alpha, poly, proof, max_boxes, time_limit)

    try:
        relaxation = tcp_allocate(system, poly, alpha, prices, gap)
    except InfeasibleError as err:
        proof = str(err) if protocol == "tcp" else f"the TCP-like relaxation is infeasible (Theorem 2): {err}"
        raise infeasible(proof) from None
    except (SolverError, NumericalError) as err:       # the relaxation failed: the UDP-like search goes without it
        if protocol == "tcp":
            raise
        relaxation, floor_note = None, f"; TCP-like bound unavailable ({err})"
    if protocol == "tcp":
        out = relaxation
    else:
        floor = relaxation.lower_bound if relaxation is not None else -np.inf
        try:
            out = udp_allocate(system, poly, alpha, prices, gap, floor, max_boxes, time_limit, progress=progress)
        except InfeasibleError as err:
            raise infeasible(str(err)) from None
        if relaxation is not None:
            floor_note = f"; TCP-like lower bound {relaxation.lower_bound:.6g} (Theorem 2)"
        out = out._replace(note=out.note + floor_note)
    scaled = float(prices @ out.mu)
    cost = cost_at(system, protocol, out.mu) if out.cost is None else out.cost
    return _attained(Allocation(mu=out.mu, communication_cost=float(beta @ out.mu), cost=cost,
                                lower_bound=out.lower_bound * unit,
                                gap=reported_gap(scaled, out.lower_bound, out.scale),
                                status=out.status, method=out.note, protocol=protocol, alpha=alpha, beta=beta,
                                boxes=out.boxes), given)


def _attainable_allocate(system: System, alpha: float, beta, bounds, constraints: Sequence[Constraint], gap: float,
                         max_boxes: int | None, time_limit: float | None, progress: bool | None,
                         margin: float | None) -> Allocation:
    """The TCP-like design on the attainable cost: min beta'mu with the finite-horizon DP's cost <= alpha, by the
    monotone branch and bound of `.udp` on `.attainable.AttainableEvaluator` (the cost falls in each
    mu_i: docs/mathematics.md, "Design on the attainable cost"; no TCP-like floor, none being proved for it)."""
    if margin is not None:
        raise InputError("margin", "applies to target='stable' only (target='attainable' bounds a cost: alpha)")
    given = system
    chain = isinstance(system, System) and system.channel is not None
    if chain:           # the chain DP along each channel's family (.attainable.ChainAttainableEvaluator)
        system = system.with_mu(chain_rates(system))
    system = check_system(system)
    if system.sensor is not None:
        raise InputError("target", "'attainable' designs the full-state loop; this system has lossy [sensor] links")
    alpha = check_alpha(alpha)
    beta = check_beta(beta, system.m)
    lo, hi = check_bounds(bounds)
    gap = check_gap(gap)
    max_boxes = _max_boxes(max_boxes, system)
    time_limit = _time_limit(time_limit)
    evaluator = ChainAttainableEvaluator(given) if chain else AttainableEvaluator(system)
    poly = _polytope([*constraints, *_family_rows(evaluator if chain else None, lo)], system.m, lo, hi)
    prices, unit = unit_prices(beta)
    what = "TCP-like design on the attainable cost" + (" behind the chain" if chain else "")
    f = MonotoneCost(evaluator)
    try:
        out = udp_allocate(system, poly, alpha, prices, gap, -np.inf, max_boxes, time_limit, progress=progress,
                           cost=f, what=what)
    except InfeasibleError as err:
        raise InfeasibleError(f"{what}: no mu within the bounds and constraints attains a cost <= alpha = {alpha:g} "
                              f"({err})", None) from None
    cost = f.checked(out.mu) if out.cost is None else out.cost
    return _attained(Allocation(mu=out.mu, communication_cost=float(beta @ out.mu), cost=cost,
                                lower_bound=out.lower_bound * unit,
                                gap=reported_gap(float(prices @ out.mu), out.lower_bound, out.scale),
                                status=out.status, method=f"{out.note}; on the attainable cost (finite-horizon DP with "
                                                          "acknowledgements" + (f", {evaluator.family.describe()})"
                                                                                if chain else ")"),
                                protocol="tcp", alpha=alpha, beta=beta, boxes=out.boxes), given, basis="attainable")


def _attained(result: Allocation, system: System, chain: bool = False, basis: str | None = None) -> Allocation:
    """``result`` with what a loop attains at its mu (`.attainable.attainment`)."""
    found = attainment(system, result.protocol, result.mu, result.cost, chain)
    basis = basis or ("attainable" if chain else "paper")
    return dataclasses.replace(result, basis=basis, attainable_cost=found.cost,
                               attainable_note=found.cost_note, stabilisable=found.stabilisable,
                               stability_note=found.stability_note)


def _loop_target(system: System, target: str, alpha: float | None, beta, bounds, constraints: Sequence[Constraint],
                 gap: float, max_boxes: int | None, time_limit: float | None, progress: bool | None,
                 margin: float | None) -> StabilityAllocation:
    """[`allocate`][packetloss_cvx.allocation.api.allocate]'s targets other than the paper's: the closed-loop designs
    of `.stability`."""
    if target not in ALLOCATION_TARGETS:
        raise InputError("target", f"expected one of {', '.join(ALLOCATION_TARGETS)}, found {target!r}")
    options: dict[str, Any] = {} if max_boxes is None else {"max_boxes": max_boxes}
    return stability_allocate(system, target, beta, margin=margin, alpha=alpha, bounds=bounds,
                              constraints=constraints, gap=gap, time_limit=time_limit, progress=progress, **options)


def _chain_allocate(system: System, evaluator: ChainEvaluator, alpha: float, beta: np.ndarray, poly: Polytope,
                    gap: float, max_boxes: int, time_limit: float | None, progress: bool | None) -> Allocation:
    """The UDP-like allocation behind chains (each channel along its family, chains.py): the monotonic branch and
    bound on the exact cost under the chain (no TCP-like floor: Theorem 2 is not established under a chain), prices
    scaled as [`allocate`][packetloss_cvx.allocation.api.allocate]."""
    prices, unit = unit_prices(beta)
    try:
        out = udp_allocate(system, poly, alpha, prices, gap, -np.inf, max_boxes, time_limit, progress=progress,
                           cost=MonotoneCost(evaluator))
    except InfeasibleError as err:
        raise _infeasible(system, "udp", alpha, poly, str(err), max_boxes, time_limit, evaluator) from None
    note = f"{out.note}; exact expected cost {evaluator.family.describe()}"
    scaled = float(prices @ out.mu)
    cost = evaluator.cost(out.mu) if out.cost is None else out.cost
    return _attained(Allocation(mu=out.mu, communication_cost=float(beta @ out.mu), cost=cost,
                                lower_bound=out.lower_bound * unit,
                                gap=reported_gap(scaled, out.lower_bound, out.scale),
                                status=out.status, method=note, protocol="udp", alpha=alpha, beta=beta,
                                boxes=out.boxes), evaluator.system,
                     chain=True)


@blas_limited
def best_cost_within_budget(system: System, protocol: str, beta, budget: float, bounds=(0.0, 1.0),
                            constraints: Sequence[Constraint] = (), max_boxes: int | None = None,
                            time_limit: float | None = None) -> MinCost:
    """The other side of the trade-off: min J*(mu) subject to beta'mu <= budget.

    The budget is one more row of the constraint set; see [`min_cost`][packetloss_cvx.allocation.api.min_cost] (convex
    for the TCP-like protocol, a branch and bound for the UDP-like one).

    Raises
    ------
    InputError
        beta or budget malformed (budget must be a finite number).
    InfeasibleError
        No mu within the bounds and constraints fits the budget.

    Notes
    -----
    As [`min_cost`][packetloss_cvx.allocation.api.min_cost] with one more row.

    Examples
    --------
    Two decoupled channels of x' = x + v u (N = 1), J*_tcp = 1/(1 + mu1) + 1/(1 + mu2): a budget
    mu1 + mu2 <= 1 is best spent evenly (4/3); a budget below what the bounds force is infeasible.

    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> best = best_cost_within_budget(t, "tcp", [1.0, 1.0], 1.0)
    >>> bool(np.isclose(best.cost, 4 / 3)), bool(np.isclose(best.mu, 0.5, atol=1e-4).all())
    (True, True)
    >>> try:
    ...     best_cost_within_budget(t, "tcp", [1.0, 1.0], 1.0, bounds=(0.6, 1.0))     # mu1 + mu2 >= 1.2
    ... except InfeasibleError as err:
    ...     "least value 1.2 > 1" in str(err)
    True
    """
    system = check_system(system)
    beta = check_beta(beta, system.m)
    budget = check_number(budget, "budget")
    return min_cost(system, protocol, bounds, [*constraints, (beta[None, :], np.array([budget]))], max_boxes,
                    time_limit)


@blas_limited
def cheapest_links(system: System, alpha: float, beta=None, actuators: str | Sequence[Actuator] = "all",
                   bounds=(0.0, 1.0),
                   gap: float = ALLOCATION_GAP_DEFAULT, max_boxes: int | None = None,
                   time_limit: float | None = None) -> dict[str, dict[str, Any]]:
    """Per actuator strategy, the cheapest links (min beta'mu over ``[lo, hi]^m``) at which the strategy's optimal
    TCP-like law costs at most ``alpha``: `stability_allocate`'s target "dp-cost" with ``actuator=`` (the monotone
    branch and bound on the strategy's DP cost, closedloop.actuator_design.actuator_dp), the cost basis
    (`strategy_dp_cost`) the average stage cost when the system has process noise, else the total noise-free cost
    from x0, over an infinite horizon. Full state; Bernoulli links, or behind the system's stationary chain each
    channel's mean rate along its family (`.chains.chain_family`: burstiness held on Gilbert channels, deliveries
    scaled on the others, mean rates up to the family's top; the law knows the current channel state).

    Each strategy's row (keyed by its name) has ``verdict``:

    * "reachable": ``mu`` with its DP ``cost <= alpha``, ``communication_cost`` beta'mu, its proved
      ``lower_bound``, ``gap`` and ``status`` ("optimal": the gap certified, else "gap_not_certified"),
      ``radius`` of its law, ``stabilisable`` (True on an exact certificate, None with ``stability_note``);
    * "unreachable", proved (every box discarded by a DP cost above ``alpha (1 + ALLOCATION_COST_RTOL)`` or an
      exact certificate that no law of the strategy is stable), with ``least_cost``, the cost at the upper corner
      ``least_cost_mu`` (the least over the box: the cost falls in each mu_i), None where no stabilising solution
      exists there, and the ``reason``;
    * "undecided" (a cap hit before a point was certified, or a check that failed: the ``reason``), or "not
      computed" (refused for its size: the ``reason``).

    Raises
    ------
    InputError
        A bad argument, named by its field (``actuator``, ``alpha``, ``beta``, ``bounds``, ``gap``).

    Examples
    --------
    One state, x+ = 2 x + v u, Omega = Psi = 1, noise-free from x0 = 1: for zero the cost from x0 is the positive root
    of (4 mu - 3) P^2 - 4 P - 1 = 0, 4 + 3 sqrt(2) at mu = 7/8, so a target of 4 + 3 sqrt(2) needs mu = 7/8.

    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    >>> row = cheapest_links(s, 4 + 3 * 2 ** 0.5, [1.0], "zero", gap=1e-6)["zero"]
    >>> row["verdict"], bool(abs(row["mu"][0] - 0.875) <= 1e-5), row["basis"]
    ('reachable', True, 'total from x0')
    """
    strategies = _strategies(actuators, system) if isinstance(actuators, str) else tuple(
        parse_actuator(a, check_system(system).horizon) for a in actuators)
    system = check_system(system)
    alpha = check_alpha(alpha)
    beta = np.ones(system.m) if beta is None else check_beta(beta, system.m)
    lo, hi = check_bounds(bounds)
    gap = check_gap(gap)
    basis = "average" if np.any(system.noise_cov != 0) else "total from x0"
    family = None if system.channel is None else chain_family(system)      # a given start refused here
    rows: dict[str, dict[str, Any]] = {}
    for strategy in strategies:
        row: dict[str, Any] = {"alpha": alpha, "basis": basis, "beta": beta.tolist()}
        rows[str(strategy)] = row
        try:
            found = stability_allocate(system, "dp-cost", beta, alpha=alpha, bounds=(lo, hi), gap=gap,
                                       time_limit=time_limit, actuator=strategy,
                                       **({} if max_boxes is None else {"max_boxes": max_boxes}))
        except InfeasibleError as err:
            row.update(verdict="unreachable", reason=str(err), **_least_cost(system, strategy, hi, family))
        except SolverError as err:
            row.update(verdict="undecided", reason=str(err))
        except BudgetError as err:
            row.update(verdict="not computed", reason=str(err))
        else:
            row.update(verdict="reachable", mu=found.mu.tolist(), communication_cost=found.cost,
                       cost=None if not np.isfinite(found.dp_cost) else found.dp_cost,
                       lower_bound=found.lower_bound, gap=found.gap, status=found.status, radius=found.radius,
                       stabilisable=found.stabilisable, stability_note=found.stability_note, boxes=found.boxes)
    return rows


def _least_cost(system: System, strategy: Actuator, hi: float, family: ChainFamily | None) -> dict[str, Any]:
    """The least cost over ``[lo, hi]^m``: the strategy's DP cost at the upper corner (the cost falls in each
    mu_i; behind a chain each mean rate also at most its family's top), None with the reason where no stabilising
    solution is found there."""
    mu = np.full(system.m, hi)
    try:
        if family is None:
            design = actuator_dp(system, strategy, mu)
        else:
            mu = np.minimum(mu, family.top)
            design = actuator_dp(system.with_channel(family.channel_at(mu)), strategy)
        cost, _ = strategy_dp_cost(system, design)
    except NumericalError as err:
        return {"least_cost": None, "least_cost_mu": mu.tolist(), "least_cost_reason": str(err)}
    return {"least_cost": cost, "least_cost_mu": mu.tolist()}
