"""expected_cost against sampled losses and noise (seeded)."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.lq.prediction import prediction
from packetloss_cvx.montecarlo.channels import sample_deliveries, sample_noise
from packetloss_cvx.montecarlo.sampling import sample_plan_costs

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


def test_sample_deliveries_have_the_channel_frequencies(small):
    """Each entry of Upsilon is delivered with probability mu_{t,i}, in the order of Vbar (t major)."""
    samples = 100_000
    Y = sample_deliveries(small, samples, np.random.default_rng(7))
    assert Y.shape == (samples, small.horizon * small.m)
    assert Y.dtype == bool
    mu = np.array([0.9, 0.3, 0.6, 0.5, 0.8, 0.2, 0.95, 0.7])  # the fixture's schedule, row by row
    se = np.sqrt(mu * (1 - mu) / samples)
    assert np.all(np.abs(Y.mean(axis=0) - mu) < 4 * se)
    # independence across entries: the sample correlation of two channels at one step is ~0
    assert abs(np.corrcoef(Y[:, 0], Y[:, 1])[0, 1]) < 4 / np.sqrt(samples)


def test_sample_deliveries_at_the_edges(small):
    edge = small.with_mu([1.0, 0.0])
    Y = sample_deliveries(edge, 1000, np.random.default_rng(0))
    assert Y[:, 0::2].all()
    assert not Y[:, 1::2].any()


def test_sample_noise_has_the_stated_covariance(small):
    """Blocks W_t ~ N(0, Sigma_W), independent across steps: covariance kron(I_N, Sigma_W)."""
    samples = 200_000
    W = sample_noise(small, samples, np.random.default_rng(11))
    assert W.shape == (samples, small.horizon * small.n)
    expected = np.kron(np.eye(small.horizon), [[0.05, 0.01], [0.01, 0.02]])  # the fixture's noise_cov
    cov = W.T @ W / samples
    sd = np.sqrt(np.outer(np.diag(expected), np.diag(expected)) + expected**2)  # sd of x_i x_j for Gaussians
    assert np.all(np.abs(cov - expected) < 5 * sd / np.sqrt(samples))
    assert np.all(np.abs(W.mean(axis=0)) < 5 * np.sqrt(np.diag(expected) / samples))


def test_sample_noise_is_zero_without_noise():
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    assert np.array_equal(sample_noise(s, 5, np.random.default_rng(0)), np.zeros((5, 3)))
