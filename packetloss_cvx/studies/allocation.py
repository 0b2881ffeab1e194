"""Studies built on the allocation: the Pareto trade-off alpha <-> beta'`mu*` and the optimal
allocations on cost contours (§VI, Figs. 6–7), with the `J*(mu)` grid those figures show.

They compute data; `packetloss_cvx.plots.figures` draws it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..allocation.api import allocate
from ..errors import InfeasibleError, InputError
from ..model.protocols import check_protocol
from ..model.system import System
from ..progress import progress_bar
from ..studies.sweeps import two_channel_sweep

__all__ = ["contour_allocations", "cost_grid", "pareto_curve"]

#: The grid of the contour figure may not exceed this many points per axis (grid^2 closed forms).
MAX_GRID = 401


def pareto_curve(system: System, protocol: str, beta, alphas: Sequence[float], progress: bool | None = None,
                 **kwargs) -> list[dict]:
    """The trade-off alpha -> beta'mu*: one allocation per cost bound.
    Each point solves eq:channel-opt for its alpha.

    Parameters
    ----------
    system, protocol, beta
        As for [`allocate`][packetloss_cvx.allocation.api.allocate].
    alphas : sequence of float
        Cost bounds.
    progress : bool or None
        A bar on stderr, one step per alpha (None: when stderr is a terminal).
    **kwargs
        Passed to [`allocate`][packetloss_cvx.allocation.api.allocate] (bounds, constraints, gap, ...).

    Returns
    -------
    list of dict
        One row per alpha: ``{"alpha", "communication_cost", "mu", "lower_bound", "status"}``;
        an alpha proven infeasible has ``communication_cost``, ``mu`` and ``lower_bound``
        None and ``status`` "infeasible".

    Notes
    -----
    One allocation per alpha: O(len(alphas)) times the cost of
    [`allocate`][packetloss_cvx.allocation.api.allocate].

    Examples
    --------
    One step of x' = x + v u from x0 = 1: J*_tcp = 1/(1 + mu) is at least 1/2, and <= 0.8 from mu = 1/4 on.

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> low, high = pareto_curve(s, "tcp", [1.0], [0.4, 0.8])
    >>> low["status"], high["status"], bool(np.isclose(high["mu"][0], 0.25, atol=1e-4))
    ('infeasible', 'optimal', True)
    """
    out = []
    for alpha in progress_bar(alphas, total=len(alphas), desc=f"{protocol} Pareto curve", progress=progress):
        try:
            a = allocate(system, protocol, alpha, beta, progress=False, **kwargs)
        except InfeasibleError:
            out.append({"alpha": float(alpha), "communication_cost": None, "mu": None, "lower_bound": None,
                        "status": "infeasible"})
            continue
        out.append({"alpha": a.alpha, "communication_cost": a.communication_cost, "mu": a.mu.tolist(),
                    "lower_bound": a.lower_bound, "status": a.status})
    return out


def contour_allocations(system: System, protocol: str, alphas: Sequence[float],
                        betas: Sequence[Sequence[float]] = ((1, 1), (0.05, 1), (1, 0.05)),
                        progress: bool | None = None, **kwargs) -> dict[tuple[float, ...], list[dict]]:
    """Figs. 6–7: the optimal allocation on each cost contour alpha, for each price vector beta.
    Each allocation is the paper's eq:opt_M for its alpha and beta.

    Returns
    -------
    dict
        ``tuple(beta) -> pareto_curve(system, protocol, beta, alphas)``.

    Notes
    -----
    O(len(betas) len(alphas)) allocations.

    Examples
    --------
    Two decoupled channels of x' = x + v u (N = 1): J*_udp = 2 - (mu1 + mu2)/2 <= 1.5 is
    mu1 + mu2 >= 1, bought on the cheaper channel.

    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> out = contour_allocations(t, "udp", [1.5], betas=[(1, 2), (2, 1)])
    >>> sorted(out), [np.round(rows[0]["mu"], 3).tolist() for rows in out.values()]
    ([(1.0, 2.0), (2.0, 1.0)], [[1.0, 0.0], [0.0, 1.0]])
    """
    return {tuple(float(b) for b in beta): pareto_curve(system, protocol, beta, alphas, progress=progress, **kwargs)
            for beta in betas}


def cost_grid(system: System, protocol: str, grid: int = 41) -> tuple[np.ndarray, np.ndarray]:
    """J*(mu) on a uniform grid of [0, 1]^2, the background of the contour figure (two channels).

    Parameters
    ----------
    system : System
        Two channels (m = 2); its own mu is ignored.
    protocol : {"tcp", "udp"}
    grid : int
        Points per axis, 2 <= grid <= `MAX_GRID`.

    Returns
    -------
    axis : ndarray, shape (grid,)
        ``linspace(0, 1, grid)``.
    costs : ndarray, shape (grid, grid)
        ``costs[j, i] = J*(mu1 = axis[i], mu2 = axis[j])`` (rows follow mu2, as ``contour`` expects).

    Notes
    -----
    ``grid**2`` closed forms, each O(N (n^3 + m^3)) by the recursion or O((N m)^3) dense.

    Examples
    --------
    Two decoupled channels of x' = x + v u (N = 1): J*_udp = 2 - (mu1 + mu2)/2.

    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> axis, costs = cost_grid(t, "udp", grid=3)
    >>> bool(np.allclose(costs, 2 - (axis[None, :] + axis[:, None]) / 2)), costs.shape
    (True, (3, 3))
    """
    protocol = check_protocol(protocol)
    if system.m != 2:
        raise InputError("system", f"the contour grid needs m = 2 channels, found m = {system.m}")
    if isinstance(grid, bool) or not isinstance(grid, (int, np.integer)) or not 2 <= grid <= MAX_GRID:
        raise InputError("grid", f"expected an integer from 2 to {MAX_GRID}, found {grid!r}")
    axis = np.linspace(0.0, 1.0, int(grid))
    return axis, np.array(two_channel_sweep(system, axis, protocols=(protocol,)).costs[protocol])
