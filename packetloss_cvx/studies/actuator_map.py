"""Where in the (mu_1, mu_2) plane each actuator strategy on a loss wins: the strategy map.

At each grid point the optimal TCP-like law of every strategy (closedloop.actuator_design.actuator_dp) and its
cost: the average stage cost under the noise, or, without noise, the total cost from x0 (``x0'P x0``, the
infinite-horizon cost the DP minimises). The winner is the strategy of least cost; where no strategy has a
stabilising optimal law (or the DP gives no verdict), none wins. Costs that agree to `STRATEGY_TIE_RTOL` are a
tie, won by the first strategy listed (zero before hold before the buffer: the simpler firmware).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..closedloop.actuator import parse_actuator
from ..closedloop.actuator_design import actuator_dp
from ..errors import InputError, NumericalError
from ..model.system import System, check_system

__all__ = ["STRATEGY_TIE_RTOL", "StrategyMap", "strategy_map"]

#: Two strategies' optimal costs closer than this (relative) are a tie: the DP solves to RICCATI_RTOL (1e-12) on
#: the cost-to-go, so 1e-9 separates a real difference from the solver's (buffer:1 and zero agree to 1e-15).
STRATEGY_TIE_RTOL = 1e-9


@dataclass(frozen=True)
class StrategyMap:
    """``axis`` (K,), ``strategies`` (names), ``cost`` (S, K, K) each strategy's optimal cost (rows mu_2, inf where
    it has no stabilising optimal law), ``winner`` (K, K) the index of the cheapest (-1: none), ``basis`` which
    cost ("average stage cost" or "cost from x0"), ``channels`` the two channels mapped."""

    axis: np.ndarray
    strategies: tuple[str, ...]
    cost: np.ndarray
    winner: np.ndarray
    basis: str
    channels: tuple[int, int]

    def to_dict(self) -> dict[str, Any]:
        """Plain lists (None for inf), the winners' shares."""
        cost = [[[float(v) if np.isfinite(v) else None for v in row] for row in grid] for grid in self.cost]
        share = {name: float(np.mean(self.winner == k)) for k, name in enumerate(self.strategies)}
        return {"axis": self.axis.tolist(), "strategies": list(self.strategies), "cost": cost,
                "winner": self.winner.tolist(), "basis": self.basis, "channels": list(self.channels),
                "share": share}


def strategy_map(system: System, grid: int, strategies: Sequence[str] = ("zero", "hold", "buffer:2"),
                 channels: tuple[int, int] = (0, 1)) -> StrategyMap:
    """The strategy map over ``mu_i, mu_j`` on a K-point axis in (0, 1] (the other channels at the file's mu).
    Time O(K^2) optimal laws per strategy (`actuator_dp`).

    Raises
    ------
    InputError
        ``grid`` below 2, a system with fewer than two channels or a Markov chain, an unknown strategy.

    Examples
    --------
    >>> from packetloss_cvx import load_example
    >>> found = strategy_map(load_example("two_actuator"), 2, ("zero", "hold"))
    >>> found.axis.tolist(), found.strategies, found.winner.tolist()       # zero wins at both corners
    ([0.5, 1.0], ('zero', 'hold'), [[0, 0], [0, 0]])
    """
    system = check_system(system)
    if system.channel is not None or system.m < 2:
        raise InputError("system", "a strategy map needs two Bernoulli channels")
    if not isinstance(grid, int) or grid < 2:
        raise InputError("grid", f"expected an integer >= 2, found {grid!r}")
    names = tuple(str(parse_actuator(s, system.horizon)) for s in strategies)
    axis = np.linspace(1.0 / grid, 1.0, grid)
    noisy = bool(np.any(system.noise_cov))
    cost = np.full((len(names), grid, grid), np.inf)
    base = np.array(system.mu_schedule[0], dtype=float)
    for r, mu_j in enumerate(axis):
        for c, mu_i in enumerate(axis):
            mu = base.copy()
            mu[channels[0]], mu[channels[1]] = mu_i, mu_j
            for k, name in enumerate(names):
                try:
                    design = actuator_dp(system, name, mu)
                except NumericalError:
                    continue
                cost[k, r, c] = design.cost if noisy else design.initial
    best = np.min(cost, axis=0)
    within = cost <= best * (1.0 + STRATEGY_TIE_RTOL)
    winner = np.where(np.isfinite(best), np.argmax(within, axis=0), -1)
    return StrategyMap(axis, names, cost, winner, "average stage cost" if noisy else "cost from x0", channels)
