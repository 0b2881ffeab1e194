"""expected_cost against sampled losses and noise (seeded)."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.montecarlo import sample_plan_costs
from packetloss_cvx.prediction import prediction

SAMPLES = 200_000


@pytest.fixture(scope="module")
def small():
    return pl.System(
        A=[[1.1, 0.2], [0.0, 0.9]], B=[[1.0, 0.0], [0.5, 1.0]], horizon=4,
        state_weight=[[2.0, 0.3], [0.3, 1.0]], input_weights=[[1.0, 0.5], [0.8, 1.0], [1.0, 1.0], [2.0, 0.4]],
        mu_schedule=[[0.9, 0.3], [0.6, 0.5], [0.8, 0.2], [0.95, 0.7]], x0=[1.0, -1.0],
        initial_weight=[0.5, 0.5], noise_cov=[[0.05, 0.01], [0.01, 0.02]],
    )


@pytest.fixture(scope="module")
def sampled(small):
    U = pl.closed_form(small, "udp").inputs
    costs = sample_plan_costs(small, U, SAMPLES, np.random.default_rng(20261121))
    return U, costs.mean(), costs.std(ddof=1) / np.sqrt(SAMPLES)


def test_udp_expected_cost_matches_sampling(small, sampled):
    U, mean, se = sampled
    assert abs(mean - pl.expected_cost(small, U, "udp")) < 4 * se


def test_tcp_definition_differs_from_sampling_by_the_variance_term(small, sampled):
    """J_tcp(U) is not E[cost] of the plan U: it drops U' Vbar Omega_d (I - Vbar) U.

    docs/claims.md, expected-cost-tcp: eq:TCP-prediction-error conditions on the
    future losses, so the loss variance never enters the TCP-like cost.
    """
    U, mean, se = sampled
    pred = prediction(small)
    u, v = U.ravel(), pred.Vbar
    variance_term = float(np.sum(u * v * pred.Omega_d * (1 - v) * u))
    gap = mean - pl.expected_cost(small, U, "tcp")
    assert abs(gap - variance_term) < 4 * se
    assert variance_term > 20 * se  # the difference is real, not sampling noise
