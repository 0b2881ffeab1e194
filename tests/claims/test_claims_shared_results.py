"""Results the audit's claims share within one run (claims.context.Context.dp): the DP optimum of each case is
solved once, for mpc-vs-dp and cost-split-sensor. References: the same quantities solved afresh on each system
(dp_riccati on the sensed twin itself), compared bit for bit, and a hand value."""

import numpy as np
import pytest

from packetloss_cvx import System
from packetloss_cvx.claims import sensing as sensing_claim
from packetloss_cvx.claims.context import Context
from packetloss_cvx.claims.mpc_vs_dp import relative_excess
from packetloss_cvx.closedloop.riccati import NO_SOLUTION
from packetloss_cvx.errors import NumericalError
from packetloss_cvx.model.random_systems import random_system


def cases(k=12):
    rng = np.random.default_rng(7)
    return [random_system(rng) for _ in range(k)]


def test_a_cases_dp_is_solved_once_and_its_error_raised_again():
    ok = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    none = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    ctx = Context(paper={}, random=[ok, none], seed=0)
    first = ctx.dp(ok)
    assert ctx.dp(ok) is first
    assert first.cost_to_go[0, 0] == pytest.approx(1 + 3**0.5, rel=1e-12)     # P = 1 + P - P^2 / (2 (1 + P))
    for _ in range(2):                      # mu = 1/2 < 1 - 1/a^2 = 3/4: no law holds the second moment
        with pytest.raises(NumericalError, match=NO_SOLUTION):
            ctx.dp(none)
    other = ok.with_mu([0.9])               # not a case: solved afresh, never kept
    assert ctx.dp(other) is not ctx.dp(other)
    assert id(other) not in ctx.riccati


@pytest.mark.parametrize("k", range(12))
def test_the_sensing_claims_split_with_the_shared_dp_is_the_one_solved_on_the_twin(k):
    ctx = Context(paper={}, random=cases(), seed=0)
    s = ctx.random[k]
    shared, own = sensing_claim._split(s, ctx.dp), sensing_claim._split(s)
    assert (shared is None) == (own is None)
    if own is None:
        return
    assert shared[:3] == own[:3]
    assert shared[5] == own[5]
    a, b = shared[4], own[4]
    np.testing.assert_array_equal(a.gain, b.gain)
    np.testing.assert_array_equal(a.cost_to_go, b.cost_to_go)
    assert a.average_stage_cost == b.average_stage_cost == float(np.sum(b.cost_to_go * own[3].noise_cov))
    assert (a.spectral_radius, a.iterations, a.residual) == (b.spectral_radius, b.iterations, b.residual)


@pytest.mark.parametrize("k", range(12))
def test_mpc_vs_dp_with_the_shared_dp_is_the_one_solved_afresh(k):
    ctx = Context(paper={}, random=cases(), seed=0)
    s = ctx.random[k]
    assert relative_excess(s, solve=ctx.dp) == relative_excess(s)


def test_the_sensed_twin_keeps_the_cases_initial_error_covariance():
    """A case that already has a sensor: its twin measures over the claim's link, from the case's own P0 (state.P0
    of its file), with the case's Sigma_W; only the sensor's C, gamma and R are the claim's."""
    from packetloss_cvx.model.files import load_example

    case = load_example("pendulum_sensor")
    twin = sensing_claim.sensed(case)
    assert np.any(case.sensor.P0)
    assert np.array_equal(twin.sensor.P0, case.sensor.P0)
    assert np.array_equal(twin.noise_cov, case.noise_cov)
    assert twin.sensor.gamma.tolist() == [0.9]
    assert twin.sensor.C.tolist() == np.eye(case.n)[:1].tolist()
