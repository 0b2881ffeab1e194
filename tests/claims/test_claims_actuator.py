"""claims.actuator (zero-vs-hold-paper-systems): the costs it compares, from other routes. Zero's optimum is the
modified Riccati equation (closedloop.riccati.dp_riccati); hold's optimum is no more expensive than the zero
optimum's gain run with the hold firmware (closedloop.actuator.actuator_costs, exact over a long horizon)."""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx import load_example
from packetloss_cvx.claims.actuator import zero_vs_hold
from packetloss_cvx.claims.context import Context, paper_systems
from packetloss_cvx.closedloop.actuator import actuator_costs
from packetloss_cvx.closedloop.actuator_design import actuator_dp
from packetloss_cvx.closedloop.riccati import dp_riccati
from packetloss_cvx.tolerances import ACTUATOR_DP_STATIONARY_RTOL


@pytest.mark.parametrize("name", ["pendulum", "two_actuator"])
def test_the_compared_costs_from_other_routes(name):
    system = load_example(name)
    zero = actuator_dp(system, "zero").initial
    reference = float(system.x0 @ dp_riccati(system).cost_to_go @ system.x0)
    assert zero == pytest.approx(reference, rel=ACTUATOR_DP_STATIONARY_RTOL)
    hold = actuator_dp(system, "hold").initial
    stage, terminal = actuator_costs(system, dp_riccati(system).gain, 2000, "hold")
    assert hold <= stage.sum() + terminal


def test_verdict_and_counterexample_are_the_pendulum():
    result = zero_vs_hold(Context(paper=paper_systems(), random=[], seed=0))
    assert result.outcomes == "-+"
    assert result.counterexample["name"] == "pendulum"
    assert result.worst < 0
    assert np.isfinite(result.worst)
