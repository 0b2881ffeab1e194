"""The burstiness sweep at fixed average delivery rates."""

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.model.twins import bursty_twin
from packetloss_cvx.montecarlo.markov_channels import sample_markov_plan_costs
from packetloss_cvx.qp.markov import exact_qp
from packetloss_cvx.studies.burstiness import burstiness_sweep


def test_sweep_of_the_two_actuator_system():
    s = pl.load_example("two_actuator")
    lams = [0.0, 0.5, 0.9]
    sweep = burstiness_sweep(s, lams, progress=False)
    np.testing.assert_array_equal(sweep.correlation, lams)
    np.testing.assert_allclose(sweep.rate, [0.9, 0.5])
    # memoryless: both exact minima are the paper's Bernoulli minima (the closed form on mu)
    for protocol in ("tcp", "udp"):
        assert sweep.exact[protocol][0] == pytest.approx(pl.closed_form(s, protocol).cost, rel=1e-10)
        assert np.all(sweep.plugin[protocol] >= sweep.exact[protocol] * (1 - 1e-9))
    np.testing.assert_allclose(sweep.plugin["tcp"], sweep.exact["tcp"], rtol=1e-9)   # only mu_t enters
    assert sweep.plugin["udp"][2] > sweep.exact["udp"][2] * 1.2                        # 27 % at lambda = 0.9
    # the exact minimum at lambda = 0.9 against the QP twin and against sampling of the chain
    twin = bursty_twin(s, 0.9)
    qp = exact_qp(twin, cross_check=False)
    assert qp.cost == pytest.approx(sweep.exact["udp"][2], rel=1e-7)
    costs = sample_markov_plan_costs(twin, qp.inputs, 40_000, np.random.default_rng(2))
    assert abs(costs.mean() - sweep.exact["udp"][2]) <= 4 * costs.std(ddof=1) / np.sqrt(costs.size)
    data = json.loads(json.dumps(sweep.to_dict()))
    assert set(data) == {"correlation", "rate", "plugin", "exact"}
    with pytest.raises(ValueError, match="read-only"):
        sweep.exact["udp"][0] = 0.0


@pytest.mark.parametrize("bad", [[1.0], [np.nan], "0.5", [], [["x"]], [0.5, 1.5]])
def test_sweep_refuses_bad_correlations(bad):
    with pytest.raises(pl.InputError, match="correlations"):
        burstiness_sweep(pl.load_example("two_actuator"), bad, progress=False)


def test_negative_correlation_beyond_the_rates_is_refused():
    with pytest.raises(pl.InputError, match=r"correlation: lambda = -0.5 needs p or r above 1"):
        burstiness_sweep(pl.load_example("two_actuator"), [-0.5], progress=False)
