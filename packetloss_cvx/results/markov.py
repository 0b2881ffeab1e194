"""Results under Gilbert–Elliott channels: the exact minimiser beside the plug-in law, a burstiness
sweep, and the Markov jump linear system's stability and mode-dependent gains."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..display import fields_html, fields_repr, to_json
from .base import Frozen, freeze, read_only
from .plans import Solution

__all__ = ["BurstinessSweep", "MarkovSolution", "MjlsResult"]


@dataclass(frozen=True)
class MarkovSolution:
    """One protocol under a Gilbert–Elliott channel (:func:`packetloss_cvx.markov.markov_solution`).

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
    (:func:`packetloss_cvx.markov.burstiness_sweep`). ``plugin``: protocol -> the protocol's exact cost
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


@dataclass(frozen=True)
class MjlsResult(Frozen):
    """Mode-dependent optimal control of a Markov jump linear system (:mod:`packetloss_cvx.markov.mjls`).

    ``gains[k]``: u = -gains[k] x in mode k; ``cost_matrices[k]``: the coupled Riccati solutions P_k;
    ``modes``: each mode's channel states (Gilbert–Elliott: 1 = good, 0 = bad per actuator; a MarkovChannel: the
    state index per actuator); ``transition``: the mode chain;
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
