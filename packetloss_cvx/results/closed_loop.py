"""Closed-loop results: a law's mean-square stability and exact costs, the DP optimum, simulations."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..display import closed_loop_html, fields_html, fields_repr, simulation_html, to_json
from .base import Frozen, Tabular, finite_or_none, scalar_row

__all__ = ["ClosedLoop", "ClosedLoopRun", "OpenLoopCheck", "Riccati", "Simulation"]


@dataclass(frozen=True)
class ClosedLoop(Frozen):
    """A stationary law ``u = -K x`` (``law``: its label) run for ever over the channel ``mu`` (simulation.moments).

    ``spectral_radius`` of the second-moment operator (mean-square stable iff < 1); ``stable`` only when
    it is below 1 by ``tolerances.MEAN_SQUARE_MARGIN``; ``average_stage_cost`` = lim E[x'Omega x + (Vu)'Psi(Vu)]
    = tr(P_K Sigma_W), ``inf`` when not stable; ``cost_to_go`` P_K (x0'P_K x0: total cost from x0 without
    noise) and ``second_moment`` (stationary E[xx']), None when not stable; ``reason`` why the cost is inf.
    """

    law: str
    gain: np.ndarray
    mu: np.ndarray
    spectral_radius: float
    stable: bool
    average_stage_cost: float
    cost_to_go: np.ndarray | None
    second_moment: np.ndarray | None
    reason: str = ""

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = closed_loop_html

    to_json = to_json   # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats; an infinite cost is None (JSON has no inf). O(n^2)."""
        return {"law": self.law, "gain": self.gain.tolist(), "mu": self.mu.tolist(),
                "mean_square_spectral_radius": self.spectral_radius, "stable": self.stable,
                "average_stage_cost": finite_or_none(self.average_stage_cost),
                "cost_to_go": None if self.cost_to_go is None else self.cost_to_go.tolist(), "reason": self.reason}


@dataclass(frozen=True)
class Riccati(Frozen):
    """The DP optimum (simulation.riccati): ``cost_to_go`` P solves the modified Riccati equation, ``gain``
    K its law u = -K x, ``average_stage_cost`` = tr(P Sigma_W), ``spectral_radius`` of the law's
    second-moment operator, ``iterations`` (value and policy), ``residual`` ||R(P) - P|| / ||P||."""

    gain: np.ndarray
    cost_to_go: np.ndarray
    average_stage_cost: float
    spectral_radius: float
    iterations: int
    residual: float

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html
    to_json = to_json       # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats. O(n^2)."""
        return {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in vars(self).items()}


@dataclass(frozen=True)
class OpenLoopCheck(Tabular):
    """A protocol's plan U* applied open loop and sampled (simulation.montecarlo): ``formula`` J* (Theorem 1),
    ``exact`` E[realised cost] under the stated model (J_udp(U*)), ``mean`` and ``stderr`` of the samples,
    ``z = (mean - exact) / stderr``; ``reason`` why the plan is missing (its numbers nan), "" when it is not;
    ``stderr_reason`` why the sample has no error bar (``stderr`` and ``z`` nan), "" when it has one."""

    formula: float
    exact: float
    mean: float
    stderr: float
    z: float
    reason: str = ""
    stderr_reason: str = ""

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html
    to_json = to_json       # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        """``simulate --json``'s ``open_loop`` object (docs/cli-contracts.md; plus ``reason`` and ``stderr_reason``
        when set); a non-finite number is None (JSON). O(1)."""
        out = {k: finite_or_none(getattr(self, k)) for k in ("formula", "exact", "mean", "stderr", "z")}
        return {**out, **({"reason": self.reason} if self.reason else {}),
                **({"stderr_reason": self.stderr_reason} if self.stderr_reason else {})}


@dataclass(frozen=True)
class ClosedLoopRun(Frozen):
    """A law run in closed loop for ``steps`` steps over sampled losses (simulation.montecarlo): ``mean_stage_cost``
    and ``stderr`` of each run's mean stage cost over t < steps, ``exact_stage_cost`` its expectation,
    ``spectral_radius`` and ``stable`` as in ClosedLoop, ``reason`` why there is no law ("" if there is); per
    step: ``state_norm_mean``, ``state_norm_std`` of ||x_t|| (t <= steps) and ``stage_cost_mean``;
    ``exact_reason`` why a law that ran has no exact value or radius (nan, e.g. a belief-dependent law behind a
    Markov channel); ``note`` what the law is, where the label does not say it all; ``stderr_reason`` why the sample
    has no error bar (``stderr`` nan: the loop's fourth moments grow, simulation.tails), "" when it has one."""

    law: str
    mean_stage_cost: float
    stderr: float
    exact_stage_cost: float
    spectral_radius: float
    stable: bool
    state_norm_mean: np.ndarray
    state_norm_std: np.ndarray
    stage_cost_mean: np.ndarray
    reason: str = ""
    exact_reason: str = ""
    note: str = ""
    stderr_reason: str = ""

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = fields_html
    to_json = to_json       # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        """``simulate --json``'s ``closed_loop`` object (docs/cli-contracts.md; plus ``reason`` when there is no law or
        no exact value, ``note`` when set, and
        ``stderr_reason`` when the sample has no error bar: ``stderr`` is then None); non-finite numbers are None.
        O(1)."""
        out: dict[str, Any] = {"mean_stage_cost": finite_or_none(self.mean_stage_cost),
                               "stderr": finite_or_none(self.stderr),
                               "exact_stage_cost": finite_or_none(self.exact_stage_cost),
                               "mean_square_spectral_radius": finite_or_none(self.spectral_radius),
                               "stable": self.stable}
        reason = self.reason or self.exact_reason
        return {**out, **({"reason": reason} if reason else {}), **({"note": self.note} if self.note else {}),
                **({"stderr_reason": self.stderr_reason} if self.stderr_reason else {})}

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """One row per step t = 0..T: the norms' mean and std, and the stage cost (nan at t = T, which has
        none); the law and its whole-run numbers as attrs."""
        stage = np.append(np.asarray(self.stage_cost_mean, dtype=float), np.nan)
        row, attrs = scalar_row(self.to_dict())
        return ({"t": np.arange(self.state_norm_mean.size), "state_norm_mean": self.state_norm_mean,
                 "state_norm_std": self.state_norm_std, "stage_cost_mean": stage},
                {"law": self.law, **{k: v[0] for k, v in row.items()}, **attrs})

    def plot(self, **kwargs: Any) -> Any:
        """This run drawn by [`plot_closed_loop`][packetloss_cvx.plots.figures.plot_closed_loop] (keywords passed on);
        returns the
        matplotlib Figure."""
        from ..plots import plot_closed_loop  # lazy: matplotlib, only when asked to draw
        return plot_closed_loop({self.law: self}, **kwargs)


@dataclass(frozen=True)
class Simulation(Frozen):
    """Monte Carlo checks (simulation.montecarlo): ``open_loop`` protocol -> OpenLoopCheck, ``closed_loop`` law ->
    ClosedLoopRun, ``trajectories`` (laws, runs, steps + 1, n) of the first runs or None; ``channel`` the model
    sampled ("bernoulli" or "gilbert-elliott")."""

    samples: int
    steps: int
    seed: int
    open_loop: dict[str, OpenLoopCheck]
    closed_loop: dict[str, ClosedLoopRun]
    trajectories: np.ndarray | None = None
    channel: str = "bernoulli"

    __repr__ = fields_repr   # the headline numbers, not the arrays (display.py)
    _repr_html_ = simulation_html
    to_json = to_json       # to_dict() as JSON text (display.py)

    def to_dict(self) -> dict[str, Any]:
        """``{law: {"open_loop": {...}, "closed_loop": {...}}}``, each part where it was run. O(laws)."""
        out: dict[str, Any] = {}
        for law, check in self.open_loop.items():
            out.setdefault(law, {})["open_loop"] = check.to_dict()
        for law, run in self.closed_loop.items():
            out.setdefault(law, {})["closed_loop"] = run.to_dict()
        return out

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """With closed-loop runs: one row per (law, step), as `ClosedLoopRun.to_pandas`, the runs' own
        numbers as attrs; else one row per protocol of the open-loop checks."""
        attrs: dict[str, Any] = {"samples": self.samples, "steps": self.steps, "seed": self.seed,
                                 "channel": self.channel}
        if not self.closed_loop:
            rows = [scalar_row(check.to_dict())[0] for check in self.open_loop.values()]
            columns = {"protocol": list(self.open_loop)}
            for key in dict.fromkeys(k for row in rows for k in row):
                columns[key] = [row.get(key, [None])[0] for row in rows]
            return columns, attrs
        parts = [(law, run._table()) for law, run in self.closed_loop.items()]
        columns = {"law": np.concatenate([[law] * len(cols["t"]) for law, (cols, _) in parts])}
        for key in ("t", "state_norm_mean", "state_norm_std", "stage_cost_mean"):
            columns[key] = np.concatenate([cols[key] for _, (cols, _) in parts])
        attrs["closed_loop"] = {law: run_attrs for law, (_, run_attrs) in parts}
        attrs["open_loop"] = {p: check.to_dict() for p, check in self.open_loop.items()}
        return columns, attrs

    def plot(self, **kwargs: Any) -> Any:
        """The closed-loop runs drawn by [`plot_closed_loop`][packetloss_cvx.plots.figures.plot_closed_loop] (keywords
        passed on);
        returns the matplotlib Figure.

        Raises
        ------
        InputError
            Field ``curves`` when the simulation ran no closed loop (``simulate(..., closed_loop=True)``).
        """
        from ..plots import plot_closed_loop  # lazy: matplotlib, only when asked to draw
        return plot_closed_loop(self, **kwargs)
