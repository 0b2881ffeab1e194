"""allocation.allocate(..., actuator=): the allocation's stabilisability verdict at mu* under each actuator strategy.

Reference: the scalar plant by hand (x+ = 2x + v u: every strategy stabilises iff mu > 1 - 1/a^2 = 3/4, for zero,
hold and the buffered plan alike), on allocations whose mu* lies on either side of 3/4.
"""

from __future__ import annotations

import pytest

from packetloss_cvx.allocation.api import allocate
from packetloss_cvx.errors import InputError
from packetloss_cvx.model.system import System

SCALAR = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])


@pytest.mark.parametrize(("alpha", "expected"), [(3.5, "stable"), (5.0, "unstable")])
def test_the_verdict_at_mu_star_follows_the_hand_critical_mu_for_every_strategy(alpha, expected):
    result = allocate(SCALAR, "tcp", alpha, [1.0], actuator="all")
    assert (result.mu[0] > 0.75) == (expected == "stable")
    assert [name for name, *_ in result.actuator] == ["zero", "hold", "buffer:3"]
    for _, verdict, radius, _ in result.actuator:
        assert verdict == expected
        assert (radius is not None and radius < 1.0) if expected == "stable" else radius is None
    assert set(result.to_dict()["actuator"]) == {"zero", "hold", "buffer:3"}


def test_without_actuator_the_result_and_its_json_are_as_before():
    result = allocate(SCALAR, "tcp", 3.5, [1.0])
    assert result.actuator == ()
    assert "actuator" not in result.to_dict()


@pytest.mark.parametrize("spec", ["drop", "buffer:4", 3])
def test_a_bad_strategy_is_an_input_error_before_any_work(spec):
    with pytest.raises(InputError, match="actuator"):
        allocate(SCALAR, "tcp", 3.5, [1.0], actuator=spec)
