"""Samples near or beyond the double range (montecarlo.runs): an error bar computed without overflowing its squares,
and none, with its reason, where the spread itself is not finite; never a z-score against a missing error bar."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo.runs import open_loop_checks, sample_stats, z_score
from packetloss_cvx.montecarlo.simulate import simulate
from packetloss_cvx.tolerances import SAMPLED_Z_MAX


def test_the_standard_error_of_costs_near_the_double_range_is_computed():
    # 1, 2, 3, 4 times 1e200: variance (ddof 1) 5/3 times 1e400, whose squares overflow if formed as they are
    mean, stderr = sample_stats(np.array([1.0, 2.0, 3.0, 4.0]) * 1e200)
    assert np.isclose(mean, 2.5e200, rtol=1e-15)
    assert np.isclose(stderr, (5 / 3) ** 0.5 / 2 * 1e200, rtol=1e-15)


def test_an_open_loop_plan_of_an_exploding_plant_gets_its_error_bar_and_z():
    # x+ = 3 x over 200 steps, mu = 0.1: plan costs about 1e191, whose squares overflow
    s = System(A=[[3.0]], B=[[1.0]], horizon=200, state_weight=[1.0], input_weight=[1.0], mu=[0.1], x0=[1.0])
    sim = simulate(s, 200, laws=("tcp", "udp"))
    for check in sim.open_loop.values():
        assert check.exact > 1e188
        assert np.isfinite(check.stderr)
        assert check.stderr > 0
        assert abs(check.z) <= SAMPLED_Z_MAX
        assert check.z == (check.mean - check.exact) / check.stderr


def test_no_z_score_against_a_spread_that_is_not_finite():
    assert np.isnan(z_score(4.7e191, np.inf, 5.7e191))
    assert np.isnan(z_score(np.inf, 1.0, 2.0))
    assert z_score(3.0, 0.5, 2.0) == 2.0


def test_a_sample_whose_spread_is_not_finite_has_no_error_bar_and_says_why():
    plan = SimpleNamespace(inputs=np.zeros((1, 1)), cost=1.0)
    checks = open_loop_checks({"tcp": plan}, [3], [np.random.SeedSequence(0)], lambda size, rng: None,
                              lambda inputs, draws: np.array([1.0, np.inf, 2.0]), lambda inputs: 2.0,
                              SimpleNamespace(update=lambda k: None))
    out = checks["tcp"].to_dict()
    assert out["stderr"] is None
    assert out["z"] is None
    assert out["stderr_reason"].startswith("no error bar: the sampled costs' spread exceeds the double range")
