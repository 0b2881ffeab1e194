"""tcp-prior-mean-chain (claims/chain_tcp.py): the paper's TCP-like cost at a chain's prior mean rates bounds the
attainable TCP-like cost behind the chain in neither direction: it lies below it by large factors, and above it
where there is process noise (without noise it is below on every case checked, hidden chains included).

Independent references: the attainable cost by the brute-force DP over delivery histories (probabilities summed over
hidden paths) of tests/closedloop/test_chain_dp.py; the paper's J*_tcp at the mean rates by the closed form on a
Bernoulli system written here with those rates (not through the chain).
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from packetloss_cvx import System, closed_form
from packetloss_cvx.claims import CLAIMS
from packetloss_cvx.claims.chain_tcp import noise_free, prior_mean_ratio, tcp_prior_mean_chain
from packetloss_cvx.claims.context import Context
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

sys.path.insert(0, str(Path(__file__).parents[1] / "closedloop"))
from test_chain_dp import brute_force_dp  # noqa: E402


def reported_at_mean(system):
    """The paper's J*_tcp on the same plant with independent losses at the chain's mean rates (``with_mu`` drops
    the chain)."""
    bernoulli = system.with_mu(system.channel.mean_rate)
    assert bernoulli.channel is None
    return closed_form(bernoulli, "tcp").cost


def small_case(rng):
    """A seeded small plant behind a Gilbert channel (burstiness 0.5 or 0.9) or a hidden two-state chain."""
    n, N = int(rng.integers(1, 3)), int(rng.integers(2, 5))
    mu = rng.uniform(0.3, 0.95)
    kind = rng.integers(3)
    if kind < 2:
        lam = (0.5, 0.9)[kind]
        channel = GilbertElliott(p=[(1 - mu) * (1 - lam)], r=[mu * (1 - lam)])
    else:
        channel = MarkovChannel(transition=[rng.dirichlet([2.0, 2.0], size=2)], delivery=[[0.9, 0.2]])
    return System(A=rng.normal(size=(n, n)) * rng.uniform(0.6, 1.5), B=rng.normal(size=(n, 1)), horizon=N,
                  state_weight=rng.uniform(0.5, 2.0, n), input_weight=[float(rng.choice([0.05, 0.5, 2.0]))],
                  x0=rng.normal(size=n), noise_cov=0.1 * np.eye(n) if rng.uniform() < 0.5 else None,
                  channel=channel)


def test_the_ratio_is_on_both_sides_of_one_on_seeded_small_chains():
    """40 seeded small cases (Gilbert and hidden chains, half with process noise): the claim's ratio against the
    brute-force DP and the Bernoulli closed form; ratios below and above 1 (not a bound in either direction), those
    above 1 all with process noise: without it the reported value is below the attainable one on every case."""
    rng = np.random.default_rng(35)
    noisy, quiet = [], []
    for _ in range(40):
        s = small_case(rng)
        reference = reported_at_mean(s) / brute_force_dp(s)
        assert prior_mean_ratio(s) == pytest.approx(reference, rel=PATH_AGREEMENT_RTOL)
        (noisy if np.any(s.noise_cov) else quiet).append(reference)
        q = noise_free(s)
        assert not np.any(q.noise_cov)
        quiet.append(reported_at_mean(q) / brute_force_dp(q))
    ratios = noisy + quiet
    assert min(ratios) < 0.9
    assert max(noisy) > 1.1
    assert max(quiet) <= 1 + PATH_AGREEMENT_RTOL


def test_the_claim_fails_on_random_systems_and_its_counterexample_is_confirmed_by_brute_force():
    rng = np.random.default_rng(1)
    cases = [random_system(rng) for _ in range(12)]
    result = tcp_prior_mean_chain(Context(paper={}, random=cases, seed=1))
    assert result.verdict == "fails"
    assert "Without process noise:" in result.note
    counterexample = system_from_dict(result.counterexample)
    assert counterexample.horizon * counterexample.m <= 8          # small enough to enumerate
    assert np.any(counterexample.noise_cov)                       # the violations are the noise's
    assert reported_at_mean(counterexample) > brute_force_dp(counterexample) * (1 + 1e-6)
    assert CLAIMS["tcp-prior-mean-chain"][1] is tcp_prior_mean_chain


def test_a_memoryless_chain_keeps_the_independent_losses_bound_without_noise():
    """lambda = 0 (p + r = 1): the deliveries are i.i.d. at mu and the acknowledgements tell the law nothing ahead,
    so without process noise the first-moment value is below the attainable one, as for independent losses."""
    rng = np.random.default_rng(7)
    for _ in range(6):
        s = noise_free(small_case(rng))
        mu = float(rng.uniform(0.2, 0.9))
        s = s.with_channel(GilbertElliott(p=[1 - mu], r=[mu]))
        assert reported_at_mean(s) <= brute_force_dp(s) * (1 + PATH_AGREEMENT_RTOL)
        assert prior_mean_ratio(s) <= 1 + PATH_AGREEMENT_RTOL
