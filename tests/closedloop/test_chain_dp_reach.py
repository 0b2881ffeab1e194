"""The chain DP's budget refusal offers an override only where one could finish: within OVERRIDE_REACH times the
budget; beyond it the message says the exact DP is out of reach and points to the bounds."""

import pytest

from packetloss_cvx.budgets import OVERRIDE_REACH, limit
from packetloss_cvx.closedloop.chain_dp import chain_dp
from packetloss_cvx.errors import BudgetError
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.system import System


def _hidden(horizon):
    """One hidden Gilbert-Elliott channel (both states lose packets): by hand, 2^t belief nodes at step t with 2
    outcomes each, sum_{t<N} 2^(t+1) = 2^(N+1) - 2 node-outcomes."""
    return System(A=[[1.3]], B=[[0.8]], horizon=horizon, state_weight=[1.5], input_weight=[0.7], x0=[2.0],
                  channel=GilbertElliott(p=[0.1], r=[0.3], h_good=[0.95], h_bad=[0.1]))


def test_far_beyond_the_budget_no_override_is_offered():
    horizon = 80                                       # 2^81 - 2 = 2.42e24 node-outcomes
    assert 2.0 ** (horizon + 1) > OVERRIDE_REACH * limit("chain_dp_nodes")
    with pytest.raises(BudgetError) as info:
        chain_dp(_hidden(horizon))
    text = str(info.value)
    assert "out of reach" in text
    assert "PACKETLOSS_CVX_BUDGET" not in text
    assert "chain_attainable's bounds" in text
    assert f"{(2.0 ** (horizon + 1) - 2) / limit('chain_dp_nodes'):.2g} times the budget" in text


def test_within_reach_the_override_is_offered_with_the_need():
    horizon = 19                                       # 2^20 - 2 = 1,048,574 node-outcomes: 5.2 x the budget
    need = 2.0 ** (horizon + 1) - 2
    assert limit("chain_dp_nodes") < need <= OVERRIDE_REACH * limit("chain_dp_nodes")
    with pytest.raises(BudgetError) as info:
        chain_dp(_hidden(horizon))
    assert "PACKETLOSS_CVX_BUDGET_CHAIN_DP_NODES=1.05e+06" in str(info.value)
    assert "out of reach" not in str(info.value)
