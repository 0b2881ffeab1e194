"""Studies built on the allocation: the Pareto trade-off alpha <-> beta'mu* and the optimal
allocations on cost contours (§VI, Figs. 6–7). They compute data; plots.py draws it."""

from __future__ import annotations

from collections.abc import Sequence

from ..errors import InfeasibleError
from ..model import System
from .api import allocate

__all__ = ["contour_allocations", "pareto_curve"]


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
