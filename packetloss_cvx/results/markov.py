"""Results under Gilbert–Elliott channels: the exact minimiser beside the plug-in law, a burstiness
sweep and a (mean rate × burstiness) map, and the Markov jump linear system's stability and mode-dependent
gains."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..display import fields_html, fields_repr, to_json
from ..errors import InputError
from ..optional import load
from .base import Frozen, Tabular, freeze, numbered, read_only
from .plans import Solution

__all__ = ["BurstinessMap", "BurstinessSweep", "MarkovSolution", "MjlsResult", "plugin_loss"]


def plugin_loss(plugin: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """``plugin / exact - 1`` elementwise: how much the plug-in law loses against the exact minimum. A zero
    minimum (x0 = 0 without noise) has a zero plug-in cost too, so its loss is 0, as ``solve``'s
    (`markov_solution`). O(size).

    Examples
    --------
    >>> plugin_loss(np.array([3.0, 0.0]), np.array([2.0, 0.0])).tolist()
    [0.5, 0.0]
    """
    plugin, exact = np.asarray(plugin, dtype=float), np.asarray(exact, dtype=float)
    return np.divide(plugin, exact, out=np.ones_like(plugin), where=exact > 0) - 1.0


@dataclass(frozen=True)
class MarkovSolution(Tabular):
    """One protocol under a Gilbert–Elliott channel (`packetloss_cvx.qp.markov_solution.markov_solution`).

    ``exact``: the minimiser of the protocol's exact expected cost (closed form); ``qp``: its
    cvxpy + Clarabel twin (cross-checked) or None; ``plugin_cost``: the protocol's exact cost of the
    plug-in plan (the paper's law with the chain's mu_t); ``relative_loss``: plugin_cost / exact.cost - 1;
    ``plan_expected_cost``: E[realised cost] of the plug-in plan under the chain (what sampling measures,
    the UDP-like form for both protocols). O(N m + n m) to build.
    """

    protocol: str
    exact: Solution
    qp: Solution | None
    plugin_cost: float
    relative_loss: float
    plan_expected_cost: float

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html
    to_json = to_json       # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"exact": self.exact.to_dict(), "plugin_cost": self.plugin_cost,
                               "relative_loss": self.relative_loss, "plan_expected_cost": self.plan_expected_cost}
        if self.qp is not None:
            out["qp"] = {"status": self.qp.status, "cost": self.qp.cost, "solve_time": self.qp.solve_time,
                         **(self.qp.cross_check.to_dict() if self.qp.cross_check is not None else {})}
        return out


@dataclass(frozen=True)
class BurstinessSweep(Frozen):
    """Costs over the burstiness lambda = 1 - p - r at fixed average delivery rates ``rate``
    (`packetloss_cvx.studies.burstiness.burstiness_sweep`). ``plugin``: protocol -> the protocol's exact cost
    of its plug-in plan; ``exact``: protocol -> the exact minimum; each an array over ``correlation``."""

    correlation: np.ndarray
    rate: np.ndarray
    plugin: dict[str, np.ndarray]
    exact: dict[str, np.ndarray]

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html
    to_json = to_json       # to_dict() as JSON text (display.py)

    def __post_init__(self) -> None:
        freeze(self)
        object.__setattr__(self, "plugin", {k: read_only(v) for k, v in self.plugin.items()})
        object.__setattr__(self, "exact", {k: read_only(v) for k, v in self.exact.items()})

    def to_dict(self) -> dict[str, Any]:
        return {"correlation": self.correlation.tolist(), "rate": self.rate.tolist(),
                "plugin": {k: v.tolist() for k, v in self.plugin.items()},
                "exact": {k: v.tolist() for k, v in self.exact.items()}}

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """One row per burstiness lambda: plugin_<p>, exact_<p> per protocol; the rates as attrs."""
        columns: dict[str, Any] = {"correlation": self.correlation}
        for p in self.exact:
            columns[f"plugin_{p}"] = self.plugin[p]
            columns[f"exact_{p}"] = self.exact[p]
        return columns, dict(zip(numbered("rate", self.rate.size), self.rate.tolist(), strict=True))

    def plot(self, **kwargs: Any) -> Any:
        """Each protocol's exact minimum and plug-in cost against lambda, drawn by
        [`plot_cost_lines`][packetloss_cvx.plots.figures.plot_cost_lines] (keywords passed on); returns the matplotlib
        Figure."""
        from ..plots import plot_cost_lines  # lazy: matplotlib, only when asked to draw
        curves = {}
        for p in self.exact:
            curves[f"{p.upper()}-like exact minimum"] = self.exact[p]
            curves[f"{p.upper()}-like plug-in plan"] = self.plugin[p]
        return plot_cost_lines(self.correlation, curves, **{"xlabel": r"burstiness $\lambda = 1 - p - r$", **kwargs})


@dataclass(frozen=True)
class BurstinessMap(Frozen):
    """Costs over a (mean rate × burstiness) grid of one channel
    (`packetloss_cvx.studies.burstiness.burstiness_map`):
    channel ``channel`` (0-based) behind the stationary Gilbert channel of long-run rate ``rate[a]`` and
    burstiness ``correlation[b]`` = lambda = 1 - p - r, the other channels as in the system
    (`channel_twin`). ``plugin``: protocol -> the protocol's exact expected cost of
    its
    plug-in plan, (R, L) with ``[a, b]`` at ``(rate[a], correlation[b])``; ``exact``: protocol -> the exact minimum,
    alike. ``name``: the system's. `relative_loss` is the plug-in law's loss."""

    channel: int
    rate: np.ndarray
    correlation: np.ndarray
    plugin: dict[str, np.ndarray]
    exact: dict[str, np.ndarray]
    name: str | None = None

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html
    to_json = to_json       # to_dict() as JSON text (display.py)

    def __post_init__(self) -> None:
        freeze(self)
        shape = (self.rate.size, self.correlation.size)
        for kind in (self.plugin, self.exact):
            for key, value in kind.items():
                if np.shape(value) != shape:
                    raise InputError(key, f"expected costs of shape {shape} (rates × correlations), found "
                                          f"{np.shape(value)}")
        object.__setattr__(self, "plugin", {k: read_only(v) for k, v in self.plugin.items()})
        object.__setattr__(self, "exact", {k: read_only(v) for k, v in self.exact.items()})

    @property
    def protocols(self) -> tuple[str, ...]:
        """The protocols evaluated (keys of ``exact``)."""
        return tuple(self.exact)

    def relative_loss(self, protocol: str) -> np.ndarray:
        """``plugin / exact - 1`` of ``protocol`` over the grid (`plugin_loss`), (R, L). O(R L)."""
        return plugin_loss(self.plugin[protocol], self.exact[protocol])

    def to_dict(self) -> dict[str, Any]:
        """Plain lists: rows over ``rate``, columns over ``correlation``. O(R L)."""
        return {"name": self.name, "channel": self.channel, "rate": self.rate.tolist(),
                "correlation": self.correlation.tolist(),
                **{p: {"plugin": self.plugin[p].tolist(), "exact": self.exact[p].tolist(),
                       "relative_loss": self.relative_loss(p).tolist()} for p in self.protocols}}

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """One row per (rate, correlation), rate slowest: plugin_<p>, exact_<p>, loss_<p> per protocol; the
        channel (1-based) and the name as attrs."""
        R, L = self.rate.size, self.correlation.size
        columns: dict[str, Any] = {"rate": np.repeat(self.rate, L), "correlation": np.tile(self.correlation, R)}
        for p in self.protocols:
            columns[f"plugin_{p}"] = np.ravel(self.plugin[p])
            columns[f"exact_{p}"] = np.ravel(self.exact[p])
            columns[f"loss_{p}"] = np.ravel(self.relative_loss(p))
        return columns, {"channel": self.channel + 1, "name": self.name or ""}

    def plot(self, protocol: str | None = None, **kwargs: Any) -> Any:
        """``protocol``'s exact minimum and the plug-in law's loss (percent) over the map, drawn by
        [`plot_burstiness_map`][packetloss_cvx.plots.figures.plot_burstiness_map] (keywords passed on; ``protocol``
        defaults to UDP-like
        where evaluated, else the first); returns the matplotlib Figure.

        Raises
        ------
        InputError
            Field ``protocol``: not one of `protocols`.
        """
        from ..plots import plot_burstiness_map  # lazy: matplotlib, only when asked to draw
        return plot_burstiness_map(self, protocol=protocol, **kwargs)

    def to_xarray(self) -> Any:
        """An `xarray.Dataset` over (``rate``, ``correlation``) (the ``xarray`` extra): ``plugin_<p>``,
        ``exact_<p>`` and ``loss_<p>`` per protocol; the channel (1-based) and name as attributes. O(R L)."""
        xr = load("xarray", "to_xarray")
        dims = ("rate", "correlation")
        cost_units = "stage-cost units (x'Qx + u'Ru)"
        data = {}
        for p in self.protocols:
            name = f"{p.upper()}-like"
            data[f"plugin_{p}"] = (dims, np.asarray(self.plugin[p]),
                                   {"long_name": f"exact expected cost of the {name} plug-in plan",
                                    "units": cost_units})
            data[f"exact_{p}"] = (dims, np.asarray(self.exact[p]),
                                  {"long_name": f"exact minimum expected cost ({name})", "units": cost_units})
            data[f"loss_{p}"] = (dims, self.relative_loss(p),
                                 {"long_name": f"plug-in law's loss against the exact minimum ({name})", "units": "1"})
        coords = {"rate": ("rate", self.rate, {"long_name": f"mean delivery rate of channel {self.channel + 1} "
                                                            "(1-based)", "units": "1"}),
                  "correlation": ("correlation", self.correlation,
                                  {"long_name": "burstiness lambda = 1 - p - r", "units": "1"})}
        return xr.Dataset(data, coords=coords,
                          attrs={"kind": "burstiness-map", "channel": self.channel + 1, "name": self.name or "",
                                 "correlation": "lambda = 1 - p - r of the mapped channel's Gilbert chain",
                                 "loss": "plugin / exact - 1: the plug-in law's loss against the exact minimum"})


@dataclass(frozen=True)
class MjlsResult(Frozen):
    """Mode-dependent optimal control of a Markov jump linear system (`packetloss_cvx.closedloop.mjls`).

    ``gains[k]``: u = -gains[k] x in mode k; ``cost_matrices[k]``: the coupled Riccati solutions P_k;
    ``modes``: each mode's channel states, the state index per actuator (Gilbert–Elliott: 0 = good, 1 = bad);
    ``transition``: the mode chain;
    ``spectral_radius``: of the closed loop's second-moment operator (< 1: mean-square stable);
    ``iterations``, ``residual``: of the coupled Riccati iteration.
    """

    gains: np.ndarray
    cost_matrices: np.ndarray
    modes: np.ndarray
    transition: np.ndarray
    spectral_radius: float
    iterations: int
    residual: float

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html
    to_json = to_json       # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        return {"gains": self.gains.tolist(), "cost_matrices": self.cost_matrices.tolist(),
                "modes": self.modes.tolist(), "transition": self.transition.tolist(),
                "spectral_radius": self.spectral_radius, "mean_square_stable": bool(self.spectral_radius < 1),
                "iterations": self.iterations, "residual": self.residual}

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """One row per mode: each actuator's channel state (state1..statem; 0 good, 1 bad); the radius, the
        iteration's numbers and the matrices (gains, P_k, transition) as attrs."""
        modes = np.asarray(self.modes)
        columns: dict[str, Any] = {"mode": np.arange(modes.shape[0])}
        columns.update(dict(zip(numbered("state", modes.shape[1]), modes.T, strict=True)))
        data = self.to_dict()
        del data["modes"]
        return columns, data
