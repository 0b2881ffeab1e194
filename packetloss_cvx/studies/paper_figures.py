"""The data behind each of the paper's figures and tables, computed from its two case studies.

Each function returns plain data (arrays, lists, floats) that `packetloss_cvx.plots.figures` draws and
``packetloss-cvx reproduce`` reports: nothing here draws, and nothing here knows what the paper
printed (that is `packetloss_cvx.claims.paper`).

* [`log_cost_pendulum`][packetloss_cvx.studies.paper_figures.log_cost_pendulum]: fig:log-cost-pendulum (log `J*` of both
protocols against nu, the
  maximiser of J_Delta);
* [`mixed_grids`][packetloss_cvx.studies.paper_figures.mixed_grids]: fig:cost-diff-mixed, fig:TCP-log-cost-mixed,
fig:UDP-log-cost-mixed (`J*` and
  J_Delta over [0, 1]^2, the maximiser of J_Delta);
* [`mixed_allocations`][packetloss_cvx.studies.paper_figures.mixed_allocations]: fig:TCP-log-cost-mixed-mult and
fig:UDP-log-cost-mixed-mult (the
  allocations of eq:opt_M on each cost contour alpha, for each price vector beta);
* [`eigenvalue_tables`][packetloss_cvx.studies.paper_figures.eigenvalue_tables]: tab:closed-loop-eig and
tab:closed-loop-eig-mixed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..lq import analysis as an
from ..lq import difference
from ..model.system import System
from .allocation import contour_allocations
from .sweeps import shared_channel_sweep, two_channel_sweep

__all__ = ["PAPER_BETAS", "eigenvalue_tables", "log_cost_pendulum", "mixed_allocations", "mixed_grids",
           "path_jumps", "pendulum_nus"]

#: The three price vectors of §VI (beta = I, (0.05, 1), (1, 0.05)).
PAPER_BETAS = ((1.0, 1.0), (0.05, 1.0), (1.0, 0.05))


def pendulum_nus(points: int) -> np.ndarray:
    """nu on (0, 1]: ``points`` log-spaced from 1e-6 (where J_Delta peaks) and ``points`` uniform. O(points).

    Examples
    --------
    >>> pendulum_nus(3).tolist()        # 1e-6, 1e-3, 1 and 0.5, 1 (0 dropped, 1 once)
    [1e-06, 0.001, 0.5, 1.0]
    """
    return np.unique(np.concatenate([np.logspace(-6, 0, points), np.linspace(0.0, 1.0, points)[1:]]))


def log_cost_pendulum(system: System, points: int = 150) -> dict[str, Any]:
    """fig:log-cost-pendulum: `J*_tcp(nu)`, `J*_udp(nu)` and J_Delta(nu) with every actuator behind one
    channel nu, and the maximiser of J_Delta
    ([`maximise_cost_difference`][packetloss_cvx.lq.difference.maximise_cost_difference]).

    Returns ``{"nu", "tcp", "udp", "diff", "difference_method", "maximiser": {"nu", "value", "method"}}``
    (arrays for the curves). O(points (N m)^3).

    Examples
    --------
    One step of x' = x + v u: J_Delta(nu) = 1 - nu/2 - 1/(1 + nu), largest at nu = sqrt(2) - 1, 1.5 - sqrt(2).

    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> best = log_cost_pendulum(s, points=2)["maximiser"]
    >>> bool(np.isclose(best["nu"], 2 ** 0.5 - 1, atol=1e-6) and np.isclose(best["value"], 1.5 - 2 ** 0.5))
    True
    """
    nus = pendulum_nus(points)
    result = shared_channel_sweep(system, nus)
    best = difference.maximise_cost_difference(difference.scalar_channel(system, 0.5), grid=200)
    return {"nu": nus, "tcp": np.array(result.costs["tcp"]), "udp": np.array(result.costs["udp"]),
            "diff": np.array(result.difference), "difference_method": result.difference_method,
            "maximiser": {"nu": float(best.point[0]), "value": best.value, "method": best.method}}


def mixed_grids(system: System, grid: int = 101) -> dict[str, Any]:
    """fig:cost-diff-mixed, fig:TCP-log-cost-mixed, fig:UDP-log-cost-mixed: J* and J_Delta over a
    ``grid`` × ``grid`` grid of [0, 1]^2 (``values[j, i]`` at ``mu1 = axis[i], mu2 = axis[j]``) and the
    maximiser of J_Delta ([`maximise_cost_difference_2d`][packetloss_cvx.lq.difference.maximise_cost_difference_2d]).

    O(grid^2 (N m)^3).

    Examples
    --------
    Two decoupled copies of x' = x + v u, N = 1: J_Delta is the sum of two, each largest at sqrt(2) - 1.

    >>> from packetloss_cvx.model.system import System
    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> out = mixed_grids(t, grid=3)
    >>> out["axis"].tolist(), bool(np.allclose(out["maximiser"]["mu"], 2 ** 0.5 - 1, atol=1e-5))
    ([0.0, 0.5, 1.0], True)
    >>> bool(np.isclose(out["maximiser"]["value"], 3 - 2 * 2 ** 0.5) and np.isclose(out["diff"][1, 1], 1 / 6))
    True
    """
    axis = np.linspace(0.0, 1.0, grid)
    result = two_channel_sweep(system, axis)
    best = difference.maximise_cost_difference_2d(system, grid=41)
    return {"axis": axis, "tcp": np.array(result.costs["tcp"]), "udp": np.array(result.costs["udp"]),
            "diff": np.array(result.difference), "difference_method": result.difference_method,
            "maximiser": {"mu": best.point.tolist(), "value": best.value, "method": best.method}}


def mixed_allocations(system: System, protocol: str, alphas: Sequence[float],
                      betas: Sequence[Sequence[float]] = PAPER_BETAS,
                      progress: bool | None = None) -> dict[tuple[float, ...], list[dict]]:
    """fig:TCP-/UDP-log-cost-mixed-mult: the cheapest allocation (eq:opt_M) on each contour
    J* = alpha for each beta ([`contour_allocations`][packetloss_cvx.studies.allocation.contour_allocations]).

    O(len(betas) len(alphas)) allocations.

    Examples
    --------
    Two decoupled copies of x' = x + v u, N = 1: J*_tcp = 1/(1 + mu1) + 1/(1 + mu2) = 1.5 costs
    mu1 + mu2 at least 2/3 (mu1 = mu2 = 1/3); a cheap channel is bought in full (0.05 * 1).

    >>> from packetloss_cvx.model.system import System
    >>> t = System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.5, 0.5], x0=[1.0, 1.0])
    >>> out = mixed_allocations(t, "tcp", [1.5])
    >>> bool(np.allclose(out[(1.0, 1.0)][0]["mu"], 1 / 3, atol=1e-5))
    True
    >>> cheap = out[(0.05, 1.0)][0]
    >>> bool(np.allclose(cheap["mu"], [1, 0], atol=1e-5)), round(cheap["communication_cost"], 5)
    (True, 0.05)
    """
    return contour_allocations(system, protocol, list(alphas), betas=betas, progress=progress)


def path_jumps(axis: Sequence[float], costs: Any, beta: Sequence[float], alphas: Sequence[float],
               substeps: int = 64, move: float = 0.15) -> list[int]:
    """The steps of a path of cheapest allocations (one per cost bound ``alphas[k]``, as `mixed_allocations`
    returns them) across which the optimum jumps rather than slides: k where, between ``alphas[k]`` and
    ``alphas[k + 1]`` (``substeps`` bounds spaced geometrically), the cheapest grid point of {J* <= a} for the
    prices ``beta`` (positive) moves by more than ``move`` plus the grid's own error from one bound to the next. A
    sliding optimum moves by a grid step or so per substep; a jump (a non-convex sublevel set, the UDP-like
    cost's) crosses the map at once. The grid's error: a step h in the dearer channel trades against
    h max(beta) / min(beta) in the cheaper one, so the cheapest grid point may hop that far along a flat contour.
    A figure breaks the path's line there instead of drawing a straight segment no optimum lies on.
    ``costs[j, i] = J*(axis[i], axis[j])`` (`mixed_grids`). Read at the grid's resolution: a jump shorter than
    ``move`` is not told from a slide. O(len(alphas) substeps g^2).

    Examples
    --------
    Two pits: J* = 2 within 0.1 of (0.1, 0.9) and of (0.9, 0.1), 4 within 0.3 of (0.9, 0.1) only, 9 elsewhere.
    With beta = (1, 1) the cheapest point at bound 4 is near (0.6, 0.1), at bound 2 it jumps to near (0.1, 0.8):

    >>> axis = np.linspace(0.0, 1.0, 51)
    >>> m1, m2 = np.meshgrid(axis, axis)
    >>> J = np.full(m1.shape, 9.0)
    >>> J[np.hypot(m1 - 0.9, m2 - 0.1) <= 0.3] = 4.0
    >>> J[(np.hypot(m1 - 0.1, m2 - 0.9) <= 0.1) | (np.hypot(m1 - 0.9, m2 - 0.1) <= 0.1)] = 2.0
    >>> path_jumps(axis, J, (1.0, 1.0), [4.0, 2.5]), path_jumps(axis, J, (1.0, 1.0), [4.0, 5.0])
    ([0], [])
    """
    grid = np.asarray(axis, dtype=float)
    J = np.asarray(costs, dtype=float)
    m1, m2 = np.meshgrid(grid, grid)
    price = (beta[0] * m1 + beta[1] * m2).ravel()
    points = np.column_stack([m1.ravel(), m2.ravel()])
    slack = float(np.max(np.diff(grid))) * max(beta) / min(beta)
    out = []
    for k in range(len(alphas) - 1):
        bounds = np.geomspace(alphas[k], alphas[k + 1], substeps)
        feasible = J.ravel()[None, :] <= bounds[:, None]
        found = feasible.any(axis=1)
        best = np.argmin(np.where(feasible, price[None, :], np.inf), axis=1)[found]
        if best.size > 1 and np.max(np.linalg.norm(np.diff(points[best], axis=0), axis=1)) > move + slack:
            out.append(k)
    return out


def eigenvalue_tables(pendulum: System, mixed: System, mu_pendulum: Sequence[float],
                      mu_mixed: Sequence[float]) -> dict[str, dict[str, dict[str, list[complex]]]]:
    """tab:closed-loop-eig and tab:closed-loop-eig-mixed: closed-loop eigenvalues of both laws
    ([`eigenvalue_table`][packetloss_cvx.lq.analysis.eigenvalue_table]: ``"A-BK"``, the paper's convention, and
    ``"A-BMK"``).

    O((N m)^3) per system.

    Examples
    --------
    x' = x + v u, N = 1, mu = 0.5: the TCP-like gain is K = 1/(1 + mu) = 2/3, so A - BK = 1/3 and
    A - B mu K = 2/3; the UDP-like gain is 1/2 (0.5 and 0.75).

    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> one = eigenvalue_tables(s, s, [0.5], [0.5])["table-1"]
    >>> bool(np.allclose([one["tcp"]["A-BK"][0], one["tcp"]["A-BMK"][0]], [1 / 3, 2 / 3]))
    True
    >>> bool(np.allclose([one["udp"]["A-BK"][0], one["udp"]["A-BMK"][0]], [0.5, 0.75]))
    True
    """
    return {"table-1": an.eigenvalue_table(pendulum, list(mu_pendulum)),
            "table-2": an.eigenvalue_table(mixed, list(mu_mixed))}
