"""Matplotlib figures drawn from data that something else computed.

Each function takes data (for instance from :mod:`packetloss_cvx.allocation.studies`),
returns a :class:`matplotlib.figure.Figure` and, when ``path`` is given, saves it there.
Figures are built without pyplot, so a notebook's backend and open figures are untouched,
and nothing here computes an allocation or a cost.

Example
-------
>>> from packetloss_cvx.plots import plot_pareto
>>> fig = plot_pareto({"tcp": [{"alpha": 5.0, "communication_cost": 1.2},
...                            {"alpha": 8.0, "communication_cost": 0.9}]})
>>> [line.get_label() for line in fig.axes[0].lines]
['TCP-like']
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from .errors import InputError
from .model import numeric_array

__all__ = ["plot_allocation_contours", "plot_closed_loop", "plot_pareto"]

_LABELS = {"tcp": "TCP-like", "udp": "UDP-like"}
_MARKERS = ("x", "^", "s", "o", "v", "D")


def _rows(rows: Any, field: str, keys: tuple[str, ...]) -> list[Mapping]:
    if not isinstance(rows, Sequence) or isinstance(rows, str):
        raise InputError(field, "expected a list of rows (dicts)")
    for k, row in enumerate(rows):
        if not isinstance(row, Mapping) or any(key not in row for key in keys):
            raise InputError(f"{field}[{k}]", f"expected a dict with keys {', '.join(keys)}")
    return list(rows)


def _save(fig: Figure, path: str | Path | None) -> Figure:
    if path is None:
        return fig
    try:
        fig.savefig(path, dpi=120)
    except OSError as err:
        raise InputError("path", f"cannot write {str(path)!r}: {err.strerror or err}") from None
    except ValueError as err:            # e.g. an extension matplotlib cannot write
        raise InputError("path", str(err)) from None
    return fig


def plot_pareto(curves: Mapping[str, Sequence[Mapping]], *, title: str | None = None,
                path: str | Path | None = None) -> Figure:
    """The trade-off between the cost bound alpha and the communication cost beta'mu*.

    Parameters
    ----------
    curves : mapping
        Label (``"tcp"``, ``"udp"`` or any text) to rows with keys ``"alpha"`` and
        ``"communication_cost"`` (as :func:`~packetloss_cvx.allocation.pareto_curve`
        returns); rows whose communication cost is None (infeasible) are left out.
    title : str, optional
    path : str or Path, optional
        Where to save the figure (the format follows the extension).

    Returns
    -------
    matplotlib.figure.Figure
        One line per label, in the order given. O(number of rows) to draw.

    Raises
    ------
    InputError
        Malformed rows or non-finite numbers (field ``curves[label][k]``), or a path that
        cannot be written (field ``path``).
    """
    if not isinstance(curves, Mapping) or not curves:
        raise InputError("curves", "expected a non-empty mapping label -> rows")
    fig = Figure(figsize=(5, 3.5))
    ax = fig.subplots()
    for label, rows in curves.items():
        field = f"curves[{label!r}]"
        kept = [r for r in _rows(rows, field, ("alpha", "communication_cost")) if r["communication_cost"] is not None]
        xy = numeric_array([[r["alpha"], r["communication_cost"]] for r in kept], field).reshape(-1, 2)
        ax.plot(xy[:, 0], xy[:, 1], marker="o", ms=3, label=_LABELS.get(label, str(label)))
    ax.set_xlabel(r"cost bound $\alpha$")
    ax.set_ylabel(r"communication cost $\beta^\top\mu^*$")
    if title:
        ax.set_title(title)
    ax.legend()
    fig.tight_layout()
    return _save(fig, path)


def plot_allocation_contours(axis: Sequence[float], costs: Any, allocations: Mapping[Any, Sequence[Mapping]],
                             levels: Sequence[float], *, title: str | None = None,
                             path: str | Path | None = None) -> Figure:
    """Figs. 6–7: log J*(mu) over [0, 1]^2, the contours J* = alpha and the optimal allocation
    on each contour for each price vector beta.

    Parameters
    ----------
    axis : sequence of float, shape (g,)
        Grid of mu1 and mu2, increasing (``cost_grid``'s first output).
    costs : array_like, shape (g, g)
        ``costs[j, i] = J*(axis[i], axis[j])``, positive (``cost_grid``'s second output).
    allocations : mapping
        beta (any label) to rows with key ``"mu"`` (a pair, or None when infeasible), as
        :func:`~packetloss_cvx.allocation.contour_allocations` returns.
    levels : sequence of float
        The cost bounds alpha drawn as contours.
    title : str, optional
    path : str or Path, optional
        Where to save the figure.

    Returns
    -------
    matplotlib.figure.Figure
        O(g^2) to contour the grid, plus the points.

    Raises
    ------
    InputError
        Shapes that do not match, non-finite or non-positive costs, malformed rows, or a
        path that cannot be written; the field is named.
    """
    grid = numeric_array(axis, "axis")
    if grid.ndim != 1 or grid.size < 2 or np.any(np.diff(grid) <= 0):
        raise InputError("axis", "expected an increasing 1-D sequence of at least 2 numbers")
    J = numeric_array(costs, "costs")
    if J.shape != (grid.size, grid.size):
        raise InputError("costs", f"expected shape ({grid.size}, {grid.size}) but found {J.shape}")
    if np.any(J <= 0):
        raise InputError("costs", "expected positive costs (their logarithm is drawn)")
    lv = np.sort(numeric_array(levels, "levels").ravel())
    if lv.size == 0:
        raise InputError("levels", "expected at least one cost bound")
    if not isinstance(allocations, Mapping):
        raise InputError("allocations", "expected a mapping beta -> rows")
    fig = Figure(figsize=(5, 4.5))
    ax = fig.subplots()
    ax.contourf(grid, grid, np.log(J), levels=30, cmap="viridis", alpha=0.6)
    if J.min() < lv.max() and lv.min() < J.max():     # contour() warns when no level is in range
        cs = ax.contour(grid, grid, J, levels=lv, colors="0.4", linewidths=0.8)
        ax.clabel(cs, fmt="%.3g", fontsize=7)
    for k, (beta, rows) in enumerate(allocations.items()):
        field = f"allocations[{beta!r}]"
        points = [r["mu"] for r in _rows(rows, field, ("mu",)) if r["mu"] is not None]
        if not points:
            continue
        pts = numeric_array(points, field)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise InputError(field, "expected each mu to be a pair (mu1, mu2)")
        ax.plot(pts[:, 0], pts[:, 1], marker=_MARKERS[k % len(_MARKERS)], ls="--", color="k", ms=5, lw=0.8,
                label=f"beta={beta}")
    ax.set_xlabel(r"$\mu_1$")
    ax.set_ylabel(r"$\mu_2$")
    if title:
        ax.set_title(title)
    if ax.lines:
        ax.legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, path)


def plot_closed_loop(curves: Mapping[str, Mapping[str, Any]], *, title: str | None = None,
                     path: str | Path | None = None) -> Figure:
    """Closed-loop runs: the mean of ||x_t|| with a band of one standard deviation, and the mean
    cumulative stage cost, one line per law.

    Parameters
    ----------
    curves : mapping
        Law (``"tcp"``, ``"udp"``, ``"dp"`` or any text) to a mapping with ``"state_norm_mean"`` and
        ``"state_norm_std"`` (length T + 1, t = 0..T) and ``"stage_cost_mean"`` (length T), as
        :class:`~packetloss_cvx.results.ClosedLoopRun` holds them. Non-finite values are not drawn.
    title : str, optional
    path : str or Path, optional

    Returns
    -------
    matplotlib.figure.Figure
        Two panels; O(laws T) to draw.

    Raises
    ------
    InputError
        Missing keys or mismatched lengths (field ``curves[law]``), or a path that cannot be written.
    """
    if not isinstance(curves, Mapping) or not curves:
        raise InputError("curves", "expected a non-empty mapping law -> curves")
    fig = Figure(figsize=(9, 3.5))
    left, right = fig.subplots(1, 2)
    labels = {**_LABELS, "dp": "DP optimum"}
    for law, data in curves.items():
        field = f"curves[{law!r}]"
        if not isinstance(data, Mapping) or any(k not in data for k in ("state_norm_mean", "state_norm_std",
                                                                         "stage_cost_mean")):
            raise InputError(field, "expected keys state_norm_mean, state_norm_std, stage_cost_mean")
        mean, std = np.asarray(data["state_norm_mean"], float), np.asarray(data["state_norm_std"], float)
        stage = np.asarray(data["stage_cost_mean"], float)
        if mean.shape != std.shape or mean.ndim != 1 or stage.shape != (mean.size - 1,):
            raise InputError(field, "expected T + 1 norms (mean and std) and T stage costs")
        t = np.arange(mean.size)
        line, = left.plot(t, mean, label=labels.get(law, str(law)))
        left.fill_between(t, np.maximum(mean - std, 0.0), mean + std, color=line.get_color(), alpha=0.2)
        right.plot(t[1:], np.cumsum(stage), color=line.get_color(), label=labels.get(law, str(law)))
    left.set_xlabel("step t")
    left.set_ylabel(r"$\|x_t\|$: mean $\pm$ one std")
    right.set_xlabel("step t")
    right.set_ylabel("mean cumulative stage cost")
    right.legend()
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)
