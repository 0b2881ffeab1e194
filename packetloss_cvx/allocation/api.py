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

from collections.abc import Sequence

import numpy as np

from ..errors import InfeasibleError, InputError, SolverError
from ..model import System
from ..protocols import check_protocol
from ..results import Allocation
from .boxes import BoxLP, boundary, cost_at
from .grammar import Constraint, check_inputs, polytope
from .tcp import tcp_allocate, tcp_min_cost
from .udp import udp_allocate, udp_min_cost

__all__ = ["allocate", "best_cost_within_budget", "min_cost"]


def min_cost(system: System, protocol: str, bounds=(0.0, 1.0), constraints: Sequence[Constraint] = ()) -> float:
    """The least optimal cost J*(mu) reachable within the bounds and constraints."""
    protocol = check_protocol(protocol)
    _, _, lo, hi = check_inputs(system, 1.0, np.zeros(system.m), bounds)
    G, h, calls = polytope(constraints, system.m)
    if protocol == "tcp":
        return tcp_min_cost(system, lo, hi, G, h, calls)
    return udp_min_cost(system, lo, hi, G, h, calls)


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
    mu, lower, boxes = udp_allocate(system, alpha, beta, lo, hi, G, h, calls, gap, max_boxes, tcp_bound)
    if mu is None:
        raise infeasible()
    value = float(beta @ mu)
    lower = min(lower, value)
    return Allocation(mu=mu, communication_cost=value, cost=cost_at(system, "udp", mu), lower_bound=lower,
                      gap=(value - lower) / max(value, 1e-12), status="optimal",
                      method="monotonic branch and bound (LP bounds, TCP-like relaxation)", protocol=protocol,
                      alpha=alpha, beta=beta, boxes=boxes)


def best_cost_within_budget(system: System, protocol: str, beta, budget: float, bounds=(0.0, 1.0),
                            constraints: Sequence[Constraint] = ()) -> float:
    """The other side of the trade-off: min J*(mu) s.t. beta'mu <= budget (convex for TCP-like)."""
    beta = np.asarray(beta, dtype=float)
    if beta.shape != (system.m,) or np.any(beta < 0):
        raise InputError("beta", f"expected {system.m} non-negative numbers")
    return min_cost(system, protocol, bounds, [*constraints, (beta[None, :], np.array([float(budget)]))])
