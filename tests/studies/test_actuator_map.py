"""studies.actuator_map: where each actuator strategy on a loss wins. References: the DARE at mu = 1 (every
strategy's optimal law is the full-information LQR there: a tie, won by zero), buffer:1 being zero (a tie at every
point), and the rule itself (the winner's cost is the least, by the costs the map reports)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from packetloss_cvx import load_example
from packetloss_cvx.errors import InputError
from packetloss_cvx.plots import plot_strategy_map
from packetloss_cvx.studies.actuator_map import STRATEGY_TIE_RTOL, strategy_map
from packetloss_cvx.tolerances import ACTUATOR_DP_RTOL


def test_every_strategy_is_the_dare_at_perfect_links_and_zero_wins_the_tie():
    system = load_example("two_actuator")
    found = strategy_map(system, 2, ("zero", "hold", "buffer:2"))
    P = solve_discrete_are(system.A, system.B, system.state_weights[0], np.diag(system.input_weights[0]))
    assert np.allclose(found.cost[:, -1, -1], system.x0 @ P @ system.x0, rtol=ACTUATOR_DP_RTOL)
    assert found.winner[-1, -1] == 0


def test_winner_is_the_least_cost_and_buffer_one_ties_with_zero():
    system = load_example("two_actuator")
    found = strategy_map(system, 3, ("buffer:1", "zero", "buffer:2"))
    assert np.allclose(found.cost[0], found.cost[1], rtol=STRATEGY_TIE_RTOL)
    for r in range(3):
        for c in range(3):
            k = found.winner[r, c]
            assert found.cost[k, r, c] <= found.cost[:, r, c].min() * (1 + STRATEGY_TIE_RTOL)
            assert k != 1                                     # buffer:1, listed first, takes zero's ties
    shares = found.to_dict()["share"]
    assert sum(shares.values()) == pytest.approx(1.0)


def test_bad_map_input_is_an_input_error():
    with pytest.raises(InputError, match="grid"):
        strategy_map(load_example("two_actuator"), 1)
    with pytest.raises(InputError, match="actuator"):
        strategy_map(load_example("two_actuator"), 2, ("zero", "drop"))
    with pytest.raises(InputError, match="winner"):
        plot_strategy_map([0.5, 1.0], ["zero"], [[0, 0, 0]])
