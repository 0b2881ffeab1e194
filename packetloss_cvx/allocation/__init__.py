"""Channel allocation M* (§VI): the cheapest delivery probabilities that keep J* <= alpha.

Modules: ``grammar`` (constraint grammar, argument checks), ``boxes`` (LPs over sub-boxes,
bisection), ``tcp`` (the exact TCP-like SOCP), ``udp`` (monotonic branch and bound),
``api`` (allocate, min_cost, best_cost_within_budget), ``studies`` (Pareto curve, contour
allocations), ``brute_force`` (an independent two-channel reference for tests and the audit).
"""

from collections.abc import Sequence

from ..errors import InfeasibleError
from ..model import System
from ..results import Allocation
from .api import allocate, best_cost_within_budget, min_cost
from .grammar import parse_constraint

__all__ = [
    "Allocation", "allocate", "best_cost_within_budget", "contour_allocations", "min_cost", "parse_constraint",
    "pareto_curve",
]


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
