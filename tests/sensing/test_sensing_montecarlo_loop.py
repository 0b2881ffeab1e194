"""sensing.montecarlo.simulate_estimated against the plain loop it was written as (the run's noise factors
computed once, a shared or empty arrival pattern updated without a gather and scatter, the prediction A P A' as
one product by A'): the same random draws, and the same values up to the order of the floating-point operations
(tolerances.ROUNDING_ORDER_RTOL), for both filters and protocols, one and two sensor channels. The loop below is
the reference: every step factors its noise, updates each pattern's runs by gathering them, and predicts with the
stacked ``A @ P @ A.T``."""

import numpy as np
import pytest

from packetloss_cvx import System
from packetloss_cvx.closedloop.moments import stationary_channel
from packetloss_cvx.closedloop.riccati import dp_riccati
from packetloss_cvx.linalg import psd_factor
from packetloss_cvx.model.sensor import Sensor
from packetloss_cvx.sensing.arrivals import arrival_patterns
from packetloss_cvx.sensing.kalman import actuation_covariance, measurement_update, pattern_rows
from packetloss_cvx.sensing.loop import filter_gains
from packetloss_cvx.sensing.montecarlo import simulate_estimated
from packetloss_cvx.tolerances import ROUNDING_ORDER_RTOL


def assert_same_to_rounding(actual, desired):
    """Two orders of one computation: within ROUNDING_ORDER_RTOL of the largest entry (tolerances.py)."""
    desired = np.asarray(desired)
    np.testing.assert_allclose(actual, desired, rtol=0, atol=ROUNDING_ORDER_RTOL * np.abs(desired).max(initial=0.0))


def noise(rng, cov, samples):
    factor = psd_factor(cov)
    if factor.shape[0] == 0:
        return np.zeros((samples, cov.shape[0]))
    return rng.standard_normal((samples, factor.shape[0])) @ factor


def plain_loop(system, K, protocol, filter, samples, steps, seed):  # noqa: A002
    n, m, sensor = system.n, system.m, system.sensor
    mu = stationary_channel(system)
    A, B, C, W, R = system.A, system.B, sensor.C, system.noise_cov, sensor.noise_cov
    Omega, psi = system.state_weights[0], system.input_weights[0]
    arrived, _ = arrival_patterns(sensor.gamma)
    rows = [pattern_rows(sensor, a) for a in arrived]
    digits = 2 ** np.arange(sensor.g - 1, -1, -1)
    gains = filter_gains(system)[1] if filter == "stationary" else None
    rng = np.random.default_rng(seed)
    x = system.x0 + noise(rng, sensor.P0, samples)
    xm = np.broadcast_to(system.x0, (samples, n)).copy()
    Pm = np.broadcast_to(sensor.P0, (samples, n, n)).copy()
    keep, total, covariance = steps // 2, np.zeros(samples), np.zeros((n, n))
    for k in range(steps):
        a = rng.random((samples, sensor.g)) < sensor.gamma
        y = x @ C.T + noise(rng, R, samples)
        pattern = a @ digits
        if filter == "kalman":
            P, L = np.empty_like(Pm), np.zeros((samples, n, sensor.p))
            for j, r in enumerate(rows):
                sel = pattern == j
                if np.any(sel):
                    P[sel], L[sel] = measurement_update(Pm[sel], C, R, r)
        else:
            L = gains[pattern]
        xhat = xm + np.einsum("sij,sj->si", L, y - xm @ C.T)
        u = -xhat @ K.T
        applied = (rng.random((samples, m)) < mu) * u
        stage = np.einsum("si,ij,sj->s", x, Omega, x) + (applied * applied) @ psi
        if k >= steps - keep:
            total += stage
            if filter == "kalman":
                covariance += P.sum(axis=0)
        x = x @ A.T + applied @ B.T + noise(rng, W, samples)
        xm = xhat @ A.T + (applied if protocol == "tcp" else mu * u) @ B.T
        if filter == "kalman":
            Pm = A @ P @ A.T + W
            if protocol == "udp":
                Pm += actuation_covariance(B, mu, u)
    means = total / keep
    return float(means.mean()), float(means.std(ddof=1) / np.sqrt(samples)), covariance / (keep * samples)


def plant(seed, n, gamma, groups=None, P0=None):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 0.95 / np.max(np.abs(np.linalg.eigvals(A)))
    p = 1 if groups is None else sum(len(g) for g in groups)
    sensor = Sensor(C=rng.normal(size=(p, n)), gamma=list(gamma), groups=groups, noise_cov=0.05 * np.eye(p),
                    P0=np.eye(n) if P0 is None else P0)
    return System(A=A, B=rng.normal(size=(n, 2)), horizon=3, state_weight=rng.uniform(0.5, 2, n),
                  input_weight=rng.uniform(0.5, 2, 2), mu=[0.8, 0.6], x0=rng.normal(size=n),
                  noise_cov=0.1 * np.eye(n), sensor=sensor)


CASES = [plant(0, 2, (0.9,)), plant(1, 4, (0.7,)), plant(2, 3, (0.8, 0.5), groups=[[0], [1]]),
         plant(3, 3, (1.0,)), plant(4, 2, (0.6,), P0=np.zeros((2, 2)))]


@pytest.mark.parametrize("case", range(len(CASES)))
@pytest.mark.parametrize(("protocol", "filter"), [("tcp", "kalman"), ("udp", "kalman"), ("tcp", "stationary")])
def test_the_run_is_the_plain_loop(case, protocol, filter):  # noqa: A002
    s = CASES[case]
    K = dp_riccati(s).gain
    got = simulate_estimated(s, K, protocol, filter, samples=300, steps=40, seed=case)
    mean, stderr, covariance = plain_loop(s, K, protocol, filter, samples=300, steps=40, seed=case)
    assert_same_to_rounding(got.mean_stage_cost, mean)
    assert_same_to_rounding(got.stderr, stderr)
    if filter == "kalman":
        assert_same_to_rounding(got.mean_filtered_covariance, covariance)


@pytest.mark.parametrize("split", [
    (50, 50, 0, 0),      # two patterns with half the runs each: both "shared by most runs"
    (0, 0, 50, 50),
    (10, 60, 20, 10),    # one pattern shared by most runs, the others scattered
    (100, 0, 0, 0),      # nothing received anywhere
    (25, 25, 25, 25),    # no pattern shared by most runs
])
def test_pattern_update_is_each_patterns_gathered_update(split):
    """pattern_update (a shared pattern computed for every run and the others written in place) against the
    update of each pattern's runs gathered, as the plain loop above does it: the same values to rounding
    (ROUNDING_ORDER_RTOL, each run at its own scale), whatever the split; a run that received nothing keeps P^-
    exactly and a zero gain."""
    from packetloss_cvx.sensing.montecarlo import pattern_update

    s = CASES[2]                                  # two sensor channels: four arrival patterns
    sensor, rng = s.sensor, np.random.default_rng(7)
    arrived, _ = arrival_patterns(sensor.gamma)
    rows = [pattern_rows(sensor, a) for a in arrived]
    pattern = rng.permutation(np.repeat(np.arange(4), split))
    F = rng.normal(size=(100, 3, 3))
    Pm = F @ F.swapaxes(1, 2) + 0.1 * np.eye(3)
    P, L = pattern_update(Pm, pattern, rows, sensor.C, sensor.noise_cov)
    want_P, want_L = Pm.copy(), np.zeros((100, 3, sensor.p))
    for j, r in enumerate(rows):
        sel = pattern == j
        if np.any(sel):
            want_P[sel], want_L[sel] = measurement_update(Pm[sel], sensor.C, sensor.noise_cov, r)
    for k in range(len(Pm)):
        assert_same_to_rounding(P[k], want_P[k])
        assert_same_to_rounding(L[k], want_L[k])
    nothing = pattern == 0                       # pattern 0: no channel arrived
    assert np.array_equal(P[nothing], Pm[nothing])
    assert not L[nothing].any()
