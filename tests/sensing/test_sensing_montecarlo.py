"""The Monte Carlo expected covariance of sensing.montecarlo.simulate_estimated has its own standard error (per
entry and for the trace, from the runs' own means over the kept steps): the exact enumeration
(sensing.kalman.expected_covariance) lies within a few of them, and another link's enumeration does not."""

import numpy as np
import pytest

from packetloss_cvx.closedloop.riccati import dp_riccati
from packetloss_cvx.model.sensor import Sensor
from packetloss_cvx.model.system import System
from packetloss_cvx.sensing.kalman import expected_covariance
from packetloss_cvx.sensing.montecarlo import simulate_estimated

CHAIN = {"model": "gilbert-elliott", "p": [0.1], "r": [0.25], "h_good": [0.95], "h_bad": [0.15]}


def plant(sensor: Sensor) -> System:
    return System(A=[[1.15, 0.3], [0.0, 0.85]], B=[[0.0], [1.0]], horizon=5, state_weight=[1.0, 1.0],
                  input_weight=[0.5], mu=[0.8], x0=[0.0, 0.0], noise_cov=[[0.2, 0.05], [0.05, 0.1]], sensor=sensor)


@pytest.mark.parametrize("link", ["bernoulli", "gilbert-elliott"])
def test_the_enumeration_lies_within_the_sampled_covariance_standard_errors(link):
    kw = {"gamma": [0.6]} if link == "bernoulli" else {"channel": CHAIN}
    sensor = Sensor(C=[[1.0, 0.0]], noise_cov=[[0.1]], P0=np.eye(2), **kw)
    s = plant(sensor)
    steps = 14                                              # kept: steps 7..13 (the second half), 2^14 paths
    run = simulate_estimated(s, dp_riccati(s).gain, "tcp", "kalman", samples=3000, steps=steps, seed=5)
    exact = expected_covariance(s.A, s.noise_cov, sensor, steps).filtered[steps - steps // 2:].mean(axis=0)
    assert run.mean_filtered_covariance_stderr.shape == (2, 2)
    assert np.all(run.mean_filtered_covariance_stderr > 0)
    z = (run.mean_filtered_covariance - exact) / run.mean_filtered_covariance_stderr
    assert np.all(np.abs(z) < 4.5)
    assert abs(np.trace(run.mean_filtered_covariance) - np.trace(exact)) < 4 * run.mean_filtered_trace_stderr
    assert run.to_dict()["mean_filtered_trace_stderr"] == run.mean_filtered_trace_stderr
    other = Sensor(C=[[1.0, 0.0]], noise_cov=[[0.1]], P0=np.eye(2), gamma=[0.3])        # another link: far away
    wrong = expected_covariance(s.A, s.noise_cov, other, steps).filtered[steps - steps // 2:].mean(axis=0)
    assert abs(np.trace(run.mean_filtered_covariance) - np.trace(wrong)) > 8 * run.mean_filtered_trace_stderr


def test_the_stationary_filter_has_no_covariance_nor_its_standard_error():
    s = plant(Sensor(C=[[1.0, 0.0]], noise_cov=[[0.1]], gamma=[0.8]))
    run = simulate_estimated(s, dp_riccati(s).gain, "tcp", "stationary", samples=20, steps=4)
    assert np.all(np.isnan(run.mean_filtered_covariance_stderr))
    assert run.to_dict()["mean_filtered_trace_stderr"] is None
