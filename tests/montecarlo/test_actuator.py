"""The sampled loop of ``u = -K x`` under each actuator strategy (montecarlo/actuator.py) against the mode engine's
exact expectation (closedloop.actuator.actuator_costs, not the code under test)."""

from __future__ import annotations

import pytest

from packetloss_cvx.closedloop.actuator import actuator_costs
from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo.actuator import simulate_actuator
from packetloss_cvx.tolerances import SAMPLED_Z_MAX


@pytest.mark.parametrize("actuator", ["zero", "hold", "buffer:2", "buffer:2:hold"])
def test_the_sampled_loop_is_the_exact_cost_within_its_interval(actuator):
    # mu = 0.4: plans run out often, so buffer:2 and buffer:2:hold differ (exact 1.64 against 2.05 per step)
    s = System(A=[[1.1]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.4], x0=[2.0],
               noise_cov=[[0.1]])
    row = simulate_actuator(s, [[0.7]], 15, actuator, 20000, seed=1)
    exact = float(actuator_costs(s, [[0.7]], 15, actuator)[0].mean())
    assert abs(row["mean_stage_cost"] - exact) <= SAMPLED_Z_MAX * row["stderr"]
    assert row["stderr"] < 0.02 * exact

