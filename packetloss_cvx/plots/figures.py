"""Matplotlib figures drawn from data that something else computed.

Each function takes data (for instance from [`packetloss_cvx.studies.allocation`][packetloss_cvx.studies.allocation]),
returns a `matplotlib.figure.Figure` and, when ``path`` is given, saves it there.
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
from matplotlib import colormaps
from matplotlib.colors import ListedColormap, LogNorm, Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle

from ..errors import InputError
from ..model.system import numeric_array
from ..safeio import save_figure
from .style import (
    LEGEND,
    OUTLINE,
    PATH_STYLES,
    callout_positions,
    contour_label_points,
    fit_width,
    set_log_ticks,
    tick_text,
)

__all__ = [
    "plot_ack_break_even", "plot_allocation_contours", "plot_burstiness_map", "plot_closed_loop", "plot_cost_lines",
    "plot_log_contour", "plot_mpc", "plot_pareto", "plot_power_pareto", "plot_region", "plot_sensor_map",
    "plot_stability_lines", "plot_strategy_map",
]

_LABELS = {"tcp": "TCP-like", "udp": "UDP-like"}


def _rows(rows: Any, field: str, keys: tuple[str, ...]) -> list[Mapping]:
    """``rows`` as dicts: a result of the package (an Allocation, a PowerAllocation) is read by its ``to_dict()``."""
    if not isinstance(rows, Sequence) or isinstance(rows, str):
        raise InputError(field, "expected a list of rows (dicts or the package's results)")
    rows = [row.to_dict() if not isinstance(row, Mapping) and callable(getattr(row, "to_dict", None)) else row
            for row in rows]
    for k, row in enumerate(rows):
        if not isinstance(row, Mapping) or any(key not in row for key in keys):
            raise InputError(f"{field}[{k}]", f"expected a dict with keys {', '.join(keys)}")
    return list(rows)


def _curves(curves: Any, x: str, y: str, *, skip_missing: bool) -> tuple[Figure, Any]:
    """A figure with one line of ``(row[x], row[y])`` per label of ``curves`` (label -> rows); rows whose ``y`` is
    None left out where ``skip_missing`` (an infeasible point), else an InputError like any other bad number."""
    if not isinstance(curves, Mapping) or not curves:
        raise InputError("curves", "expected a non-empty mapping label -> rows")
    fig = Figure(figsize=(6.4, 3.6), layout="constrained")
    ax = fig.subplots()
    for label, rows in curves.items():
        field = f"curves[{label!r}]"
        kept = [r for r in _rows(rows, field, (x, y)) if not (skip_missing and r[y] is None)]
        xy = numeric_array([[r[x], r[y]] for r in kept], field).reshape(-1, 2)
        ax.plot(xy[:, 0], xy[:, 1], marker="o", ms=3, label=_LABELS.get(label, str(label)))
    return fig, ax


def _save(fig: Figure, path: str | Path | None) -> Figure:
    """Saved atomically (safeio.save_figure); an existing file is replaced, as Matplotlib's savefig does: a
    figure is redrawn from its data (the command line refuses without --force, docs/design.md §4)."""
    if path is not None:
        save_figure(fig, path, overwrite=True)
    return fig


def plot_pareto(curves: Mapping[str, Sequence[Mapping]], *, title: str | None = None,
                path: str | Path | None = None) -> Figure:
    """The trade-off between the cost bound alpha and the communication cost beta'mu*.

    Parameters
    ----------
    curves : mapping
        Label (``"tcp"``, ``"udp"`` or any text) to rows with keys ``"alpha"`` and
        ``"communication_cost"`` (as [`pareto_curve`][packetloss_cvx.studies.allocation.pareto_curve]
        returns), or to `Allocation` results; rows whose communication cost is
        None (infeasible) are left out.
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

    Examples
    --------
    >>> rows = [{"alpha": 1.0, "communication_cost": 2.0}, {"alpha": 2.0, "communication_cost": None},
    ...         {"alpha": 3.0, "communication_cost": 0.5}]
    >>> line, = plot_pareto({"tcp": rows}).axes[0].lines       # the infeasible row is left out
    >>> line.get_xdata().tolist(), line.get_ydata().tolist()
    ([1.0, 3.0], [2.0, 0.5])
    """
    fig, ax = _curves(curves, "alpha", "communication_cost", skip_missing=True)
    ax.set_xlabel(r"cost bound $\alpha$")
    ax.set_ylabel(r"communication cost $\beta^\top\mu^*$")
    if title:
        ax.set_title(title)
    fig.legend(**LEGEND)
    return _save(fig, path)


def plot_allocation_contours(axis: Sequence[float], costs: Any, allocations: Mapping[Any, Sequence[Mapping]],
                             levels: Sequence[float], *, title: str | None = None,
                             path: str | Path | None = None) -> Figure:
    """Figs. 6–7: `J*(mu)` over [0, 1]^2 on a logarithmic colour scale, the contours `J*` = alpha and the optimal
    allocation on each contour for each price vector beta
    ([`plot_log_contour`][packetloss_cvx.plots.figures.plot_log_contour] draws it).

    Parameters
    ----------
    axis : sequence of float, shape (g,)
        Grid of mu1 and mu2, increasing (``cost_grid``'s first output).
    costs : array_like, shape (g, g)
        ``costs[j, i] = J*(axis[i], axis[j])``, positive (``cost_grid``'s second output).
    allocations : mapping
        beta (any label) to rows with key ``"mu"`` (a pair, or None when infeasible), as
        [`contour_allocations`][packetloss_cvx.studies.allocation.contour_allocations] returns.
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

    Examples
    --------
    >>> axis = [0.1, 0.5, 1.0]
    >>> costs = [[9.0, 6.0, 5.0], [6.0, 3.0, 2.0], [5.0, 2.0, 1.0]]     # falls as either mu rises
    >>> fig = plot_allocation_contours(axis, costs, {(1, 1): [{"mu": (0.5, 1.0)}, {"mu": None}]}, [2.0, 5.0])
    >>> [(line.get_xdata().tolist(), line.get_ydata().tolist()) for line in fig.axes[0].lines]
    [([0.5], [1.0])]
    """
    grid = numeric_array(axis, "axis")
    if grid.ndim != 1 or grid.size < 2 or np.any(np.diff(grid) <= 0):
        raise InputError("axis", "expected an increasing 1-D sequence of at least 2 numbers")
    J = numeric_array(costs, "costs")
    if J.shape != (grid.size, grid.size):
        raise InputError("costs", f"expected shape ({grid.size}, {grid.size}) but found {J.shape}")
    if np.any(J <= 0):
        raise InputError("costs", "expected positive costs (drawn on a logarithmic scale)")
    if numeric_array(levels, "levels").size == 0:
        raise InputError("levels", "expected at least one cost bound")
    if not isinstance(allocations, Mapping):
        raise InputError("allocations", "expected a mapping beta -> rows")
    lines = {f"beta={beta}": [r["mu"] for r in _rows(rows, f"allocations[{beta!r}]", ("mu",))]
             for beta, rows in allocations.items()}
    return plot_log_contour(grid, grid, J, colorbar_label=r"$J^*$, paper basis (log scale)", levels=levels,
                            allocations=lines, title=title, path=path)


def _norm_band(mean: np.ndarray, std: np.ndarray, yscale: str) -> tuple[np.ndarray, np.ndarray]:
    """The band of ||x_t|| drawn by `plot_closed_loop`: mean -+ std (clipped at 0) on a linear or symlog axis; on a
    log axis the geometric spread mean / g .. mean g with g = 1 + std / mean (upper side mean + std; not drawn where
    the mean is not positive). O(T).

    >>> lower, upper = _norm_band(np.array([0.5, 0.25]), np.array([1.0, 1.0]), "log")
    >>> lower.tolist(), upper.tolist()        # 0.25 / 1.5 and 0.0625 / 1.25, never down to 0
    ([0.16666666666666666, 0.05], [1.5, 1.25])
    """
    upper = mean + std
    if yscale != "log":
        return np.maximum(mean - std, 0.0), upper
    with np.errstate(divide="ignore", invalid="ignore"):
        lower = np.where(mean > 0, mean * mean / upper, np.nan)
    return lower, np.where(mean > 0, upper, np.nan)


def plot_closed_loop(curves: Any, *, yscale: str = "linear", title: str | None = None,
                     path: str | Path | None = None) -> Figure:
    """Closed-loop runs: the mean of ||x_t|| with a band of one standard deviation, and the mean
    cumulative stage cost, one line per law.

    Parameters
    ----------
    curves : Simulation or mapping
        A `Simulation` (its ``closed_loop`` runs), or law (``"tcp"``, ``"udp"``,
        ``"dp"`` or any text) to a `ClosedLoopRun` or to a mapping with
        ``"state_norm_mean"`` and ``"state_norm_std"`` (length T + 1, t = 0..T) and ``"stage_cost_mean"``
        (length T), as a ClosedLoopRun holds them. Non-finite values are not drawn.
    yscale : {"linear", "log", "symlog"}
        Both panels' y axes: "log" (or "symlog", which keeps zeros) so that a diverging law does not flatten
        the others. On "log" the band is the geometric spread mean x/÷ (1 + std / mean): its upper side is mean +
        std as on a linear axis, its lower side mean^2 / (mean + std), as far below the mean in log space (mean - std
        can be <= 0, which a log axis would draw down to its bottom edge, read as spread); the axis label says so.
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

    Examples
    --------
    >>> run = {"state_norm_mean": [1.0, 0.5, 0.25], "state_norm_std": [0.0, 0.1, 0.1], "stage_cost_mean": [2.0, 1.0]}
    >>> left, right = plot_closed_loop({"tcp": run}).axes
    >>> left.lines[0].get_ydata().tolist(), right.lines[0].get_ydata().tolist()    # right: the running sum
    ([1.0, 0.5, 0.25], [2.0, 3.0])
    """
    keys = ("state_norm_mean", "state_norm_std", "stage_cost_mean")
    if yscale not in ("linear", "log", "symlog"):
        raise InputError("yscale", f"expected linear, log or symlog, found {yscale!r}")
    curves = getattr(curves, "closed_loop", curves)       # a Simulation: its closed-loop runs
    if not isinstance(curves, Mapping) or not curves:
        raise InputError("curves", "expected a Simulation with closed-loop runs or a non-empty mapping law -> "
                                   "curves")
    fig = Figure(figsize=(10, 3.6), layout="constrained")
    left, right = fig.subplots(1, 2)
    labels = {**_LABELS, "dp": "DP optimum"}
    for law, data in curves.items():
        field = f"curves[{law!r}]"
        if not isinstance(data, Mapping) and all(hasattr(data, k) for k in keys):     # a ClosedLoopRun
            data = {k: getattr(data, k) for k in keys}
        if not isinstance(data, Mapping) or any(k not in data for k in ("state_norm_mean", "state_norm_std",
                                                                         "stage_cost_mean")):
            raise InputError(field, "expected keys state_norm_mean, state_norm_std, stage_cost_mean")
        mean, std = np.asarray(data["state_norm_mean"], float), np.asarray(data["state_norm_std"], float)
        stage = np.asarray(data["stage_cost_mean"], float)
        if mean.shape != std.shape or mean.ndim != 1 or stage.shape != (mean.size - 1,):
            raise InputError(field, "expected T + 1 norms (mean and std) and T stage costs")
        t = np.arange(mean.size)
        line, = left.plot(t, mean, label=labels.get(law, str(law)))
        left.fill_between(t, *_norm_band(mean, std, yscale), color=line.get_color(), alpha=0.2)
        right.plot(t[1:], np.cumsum(stage), color=line.get_color(), label=labels.get(law, str(law)))
    for panel in (left, right):
        panel.set_yscale(yscale)
    scale = {"linear": "", "log": " (log scale)", "symlog": " (symmetric log scale)"}[yscale]
    left.set_xlabel("step t")
    left.set_ylabel(rf"$\|x_t\|$: mean $\pm$ one std{scale}" if yscale != "log" else
                    "$\\|x_t\\|$ (log scale): mean,\n"
                    r"band mean $\times\!/\!\div$ (1 + std/mean)")
    right.set_xlabel("step t")
    right.set_ylabel(f"mean cumulative stage cost{scale}")
    fig.legend(handles=right.get_legend_handles_labels()[0], **LEGEND)
    if title:
        fig.suptitle(title)
    return _save(fig, path)


#: The constrained loop's controllers (montecarlo/mpc.py), in words.
_CONTROLLER_LABELS = {"clipped": "clipped LQ law", "certainty-equivalent": "certainty-equivalent MPC",
                      "expected-cost": "expected-cost MPC"}


def _linear_text(a: Sequence[float], bound: float) -> str:
    """``a'x > bound`` written out: ``([-1, 0], 0.05)`` -> "x1 < -0.05", ``([1, 2], 3)`` -> "x1+2x2 > 3"."""
    a = np.asarray(a, dtype=float)
    (nonzero,) = np.nonzero(a)
    if nonzero.size == 1:                                   # one state: its own bound
        j = int(nonzero[0])
        return f"x{j + 1} {'>' if a[j] > 0 else '<'} {bound / a[j]:g}"
    terms = []
    for j, c in enumerate(a):
        if c != 0.0:
            coef = "" if abs(c) == 1.0 else f"{abs(c):g}"
            terms.append(("-" if c < 0 else "+") + f"{coef}x{j + 1}")
    text = "".join(terms).lstrip("+") or "0"
    return f"{text} > {bound:g}"


def _row_words(name: str, constraints: Mapping[str, Any]) -> str:
    """What a violation row's event is, in the constraint's numbers, on two lines: ``x_max[0]`` -> "x1 > 2" over
    "(limit on E[x1])", ``chance[0]`` -> "x1 < -0.05" over "(chance row 1, eps 0.1)"."""
    kind, _, index = name.partition("[")
    i = int(index.rstrip("]")) if index else 0
    if kind in ("x_max", "x_min"):
        bound = constraints[kind][i]
        return f"x{i + 1} {'>' if kind == 'x_max' else '<'} {bound:g}\n(limit on E[x{i + 1}])"
    if kind == "F":
        return _linear_text(constraints["F"][i], constraints["g"][i]) + f"\n(polyhedron row {i + 1})"
    if kind == "chance":
        a, b, eps = constraints["chance"][i]
        return _linear_text(a, b) + f"\n(chance row {i + 1}, eps {eps:g})"
    return "hard program\ninfeasible" if kind == "infeasible" else name


def _limit_lines(ax: Any, constraints: Mapping[str, Any], index: int, lower: str, upper: str,
                 chance: bool = False) -> None:
    """Dashed lines at the finite bounds ``constraints[lower][index]``, ``constraints[upper][index]``; with
    ``chance``, dotted lines at the chance rows that bound this state alone (``a = c e_index``: ``b / c``)."""
    for key in (lower, upper):
        values = constraints.get(key)
        if values is not None and np.isfinite(values[index]):
            ax.axhline(values[index], color="black", linestyle="--", linewidth=1.0)
    for a, b, _eps in constraints.get("chance", []) if chance else []:
        a = np.asarray(a, dtype=float)
        others = np.delete(a, index)
        if a[index] != 0.0 and not others.any():
            ax.axhline(b / a[index], color="black", linestyle=":", linewidth=1.2)


def plot_mpc(sim: Any, *, protocol: str | None = None, state: int = 0, input: int = 0,
             measure: str = "worst-step", title: str | None = None, path: str | Path | None = None) -> Figure:
    """The constrained loop sampled (`simulate_mpc`): each controller's realised trajectories on the same sample
    paths, and how often each state-side constraint was violated, with its confidence interval.

    Top row: state ``x[state]`` of the kept runs, one panel per controller (the first run bold, the others thin),
    the limits on it dashed (the program puts them on the expected state) and the chance rows on this state alone
    dotted. Middle row: the input ``u[input]``, its bounds dashed: the input the actuator applied where the run kept
    it (``ControllerRun.applied``: under hold or buffer, where it differs from the command), else the commanded one
    (under zero the actuator applies it, or zero on a loss); the axis says which. Steps where the first run's packet
    on that channel was lost are shaded grey in both rows. Bottom: per state-side row (state limits, polyhedron rows,
    chance rows) and the program's infeasibility, each controller's frequency with its Wilson interval; a chance
    row's allowed eps is marked ``|``. Input and rate bounds are not drawn there: every controller holds them on
    what it commands (under hold or buffer their rows count the applied inputs: read them from ``violations``).

    Parameters
    ----------
    sim : MPCSimulation
        Run with ``keep >= 1`` (the trajectories drawn).
    protocol : {"tcp", "udp"}, optional
        Whose controllers (default: the first run).
    state, input : int
        The state and the input channel drawn (0-based).
    measure : {"worst-step", "runs"}
        The frequency drawn: at the step with the most violations (a chance row's eps is a bound at each step), or
        of the runs with a violation at some step.
    title : str, optional
        The figure's title; default: the protocol, the channel, the actuator's strategy (unless zero) and the runs,
        in words.
    path : str or Path, optional

    Returns
    -------
    matplotlib.figure.Figure
        Two panels per controller and one of the frequencies; O(controllers keep steps + rows) to draw.

    Raises
    ------
    InputError
        Field ``protocol`` (not run), ``keep`` (no trajectory kept), ``state``/``input`` (out of range) or
        ``measure``.

    Examples
    --------
    >>> from packetloss_cvx import System, Constraints
    >>> from packetloss_cvx.montecarlo.mpc import simulate_mpc
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> sim = simulate_mpc(s, Constraints(u_min=[-0.3], u_max=[0.3], x_max=[2.0]), samples=3, steps=2, keep=2,
    ...                    protocols=["tcp"])
    >>> fig = plot_mpc(sim)
    >>> len(fig.axes), fig.axes[0].get_title()
    (7, 'clipped LQ law')
    """
    runs = getattr(sim, "runs", None)
    if not isinstance(runs, Mapping) or not runs:
        raise InputError("sim", "expected an MPCSimulation (simulate_mpc's result)")
    protocol = next(iter(runs)) if protocol is None else protocol
    if protocol not in runs:
        raise InputError("protocol", f"expected one of {', '.join(runs)} (the protocols run), found {protocol!r}")
    if measure not in ("worst-step", "runs"):
        raise InputError("measure", f"expected worst-step or runs, found {measure!r}")
    controllers = runs[protocol]
    delivered = getattr(sim, "delivered", None)
    if delivered is None or any(run.states is None for run in controllers.values()):
        raise InputError("keep", "expected trajectories: run simulate_mpc with keep >= 1")
    first = next(iter(controllers.values()))
    n, m = first.states.shape[2], first.inputs.shape[2]
    if not 0 <= state < n:
        raise InputError("state", f"expected an index in 0..{n - 1}, found {state}")
    if not 0 <= input < m:
        raise InputError("input", f"expected an index in 0..{m - 1}, found {input}")
    names = list(controllers)
    fig = Figure(figsize=(11, 8.4), layout="constrained")
    axes = fig.subplot_mosaic([[f"x{k}" for k in range(len(names))], [f"u{k}" for k in range(len(names))],
                               ["rates"] * len(names)], height_ratios=[1.0, 0.8, 1.0])
    constraints = getattr(sim, "constraints", {}) or {}
    lost = np.flatnonzero(~np.asarray(delivered[0, :, input], dtype=bool))
    first_which = "commanded" if first.applied is None else "applied"
    for k, name in enumerate(names):
        run, colour = controllers[name], f"C{k}"
        top, bottom = axes[f"x{k}"], axes[f"u{k}"]
        steps = run.inputs.shape[1]
        inputs, which = (run.inputs, "commanded") if run.applied is None else (run.applied, "applied")
        for j in range(run.states.shape[0] - 1, -1, -1):        # the first run last: on top
            bold = {"linewidth": 2.0, "alpha": 1.0} if j == 0 else {"linewidth": 0.8, "alpha": 0.35}
            top.plot(np.arange(steps + 1), run.states[j, :, state], color=colour, **bold)
            bottom.step(np.arange(steps), inputs[j, :, input], where="post", color=colour, **bold)
        for t in lost:
            for ax in (top, bottom):
                ax.axvspan(t, t + 1, color="0.85", zorder=0, linewidth=0)
        _limit_lines(top, constraints, state, "x_min", "x_max", chance=True)
        _limit_lines(bottom, constraints, input, "u_min", "u_max")
        top.set_title(_CONTROLLER_LABELS.get(name, name), fontsize="medium")
        top.set_ylabel(f"state $x_{{{state + 1}}}$" if k == 0 else "")
        bottom.set_ylabel(f"{which} $u_{{{input + 1}}}$" if k == 0 or which != first_which else "")
        bottom.set_xlabel("step t")
        if k:
            top.sharey(axes["x0"])
            bottom.sharey(axes["u0"])
    rates = axes["rates"]
    shown = [v.name for v in first.violations if v.name.split("[")[0] in ("x_max", "x_min", "F", "chance")]
    rows = [*shown, "infeasible"]
    width = 0.8 / len(names)
    for k, name in enumerate(names):
        run, labelled = controllers[name], False
        for i, row in enumerate(rows):
            f = run.infeasible if row == "infeasible" else run.violation(row)
            if f is None:                                       # the clipped law solves nothing
                continue
            value, (lo, hi) = (f.worst_frequency, f.worst_ci) if measure == "worst-step" else \
                (f.runs_with / f.runs, f.runs_ci)
            y = i - 0.4 + width * (k + 0.5)
            rates.errorbar(value, y, xerr=[[max(value - lo, 0.0)], [max(hi - value, 0.0)]], fmt="o", color=f"C{k}",
                           capsize=3, label=None if labelled else _CONTROLLER_LABELS.get(name, name))
            labelled = True
            if f.allowed > 0 and k == 0:
                first_allowed = not any(line.get_label() == "allowed eps" for line in rates.lines)
                rates.plot([f.allowed], [i], marker="|", markersize=18, color="black", linestyle="none",
                           label="allowed eps" if first_allowed else None)
    rates.set_yticks(range(len(rows)), [_row_words(r, constraints) for r in rows])
    rates.invert_yaxis()
    rates.set_xlim(-0.02, 1.02)
    rates.set_xlabel("frequency at the worst step" if measure == "worst-step" else "fraction of runs with a violation")
    level = int(round(100 * first.violations[0].confidence)) if first.violations else 95
    runs_count = getattr(sim, "samples", first.infeasible.runs if first.infeasible else 0)
    rates.set_title(("Violations at the worst step" if measure == "worst-step" else "Runs with some violation")
                    + f" over {runs_count} runs, with {level} % Wilson intervals")
    handles, labels = rates.get_legend_handles_labels()
    handles.append(Patch(color="0.85", label="packet lost (first run)"))
    handles.append(Line2D([], [], color="black", linestyle="--", label="limit on the expected state / input bound"))
    if constraints.get("chance"):
        handles.append(Line2D([], [], color="black", linestyle=":", label="chance row's threshold"))
    fig.legend(handles=handles, **LEGEND)
    channel = {"bernoulli": "Bernoulli", "gilbert-elliott": "Gilbert–Elliott", "markov": "Markov"}.get(
        getattr(sim, "channel", ""), "")
    actuator = getattr(sim, "actuator", "zero")
    on_loss = "" if actuator == "zero" else f", actuator {actuator}"
    fig.suptitle(title or f"{_LABELS.get(protocol, protocol)} controllers over a {channel} link{on_loss}: "
                          f"{first.states.shape[0]} of {runs_count} runs drawn")
    return _save(fig, path)


def plot_cost_lines(x: Sequence[float], curves: Mapping[str, Any], *, xlabel: str, log: bool = True,
                    xscale: str = "linear", marker: float | None = None, marker_label: str | None = None,
                    title: str | None = None, path: str | Path | None = None) -> Figure:
    """Costs against one swept quantity (Fig. log-cost-pendulum and 1-D sweeps).

    Parameters
    ----------
    x : sequence of float, shape (points,)
        The swept values (nu, mu_i, an x0 scale, horizons).
    curves : mapping
        Label (``"tcp"``, ``"udp"``, ``"diff"`` or any text) to values of shape (points,).
    xlabel : str
    log : bool
        Draw the values on a logarithmic y axis; values <= 0 (J_Delta where every mu_i is 0 or 1) are not on
        it: left out, and the curve's legend entry says how many.
    xscale : {"linear", "log"}
    marker : float, optional
        An x to mark with a vertical dotted line (e.g. the maximiser of J_Delta), labelled ``marker_label``.
    title : str, optional
    path : str or Path, optional

    Returns
    -------
    matplotlib.figure.Figure
        The legend beside the axes. O(points) per curve.

    Raises
    ------
    InputError
        Shapes that do not match or non-finite numbers (the field named), an unwritable path.

    Examples
    --------
    >>> fig = plot_cost_lines([0.1, 0.5, 0.9], {"tcp": [1.0, 20.0, 0.0]}, xlabel="nu", marker=0.5)
    >>> line = fig.axes[0].lines[0]                       # the values on a log axis; 0 is not on it
    >>> line.get_ydata()[:2].tolist(), bool(np.isnan(line.get_ydata()[2])), fig.axes[0].get_yscale()
    ([1.0, 20.0], True, 'log')
    >>> line.get_label()
    'TCP-like $J^*$ (paper) (1 point <= 0: off the log axis)'
    """
    xs = numeric_array(x, "x")
    if xs.ndim != 1 or xs.size < 1:
        raise InputError("x", "expected a non-empty 1-D sequence")
    if not isinstance(curves, Mapping) or not curves:
        raise InputError("curves", "expected a non-empty mapping label -> values")
    fig = Figure(figsize=(7.4, 3.8), layout="constrained")
    ax = fig.subplots()
    names = {"tcp": "TCP-like $J^*$ (paper)", "udp": "UDP-like $J^*$ (paper = attainable)",
             "diff": r"$J_\Delta = J^*_{udp} - J^*_{tcp}$ (paper)"}
    for label, values in curves.items():
        ys = numeric_array(values, f"curves[{label!r}]")
        if ys.shape != xs.shape:
            raise InputError(f"curves[{label!r}]", f"expected shape {xs.shape} but found {ys.shape}")
        text = names.get(label, str(label))
        dropped = int(np.sum(ys <= 0)) if log else 0
        if dropped:
            text += f" ({dropped} point{'s' if dropped > 1 else ''} <= 0: off the log axis)"
            ys = np.where(ys > 0, ys, np.nan)
        ax.plot(xs, ys, ls="--" if label == "diff" else "-", lw=1.6, label=text)
    if marker is not None:
        ax.axvline(marker, color="k", ls=":", lw=1.2, label=marker_label)
    ax.set_xscale(xscale)
    if log:
        ax.set_yscale("log")
        shown = np.concatenate([line.get_ydata() for line in ax.lines if line.get_label() != marker_label])
        shown = shown[np.isfinite(shown) & (shown > 0)]
        if shown.size:
            set_log_ticks(ax.yaxis, shown.min(), shown.max())
    ax.set_xlabel(xlabel)
    ax.set_ylabel("expected cost (log scale)" if log else "expected cost")
    if title:                # over the whole figure: the legend beside the axes leaves them narrower than it
        fig.suptitle(title, fontsize=9)
    fig.legend(**LEGEND)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def plot_log_contour(axis_x: Sequence[float], axis_y: Sequence[float], values: Any, *, xlabel: str = r"$\mu_1$",
                     ylabel: str = r"$\mu_2$", colorbar_label: str = "expected cost (log scale)",
                     marker: Sequence[float] | None = None, levels: Sequence[float] | None = None,
                     allocations: Mapping[Any, Sequence[Sequence[float] | None]] | None = None,
                     breaks: Mapping[Any, Sequence[int]] | None = None,
                     title: str | None = None, path: str | Path | None = None) -> Figure:
    """A positive quantity over a 2-D grid on a logarithmic colour scale (``LogNorm``; the colour bar is
    ticked in the values themselves), for Figs. cost-diff-mixed, TCP-/UDP-log-cost-mixed and, with
    ``levels`` and ``allocations``, their ``-mult`` variants.

    Parameters
    ----------
    axis_x, axis_y : sequence of float, shapes (gx,), (gy,)
        Increasing grid values.
    values : array_like, shape (gy, gx)
        ``values[j, i]`` at ``(axis_x[i], axis_y[j])``. The colour scale spans the positive values (from
        their 2nd percentile when they span more than four decades, so that a few near-zero values, J_Delta
        at the corners, do not flatten it); values below it, 0 included (J_Delta = 0 where every mu_i is 0
        or 1), are drawn in its lowest colour (the colour bar's arrow; a legend entry says so).
    marker : pair, optional
        A point marked with a white cross edged in black, never clipped by the axes (the maximiser of J_Delta).
    levels : sequence of float, optional
        Values drawn as contour lines (the cost bounds alpha), each labelled once where the label has room
        (no label collides with another or sits on another line); the legend lists them all.
    allocations : mapping, optional
        Label (e.g. beta) to points (pairs, or None where there is none): each a bright line outlined in
        black through its points (the paper's eq:opt_M lines), the axes reaching a margin beyond the grid so
        that points on mu = 0 or 1 are drawn whole, off the frame. With one point per level (in the order of
        ``levels``), each marker's level is written beside it where its contour carries no label of its own.
    breaks : mapping, optional
        Label to the steps k at which the path's line is broken between its points k and k + 1: where the
        optimum jumps instead of sliding
        ([`path_jumps`][packetloss_cvx.studies.paper_figures.path_jumps] finds them), so that no straight
        segment is drawn where no optimum lies.
    title : str, optional
    path : str or Path, optional

    Returns
    -------
    matplotlib.figure.Figure
        The map, its colour bar and the legend beside them. O(gx gy) to contour the grid, O(L V^2) to place
        the labels of L levels of V vertices.

    Raises
    ------
    InputError
        Shapes that do not match, non-finite numbers, no positive value, malformed points, an unwritable path.

    Examples
    --------
    >>> fig = plot_log_contour([0.0, 1.0], [0.0, 0.5, 1.0], [[1.0, 10.0], [10.0, 100.0], [100.0, 1000.0]],
    ...                        marker=(0.5, 0.5))
    >>> ax, bar = fig.axes           # a log colour scale over the values: 1 to 1000
    >>> norm = ax.collections[0].norm
    >>> type(norm).__name__, norm.vmin, norm.vmax, ax.lines[0].get_xydata().tolist()
    ('LogNorm', 1.0, 1000.0, [[0.5, 0.5]])
    """
    gx, gy = numeric_array(axis_x, "axis_x"), numeric_array(axis_y, "axis_y")
    for name, g in (("axis_x", gx), ("axis_y", gy)):
        if g.ndim != 1 or g.size < 2 or np.any(np.diff(g) <= 0):
            raise InputError(name, "expected an increasing 1-D sequence of at least 2 numbers")
    raw = numeric_array(values, "values")
    if raw.shape != (gy.size, gx.size):
        raise InputError("values", f"expected shape ({gy.size}, {gx.size}) but found {raw.shape}")
    positive = raw[raw > 0]
    if not positive.size:
        raise InputError("values", "expected some positive values (drawn on a logarithmic scale)")
    lo, hi = float(positive.min()), float(positive.max())
    if hi > 1e4 * lo:                    # a few near-zero values (J_Delta at the corners) must not flatten the rest
        lo = float(np.percentile(positive, 2))
    if hi <= lo * (1 + 1e-9):
        lo, hi = lo / 2, hi * 2                                          # one value: one colour
    fig = Figure(figsize=(7.9, 5.0), layout="constrained")
    ax = fig.subplots()
    ax.set_box_aspect(1)
    # points on mu = 0 or 1 are drawn whole inside the frame: the axes reach a margin beyond the grid, whose own
    # edge is outlined (the map covers the grid only)
    pad = 0.03 if (marker is not None or allocations) else 0.0
    span_x, span_y = gx[-1] - gx[0], gy[-1] - gy[0]
    ax.set_xlim(gx[0] - pad * span_x, gx[-1] + pad * span_x)
    ax.set_ylim(gy[0] - pad * span_y, gy[-1] + pad * span_y)
    if pad:
        ax.add_patch(Rectangle((gx[0], gy[0]), span_x, span_y, fill=False, lw=0.8, ec="0.3", zorder=3))
    below = raw < lo
    filled = ax.contourf(gx, gy, np.where(raw > 0, raw, lo / 10), levels=np.geomspace(lo, hi, 31),
                         norm=LogNorm(lo, hi), cmap="viridis", extend="min" if below.any() else "neither")
    set_log_ticks(fig.colorbar(filled, ax=ax, label=colorbar_label), lo, hi)
    extra: list[Any] = []
    if below.any():
        zero = ", 0 included" if np.any(raw <= 0) else ""
        extra.append(Patch(color=filled.cmap(0.0), label=f"< {lo:.3g}{zero}"))
    lv = np.sort(numeric_array(levels, "levels").ravel()) if levels is not None else np.empty(0)
    inside = lv[(lv > np.min(raw)) & (lv < np.max(raw))]
    cs = ax.contour(gx, gy, raw, levels=inside, colors="0.93", linewidths=0.7) if inside.size else None
    order = numeric_array(levels, "levels").ravel() if levels is not None else np.empty(0)
    marked: list[tuple[float, np.ndarray]] = []       # (level, point) of every marker on a contour
    broken = False
    for k, (label, points) in enumerate((allocations or {}).items()):
        if not any(p is not None for p in points):
            continue
        rows = [np.full(2, np.nan) if p is None else numeric_array(p, f"allocations[{label!r}]") for p in points]
        if any(r.shape != (2,) for r in rows):
            raise InputError(f"allocations[{label!r}]", "expected points as pairs (mu1, mu2)")
        pts = np.array(rows)
        if len(pts) == order.size:         # one point per level, as contour_allocations returns them
            marked += [(float(a), p) for a, p in zip(order, pts, strict=True) if np.all(np.isfinite(p))]
        cut = sorted({int(step) + 1 for step in (breaks or {}).get(label, ()) if 0 <= int(step) < len(pts) - 1})
        if cut:                           # where the optimum jumps: no straight segment
            broken = True
        # a point without an optimum (None) is left out; a jump becomes a nan row, which breaks the line
        pieces = np.split(pts, cut)
        pts = np.vstack([np.vstack([piece[np.all(np.isfinite(piece), axis=1)], np.full((1, 2), np.nan)])
                         for piece in pieces])
        shown = np.flatnonzero(np.all(np.isfinite(pts), axis=1))
        pts = pts[shown[0]:shown[-1] + 1] if shown.size else pts[:0]
        colour, dashes, mark = PATH_STYLES[k % len(PATH_STYLES)]
        ax.plot(pts[:, 0], pts[:, 1], color=colour, ls=dashes, lw=1.5, marker=mark, ms=4.5, mec="k", mew=0.6,
                path_effects=OUTLINE, clip_on=False, zorder=4, label=str(label))
    if marker is not None:
        point = numeric_array(marker, "marker").ravel()
        ax.plot([point[0]], [point[1]], marker="X", color="w", mec="k", mew=1.3, ms=12, ls="none",
                clip_on=False, zorder=5, label="maximiser")
    if cs is not None:
        names = [tick_text(a) for a in inside]
        rows_text = [", ".join(names[k:k + 5]) for k in range(0, len(names), 5)]
        extra.append(Line2D([], [], color="0.55", lw=0.9, label="contours $\\alpha$:\n" + ",\n".join(rows_text)))
        if marked:
            extra.append(Line2D([], [], ls="none", marker="o", mfc="none", mec="0.3", ms=5,
                                label="each marker: the optimum\non the contour $\\alpha$ through it"))
    if broken:
        extra.append(Line2D([], [], ls="none", label="a path is broken\nwhere the optimum jumps"))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:                # over the whole figure: the legend beside the axes leaves them narrower than it
        fig.suptitle(title, fontsize=9)
    handles = ax.get_legend_handles_labels()[0] + extra
    if handles:
        fig.legend(handles=handles, **LEGEND)
    fit_width(fig)                        # laid out: the labels below are sized in the axes' own points
    if cs is not None:
        _label_levels(ax, cs, marked)
    return _save(fig, path)


def _label_levels(ax: Any, cs: Any, marked: list[tuple[float, np.ndarray]]) -> None:
    """Each contour level labelled once: on its line where there is room (contour_label_points); a level
    crowded there (the high alphas packed into a corner) is written in the nearest free spot and joined by a
    thin leader to one of its markers (the optimum on that contour) or else to its line. The figure is laid out
    (its axes' size in points sizes the labels' boxes). O(L V^2)."""
    drawn = [line.get_xydata() for line in ax.lines]
    chosen, points = contour_label_points(ax, cs, drawn)
    if chosen:
        ax.clabel(cs, levels=chosen, manual=points, inline=True, fmt=tick_text, fontsize=7.5)
    rest = [float(a) for a in cs.levels if float(a) not in chosen]
    if not rest:
        return
    to_frac = ax.transData + ax.transAxes.inverted()
    bbox = ax.get_window_extent()
    scale = ax.figure.dpi / 72.0
    # the labels on the lines, as contour_label_points counts them: 0.13 wide and 0.06 tall around their points
    boxes = [[x - 0.065, y - 0.03, x + 0.065, y + 0.03] for x, y in (to_frac.transform(points) if points else [])]
    obstacles = [to_frac.transform(np.reshape(p, (-1, 2))) for p in drawn if len(p)]
    dense = [np.vstack([a + t * (b - a) for a, b in zip(pts[:-1], pts[1:], strict=True)
                        for t in np.linspace(0, 1, 30)]) if len(pts) > 1 else pts for pts in obstacles]
    dense = [d[np.all(np.isfinite(d), axis=1)] for d in dense]
    anchors, sizes = [], []
    paths = dict(zip((float(a) for a in cs.levels), cs.get_paths(), strict=True))
    for level in rest:
        on = [p for a, p in marked if a == level]
        if on:
            anchor = to_frac.transform(on[0][None])[0]
        else:
            verts = to_frac.transform(paths[level].vertices)
            verts = verts[np.all((verts > 0.03) & (verts < 0.97), axis=1)]
            if not verts.size:
                continue
            anchor = verts[len(verts) // 2]
        anchors.append((level, anchor))
        width = (0.62 * 7.5 * len(tick_text(level)) + 6) * scale / bbox.width
        sizes.append((width, (7.5 * 1.5 + 4) * scale / bbox.height))
    spots = callout_positions([a for _, a in anchors], sizes, np.vstack([*dense, np.empty((0, 2))]), boxes)
    for (level, anchor), spot in zip(anchors, spots, strict=True):
        if spot is None:
            continue
        ax.annotate(tick_text(level), xy=anchor, xycoords="axes fraction", xytext=spot, textcoords="axes fraction",
                    ha="center", va="center", fontsize=7.5, color="0.1", zorder=6,
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "0.5", "lw": 0.5, "alpha": 0.85},
                    arrowprops={"arrowstyle": "-", "color": "0.93", "lw": 0.7, "shrinkA": 0, "shrinkB": 2})


def plot_burstiness_map(rates: Any, correlations: Sequence[float] | None = None, cost: Any = None,
                        loss_percent: Any = None, *, protocol: str | None = None,
                        cost_label: str = "exact minimum (log scale)", title: str | None = None,
                        path: str | Path | None = None) -> Figure:
    """A (mean rate × burstiness) map of one channel in two panels: ``cost`` (the exact minimum) on a logarithmic
    colour scale (``LogNorm``, ticked in the values) and ``loss_percent`` (the plug-in law's loss, in %) on a
    linear one from its least to its largest value (0 to 1 when it is constant: no loss). Each grid point is one
    cell (``pcolormesh``, nearest), burstiness lambda across, mean rate up; the axes may come in any order (they
    are sorted for drawing). O(R L).

    Parameters
    ----------
    rates, correlations : sequence of float, shapes (R,), (L,)
        Distinct mean rates and values of lambda = 1 - p - r. ``rates`` may be a
        `BurstinessMap` alone: its axes, ``protocol``'s exact minimum (default
        UDP-like where evaluated, else the first) and the plug-in law's loss in percent.
    cost, loss_percent : array_like, shape (R, L)
        ``[a, b]`` at ``(rates[a], correlations[b])``; ``cost`` needs a positive value (cells <= 0 are drawn in
        the lowest colour), ``loss_percent`` finite.
    cost_label, title : str, optional
    path : str or Path, optional

    Raises
    ------
    InputError
        Shapes that do not match, repeated or non-finite axis values, non-finite numbers, no positive cost.

    Examples
    --------
    >>> fig = plot_burstiness_map([0.5, 0.9], [0.0, 0.5, 0.9], [[4.0, 8.0, 20.0], [2.0, 3.0, 9.0]],
    ...                           [[0.0, 1.0, 9.0], [0.0, 0.5, 5.0]])
    >>> cost_axis, loss_axis = fig.axes[0], fig.axes[1]
    >>> norm = cost_axis.collections[0].norm
    >>> type(norm).__name__, norm.vmin, norm.vmax, loss_axis.collections[0].norm.vmax
    ('LogNorm', 2.0, 20.0, 9.0)
    """
    if hasattr(rates, "relative_loss") and hasattr(rates, "exact"):          # a BurstinessMap
        grid = rates
        protocol = protocol or ("udp" if "udp" in grid.exact else next(iter(grid.exact)))
        if protocol not in grid.exact:
            raise InputError("protocol", f"expected one of {', '.join(grid.exact)}, found {protocol!r}")
        rates, correlations = grid.rate, grid.correlation
        cost, loss_percent = grid.exact[protocol], 100.0 * grid.relative_loss(protocol)
    if correlations is None or cost is None or loss_percent is None:
        raise InputError("correlations" if correlations is None else "cost" if cost is None else "loss_percent",
                         "expected the correlations, the cost and the loss beside the rates (or a BurstinessMap)")
    gy, gx = numeric_array(rates, "rates"), numeric_array(correlations, "correlations")
    for name, g in (("rates", gy), ("correlations", gx)):
        if g.ndim != 1 or g.size < 2 or np.unique(g).size != g.size:
            raise InputError(name, "expected at least 2 distinct numbers")
    values = {}
    for name, raw in (("cost", cost), ("loss_percent", loss_percent)):
        arr = numeric_array(raw, name)
        if arr.shape != (gy.size, gx.size):
            raise InputError(name, f"expected shape ({gy.size}, {gx.size}) but found {arr.shape}")
        values[name] = arr[np.argsort(gy)][:, np.argsort(gx)]
    gy, gx = np.sort(gy), np.sort(gx)
    positive = values["cost"][values["cost"] > 0]
    if not positive.size:
        raise InputError("cost", "expected some positive values (drawn on a logarithmic scale)")
    lo, hi = float(positive.min()), float(positive.max())
    if hi <= lo * (1 + 1e-9):
        lo, hi = lo / 2, hi * 2                                          # one value: one colour
    fig = Figure(figsize=(10.5, 4.6), layout="constrained")
    left, right = fig.subplots(1, 2)
    mesh = left.pcolormesh(gx, gy, np.where(values["cost"] > 0, values["cost"], lo), shading="nearest",
                           norm=LogNorm(lo, hi), cmap="viridis")
    set_log_ticks(fig.colorbar(mesh, ax=left, label=cost_label), lo, hi)
    loss = values["loss_percent"]
    low, high = float(loss.min()), float(loss.max())
    if high - low <= 1e-9 * max(1.0, abs(high)):
        low, high = min(low, 0.0), max(high, 0.0) + 1.0                 # no loss anywhere: one colour
    shaded = right.pcolormesh(gx, gy, loss, shading="nearest", vmin=low, vmax=high, cmap="magma")
    fig.colorbar(shaded, ax=right, label="plug-in law's loss (%, linear scale)")
    for ax in (left, right):
        ax.set(xlabel=r"burstiness $\lambda = 1 - p - r$", ylabel=r"mean delivery rate $\mu$")
    if title:
        fig.suptitle(title, fontsize=9)
    return _save(fig, path)


def plot_region(axis: Any, radius: Any = None, stable: Mapping[str, Any] | None = None, *,
                xlabel: str | None = None, ylabel: str | None = None, title: str | None = None,
                radius_label: str | None = None, path: str | Path | None = None) -> Figure:
    """Stability regions over two channels: ``radius`` (the least mean-square radius any linear law reaches,
    min_K rho(L_K), shape (K, K), rows the second channel) filled on a diverging colour scale centred at 1 that
    spans the data (blue stable, red not), its level 1 drawn as the boundary of the stabilisable set (interpolated
    between grid points, so a coarse grid gives a smooth line), each region named on the map, and each law's
    region boundary: the level 1 of its own radius where ``radius`` is a mapping law -> grid, else the 1/2 level
    of its 0/1 ``stable`` map (nan undecided). ``axis`` may be a `RegionMap` with a grid, alone: its axis, every
    law's radius (the colours: its "dp" law's), every law's ``stable`` map and its channels' names (``xlabel`` and
    ``ylabel`` default to them; else to mu_1, mu_2). ``radius_label``: the colour bar's words when the colours
    are one law's own radius rather than the least one (``radius`` a mapping without "dp": its first law's);
    the region above 1 is then "not stable" rather than "not stabilisable". O(K^2) per law.

    Raises
    ------
    InputError
        A RegionMap without a grid or without the "dp" law (field ``region``); the arrays' shapes (the field
        named); ``radius`` or ``stable`` missing beside a plain axis.

    Examples
    --------
    >>> axis = [0.0, 0.5, 1.0]
    >>> radius = [[2.0, 1.5, 1.0], [1.5, 1.0, 0.5], [1.0, 0.5, 0.2]]
    >>> fig = plot_region(axis, radius, {"dp": [[0, 0, 0], [0, 0, 1], [0, 1, 1]]})
    >>> len(fig.axes), fig.axes[0].get_xlabel()     # the map and its colour bar
    (2, '$\\\\mu_1$')
    >>> filled = fig.axes[0].collections[0]          # the colour scale spans the data, white at radius 1
    >>> float(filled.norm.vmin), float(filled.norm.vmax), bool(min(filled.cmap(filled.norm(1.0))[:3]) > 0.9)
    (0.2, 2.0, True)
    """
    names = (r"$\mu_1$", r"$\mu_2$")
    if hasattr(axis, "laws") and hasattr(axis, "channels"):        # a RegionMap
        region = axis
        if region.stable is None or "dp" not in region.laws:
            raise InputError("region", "expected a RegionMap with a grid and the 'dp' law (region_map(..., "
                                       "grid=K, laws=[\"dp\", ...])): the colours are the dp law's least radius")
        axis = region.axis
        radius = dict(zip(region.laws, region.radius, strict=True)) if radius is None else radius
        stable = dict(zip(region.laws, region.stable, strict=True)) if stable is None else stable
        names = tuple(rf"$\mu_{c + 1}$" if c < 9 else rf"$\mu_{{{c + 1}}}$" for c in region.channels)
    if radius is None or stable is None:
        raise InputError("radius" if radius is None else "stable", "expected the radius grid and the stable maps "
                                                                  "beside the axis (or a RegionMap alone)")
    xlabel, ylabel = names[0] if xlabel is None else xlabel, names[1] if ylabel is None else ylabel
    g = numeric_array(axis, "axis")
    if g.ndim != 1 or g.size < 2 or np.any(np.diff(g) <= 0):
        raise InputError("axis", "expected an increasing 1-D sequence of at least 2 numbers")
    radii = {str(k): np.asarray(v, dtype=float) for k, v in radius.items()} if isinstance(radius, Mapping) else {}
    if isinstance(radius, Mapping) and not radii:
        raise InputError("radius", "expected at least one law's radius grid")
    least = not radii or "dp" in radii           # the colours: the least radius (dp), else the first law's own
    r = radii.get("dp", next(iter(radii.values()))) if radii else np.asarray(radius, dtype=float)
    if radius_label is None:
        radius_label = (r"least mean-square radius $\min_K \rho(\mathcal{L}_K)$" if least
                        else f"mean-square radius of the {next(iter(radii))} law")
    for law, v in {**radii, "": r}.items():
        if v.shape != (g.size, g.size):
            raise InputError(f"radius[{law!r}]" if law else "radius",
                             f"expected shape ({g.size}, {g.size}) but found {v.shape}")
    fig = Figure(figsize=(9.5, 5.0), layout="constrained")     # narrowed to what it draws below (fit_width)
    ax = fig.add_subplot()
    ax.set_box_aspect(1)
    finite = r[np.isfinite(r)]
    handles: list[Any] = []
    crosses = finite.size and finite.min() < 1.0 < finite.max()
    if finite.size:
        lo, hi = float(finite.min()), float(finite.max())
        lo, hi = min(lo, 1.0 - 1e-3), max(hi, 1.0 + 1e-3)            # 1 inside the scale: the colours read stable
        # blue below 1, red above, white at 1, each side stretched over its own range: a linear scale that fits
        # the data and still reads stable / not stable
        values = np.linspace(lo, hi, 256)
        shade = np.where(values < 1.0, 0.5 * (values - lo) / (1.0 - lo), 0.5 + 0.5 * (values - 1.0) / (hi - 1.0))
        cmap = ListedColormap(colormaps["RdBu_r"](shade))
        levels = np.unique(np.concatenate([np.linspace(lo, 1.0, 13), np.linspace(1.0, hi, 13)]))
        filled = ax.contourf(g, g, np.ma.masked_invalid(r), levels=levels, norm=Normalize(lo, hi), cmap=cmap)
        bar = fig.colorbar(filled, ax=ax, spacing="proportional", label=radius_label)
        bar.set_ticks(np.unique(np.round(np.concatenate([np.linspace(lo, 1.0, 5), np.linspace(1.0, hi, 3)]), 3)))
    if np.any(~np.isfinite(r)):
        handles.append(Patch(facecolor="white", edgecolor="0.5", label="radius not computed"))
    styles = ["-", "--", ":", "-."]
    colors = ["black", "tab:orange", "tab:green", "tab:purple"]
    for k, (law, values) in enumerate(stable.items()):
        v = np.asarray(values, dtype=float)
        if v.shape != r.shape:
            raise InputError("stable", f"{law}: expected shape {r.shape} but found {v.shape}")
        own = radii.get(str(law), r if (str(law) == "dp" and not radii) else None)
        style = {"colors": colors[k % 4], "linestyles": styles[k % 4], "linewidths": 2.2 if law == "dp" else 1.6}
        drawn = False
        if own is not None:
            ok = own[np.isfinite(own)]
            if ok.size and ok.min() < 1.0 < ok.max():
                ax.contour(g, g, np.ma.masked_invalid(own), levels=[1.0], **style)
                drawn = True
        elif np.nanmin(v) < 0.5 < np.nanmax(v):
            ax.contour(g, g, np.nan_to_num(v, nan=0.5), levels=[0.5], **style)
            drawn = True
        if drawn:
            what = "radius = 1: " if own is not None else ""
            handles.append(Line2D([], [], color=colors[k % 4], linestyle=styles[k % 4],
                                  linewidth=style["linewidths"], label=f"{what}{law} law's boundary"))
        undecided = np.isnan(v)
        if undecided.any():
            jj, ii = np.nonzero(undecided)
            ax.plot(g[ii], g[jj], ls="none", marker="x", ms=4, color=colors[k % 4], label=f"{law}: undecided")
            handles.append(ax.lines[-1])
    if crosses:                       # each side of the stabilisable set's boundary named where it has room
        above = "not stabilisable" if least else "not stable"
        for text, side in (("stable\n(radius < 1)", r < 1.0), (f"{above}\n(radius > 1)", r > 1.0)):
            found = _deepest(g, side, ~side & np.isfinite(r))
            if found is None:
                continue
            spot, room = found
            box = {"boxstyle": "round,pad=0.25", "fc": "white", "ec": "0.4", "lw": 0.6, "alpha": 0.9}
            if room >= 0.12:                                  # the region has room for its name
                ax.text(*spot, text, ha="center", va="center", fontsize=8, zorder=6, bbox=box)
            else:                                             # a sliver: named beside it, with an arrow
                centre = (g[0] + g[-1]) / 2
                ax.annotate(text, xy=spot, xytext=(spot[0] + 0.3 * np.sign(centre - spot[0]) * (g[-1] - g[0]),
                                                   spot[1] + 0.25 * np.sign(centre - spot[1]) * (g[-1] - g[0])),
                            ha="center", va="center", fontsize=8, zorder=6, bbox=box,
                            arrowprops={"arrowstyle": "->", "color": "k", "lw": 0.9})
    elif finite.size:
        handles.append(Patch(facecolor="white", edgecolor="none",
                             label="stable everywhere shown" if finite.max() < 1.0
                             else "not stabilisable anywhere" if least else "not stable anywhere"))
    ax.set(xlabel=xlabel, ylabel=ylabel, xlim=(g[0], g[-1]), ylim=(g[0], g[-1]))
    if title:
        fig.suptitle(title, fontsize=9)
    if handles:
        fig.legend(handles=handles, **LEGEND)
    fit_width(fig)
    return _save(fig, path)


def _deepest(g: np.ndarray, inside: np.ndarray, outside: np.ndarray) -> tuple[tuple[float, float], float] | None:
    """The grid point of ``inside`` (a bool map over g x g, rows y) farthest from every point of ``outside`` and
    from the map's edges, where a label of a region reads best, with that distance (a fraction of the map's
    side); None when ``inside`` is empty. O(K^2 * boundary) on at most 41 x 41 points."""
    step = max(1, int(np.ceil(g.size / 41)))
    sub = g[::step]
    yy, xx = np.meshgrid(sub, sub, indexing="ij")
    ins, outs = inside[::step, ::step], outside[::step, ::step]
    if not ins.any():
        return None
    span = g[-1] - g[0]
    room = np.minimum.reduce([xx - g[0], g[-1] - xx, yy - g[0], g[-1] - yy]) / span * 2.0
    if outs.any():
        others = np.column_stack([xx[outs], yy[outs]])
        near = np.min(np.hypot(xx[..., None] - others[:, 0], yy[..., None] - others[:, 1]), axis=-1) / span
        room = np.minimum(room, near)
    room = np.where(ins, room, -np.inf)
    j, i = np.unravel_index(int(np.argmax(room)), room.shape)
    if not np.isfinite(room[j, i]) or room[j, i] <= 0:             # on the edge only: point at its middle
        pts = np.argwhere(ins)
        j, i = pts[len(pts) // 2]
        return (float(xx[j, i]), float(yy[j, i])), 0.0
    return (float(xx[j, i]), float(yy[j, i])), float(room[j, i])


def plot_stability_lines(x: Sequence[float], radii: Mapping[str, Any], *, xlabel: str, title: str | None = None,
                         path: str | Path | None = None) -> Figure:
    """Each law's mean-square spectral radius in closed loop against one swept quantity (``sweep --stability``):
    one line per law, the level 1 dashed, the region above it (not mean-square stable) shaded and named.

    ``radii``: label (``"tcp"``, ``"udp"`` or any text) to radii of shape (points,). O(points) per law.

    Examples
    --------
    >>> fig = plot_stability_lines([0.2, 0.5, 1.0], {"tcp": [1.4, 0.9, 0.3]}, xlabel=r"$\\nu$")
    >>> ax = fig.axes[0]
    >>> ax.lines[0].get_ydata().tolist(), ax.lines[0].get_label(), bool(ax.get_ylim()[1] > 1.4)
    ([1.4, 0.9, 0.3], 'TCP-like law', True)
    """
    xs = numeric_array(x, "x")
    if xs.ndim != 1 or xs.size < 1:
        raise InputError("x", "expected a non-empty 1-D sequence")
    if not isinstance(radii, Mapping) or not radii:
        raise InputError("radii", "expected a non-empty mapping law -> radii")
    fig = Figure(figsize=(7.4, 3.8), layout="constrained")
    ax = fig.subplots()
    top = 1.0
    for label, values in radii.items():
        ys = np.asarray(values, dtype=float)
        if ys.shape != xs.shape:
            raise InputError(f"radii[{label!r}]", f"expected shape {xs.shape} but found {ys.shape}")
        top = max(top, float(np.nanmax(ys)) if np.isfinite(ys).any() else top)
        ax.plot(xs, ys, marker="o", ms=3, lw=1.6, label={"tcp": "TCP-like law", "udp": "UDP-like law"}.get(
            label, str(label)))
    top *= 1.08
    ax.axhline(1.0, color="k", ls="--", lw=1.0, label="radius = 1")
    ax.axhspan(1.0, top, color="tab:red", alpha=0.12, lw=0, label="not mean-square stable (radius > 1)")
    ax.set_ylim(0.0, top)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(r"mean-square radius $\rho(\mathcal{L}_K)$ in closed loop")
    ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.legend(**LEGEND)
    return _save(fig, path)


def plot_strategy_map(axis: Any, strategies: Sequence[str] | None = None, winner: Any = None, *,
                      xlabel: str = r"$\mu_1$", ylabel: str = r"$\mu_2$", title: str | None = None,
                      path: str | Path | None = None) -> Figure:
    """Where each actuator strategy on a loss wins (studies.actuator_map): ``winner`` (K, K), rows the second
    channel, the index of the cheapest strategy's optimal law (-1: none stabilises, grey). ``axis`` may be a
    StrategyMap alone. O(K^2).

    Examples
    --------
    >>> fig = plot_strategy_map([0.5, 1.0], ["zero", "hold"], [[-1, 0], [1, 0]])
    >>> [t.get_text() for t in fig.legends[0].get_texts()]
    ['zero', 'hold', 'no strategy stabilises']
    """
    if hasattr(axis, "winner") and hasattr(axis, "strategies"):     # a StrategyMap
        axis, strategies, winner = axis.axis, axis.strategies, axis.winner
    if strategies is None or winner is None:
        raise InputError("winner", "expected the strategies and the winner grid beside the axis (or a StrategyMap "
                                   "alone)")
    g = numeric_array(axis, "axis")
    w = np.asarray(winner, dtype=int)
    if w.shape != (g.size, g.size):
        raise InputError("winner", f"expected shape ({g.size}, {g.size}) but found {w.shape}")
    palette = ["tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown"]
    colors = ["lightgrey", *palette[:len(strategies)]]
    fig = Figure(figsize=(6.4, 5.0), layout="constrained")
    ax = fig.add_subplot()
    ax.pcolormesh(g, g, w + 1, shading="nearest", cmap=ListedColormap(colors), vmin=-0.5,
                  vmax=len(strategies) + 0.5)
    handles = [Patch(color=palette[k], label=name) for k, name in enumerate(strategies)]
    handles.append(Patch(color="lightgrey", label="no strategy stabilises"))
    ax.set(xlabel=xlabel, ylabel=ylabel, xlim=(g[0], g[-1]), ylim=(g[0], g[-1]))
    if title:
        ax.set_title(title)
    fig.legend(handles=handles, **LEGEND)
    return _save(fig, path)


def plot_sensor_map(gamma: Sequence[float], mu: Sequence[float], cost: Any, stable: Mapping[str, Any], *,
                    title: str | None = None, path: str | Path | None = None) -> Figure:
    """Both links lossy: ``cost`` (shape (G, M), rows gamma; inf where the loop is proved not stable, nan where
    undecided: sensing.loop.loop_map) on a logarithmic colour map over (mu, gamma), grey where not stable, white
    where undecided (only when some cell is), and each law's stability boundary (the 1/2 level of its 0/1
    ``stable`` map). O(G M) per law.

    Examples
    --------
    >>> fig = plot_sensor_map([0.5, 1.0], [0.5, 1.0], [[np.inf, 4.0], [3.0, 2.0]], {"dp": [[0, 1], [1, 1]]})
    >>> len(fig.axes), fig.axes[0].get_xlabel()
    (2, 'actuator delivery rate $\\\\mu$')
    >>> fig = plot_sensor_map([0.5, 1.0], [0.5, 1.0], [[np.nan, 4.0], [3.0, 2.0]], {"dp": [[0, 1], [1, 1]]})
    >>> [t.get_text() for t in fig.legends[0].get_texts()][:2]
    ['not mean-square stable', 'undecided (between the critical-rate bounds)']
    """
    g, m = numeric_array(gamma, "gamma"), numeric_array(mu, "mu")
    c = np.asarray(cost, dtype=float)
    if c.shape != (g.size, m.size):
        raise InputError("cost", f"expected shape ({g.size}, {m.size}) but found {c.shape}")
    fig = Figure(figsize=(7.6, 5.0), layout="constrained")
    ax = fig.add_subplot()
    finite = c[np.isfinite(c) & (c > 0)]
    handles = [Patch(facecolor="lightgrey", label="not mean-square stable")]
    ax.set_facecolor("lightgrey")
    if finite.size:
        lo, hi = float(finite.min()), float(finite.max())
        hi = hi if hi > lo else lo * 10.0
        mesh = ax.pcolormesh(m, g, np.ma.masked_invalid(np.where(np.isfinite(c), c, np.nan)), shading="nearest",
                             norm=LogNorm(lo, hi), cmap="viridis")
        fig.colorbar(mesh, ax=ax, label="average stage cost (DP law on the estimate)")
    undecided = np.isnan(c)
    if np.any(undecided):         # no verdict is not "not stable": drawn apart, never grey
        ax.pcolormesh(m, g, np.ma.masked_where(~undecided, np.zeros_like(c)), shading="nearest", cmap="Greys",
                      vmin=0.0, vmax=1.0)                                   # white
        handles.append(Patch(facecolor="white", edgecolor="grey", label="undecided (between the critical-rate bounds)"))
    styles, colors = ["-", "--", ":"], ["black", "tab:orange", "tab:red"]
    for k, (law, values) in enumerate(stable.items()):
        v = np.asarray(values, dtype=float)
        if v.shape != c.shape:
            raise InputError("stable", f"{law}: expected shape {c.shape} but found {v.shape}")
        if np.nanmin(v) < 0.5 < np.nanmax(v):
            ax.contour(m, g, v, levels=[0.5], colors=colors[k % 3], linestyles=styles[k % 3], linewidths=1.6)
            handles.append(Line2D([], [], color=colors[k % 3], linestyle=styles[k % 3], label=f"{law} boundary"))
        else:                        # no boundary on the map: said in words, not as a line that is not drawn
            where = "stable everywhere shown" if np.nanmin(v) > 0.5 else "never stable here"
            handles.append(Patch(facecolor="none", edgecolor="none", label=f"{law}: {where}"))
    ax.set(xlabel=r"actuator delivery rate $\mu$", ylabel=r"sensor delivery rate $\gamma$", xlim=(m[0], m[-1]),
           ylim=(g[0], g[-1]))
    if title:                # over the whole figure: the legend beside the axes leaves them narrower than it
        fig.suptitle(title, fontsize=9)
    fig.legend(handles=handles, **LEGEND)
    return _save(fig, path)


def plot_power_pareto(curves: Mapping[str, Sequence[Mapping]], *, unit: str | None = None, title: str | None = None,
                      path: str | Path | None = None) -> Figure:
    """The power-cost trade-off: the least J* against the total power budget.

    ``curves``: label to rows with keys ``"budget"`` and ``"cost"`` (``PowerAllocation.to_dict()`` of
    [`power_pareto`][packetloss_cvx.allocation.power.power_pareto]'s points); J* on a log axis. ``unit``: the
    unit of the powers, as the link model's power table gives them (e.g. "mW"), written on the axis; the table
    carries no unit name, so by default the axis says "power-table units" rather than guess one.
    O(rows) to draw.

    Examples
    --------
    >>> rows = [{"budget": 0.0, "cost": 4.0}, {"budget": 1.0, "cost": 2.0}]
    >>> fig = plot_power_pareto({"tcp": rows}, unit="mW")
    >>> line, = fig.axes[0].lines
    >>> line.get_xdata().tolist(), line.get_ydata().tolist(), fig.axes[0].get_xlabel()
    ([0.0, 1.0], [4.0, 2.0], 'total power budget $\\\\sum_i P_i \\\\leq B$ (mW)')
    """
    fig, ax = _curves(curves, "budget", "cost", skip_missing=False)
    ax.set_yscale("log")
    ax.set_xlabel(rf"total power budget $\sum_i P_i \leq B$ ({unit or 'power-table units'})")
    ax.set_ylabel("least optimal cost $J^*(\\mu(P))$,\npaper basis (log scale)")     # two lines: fits 3.6 in
    if title:
        ax.set_title(title)
    fig.legend(**LEGEND)
    return _save(fig, path)


def plot_ack_break_even(alpha: Any, break_even: Sequence[float] | None = None, *,
                        currency: str = r"$\beta^\top\mu$", title: str | None = None,
                        path: str | Path | None = None,
                        attainable: tuple[Sequence[float], Sequence[float]] | None = None) -> Figure:
    """Above which price of the acknowledgement link the UDP-like design wins, against alpha:
    the break-even price (``allocation.ack.ack_break_even``), the region above it shaded "UDP-like".
    ``alpha`` may be a list of `ProtocolChoice` alone (each its alpha and break-even price).
    ``attainable``: ``(alphas, prices)`` on the attainable basis (the TCP-like design on the cost its law
    attains), drawn as points beside the line (then labelled the paper's basis). Non-finite points (no design) are
    left out. O(points) to draw.

    Examples
    --------
    >>> fig = plot_ack_break_even([1.0, 2.0, 3.0], [0.5, 0.2, float("nan")], attainable=([2.0], [0.1]))
    >>> fig.axes[0].lines[0].get_ydata().tolist(), fig.axes[0].lines[1].get_ydata().tolist()
    ([0.5, 0.2], [0.1])
    """
    if break_even is None and isinstance(alpha, Sequence) and alpha and all(
            hasattr(c, "break_even") and hasattr(c, "alpha") for c in alpha):      # ProtocolChoice results
        alpha, break_even = [c.alpha for c in alpha], [c.break_even for c in alpha]
    if break_even is None:
        raise InputError("break_even", "expected the break-even prices beside alpha (or a list of ProtocolChoice)")
    a = np.asarray(alpha, dtype=float)
    b = np.asarray(break_even, dtype=float)
    if a.shape != b.shape or a.ndim != 1:
        raise InputError("break_even", f"expected two lists of one length, found {a.shape} and {b.shape}")
    keep = np.isfinite(a) & np.isfinite(b)
    fig = Figure(figsize=(6.4, 3.6), layout="constrained")
    ax = fig.subplots()
    both = attainable is not None
    ax.plot(a[keep], b[keep], marker="o", ms=3, color="black",
            label="break-even, paper basis" if both else "break-even acknowledgement price")
    if attainable is not None:
        aa, ab = (np.asarray(v, dtype=float) for v in attainable)
        if aa.shape != ab.shape or aa.ndim != 1:
            raise InputError("attainable", f"expected two lists of one length, found {aa.shape} and {ab.shape}")
        ok = np.isfinite(aa) & np.isfinite(ab)
        ax.plot(aa[ok], ab[ok], linestyle="none", marker="s", ms=5, color="tab:red",
                label="break-even, attainable basis")
    top = float(np.max(b[keep])) * 1.15 if keep.any() else 1.0
    ax.fill_between(a[keep], b[keep], top, alpha=0.25, label="UDP-like cheaper" + (" (paper)" if both else ""))
    ax.fill_between(a[keep], 0.0, b[keep], alpha=0.25, label="TCP-like + link cheaper" + (" (paper)" if both else ""))
    ax.set_ylim(0.0, top)
    ax.set_xlabel(r"cost bound $\alpha$")
    ax.set_ylabel(f"acknowledgement price ({currency})")
    if title:                # over the whole figure: the legend beside the axes leaves them narrower than it
        fig.suptitle(title, fontsize=9)
    fig.legend(**LEGEND)
    return _save(fig, path)
