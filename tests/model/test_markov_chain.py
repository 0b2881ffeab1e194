"""Prediction from Gilbert–Elliott chains: R = E[v v'] against path enumeration (matrix powers of
the transition matrix) and against sampled deliveries; the HMM filter against Bayes' rule on the
joint distribution; plug-in schedules for both protocols."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.errors import InputError
from packetloss_cvx.model.chain import (
    attach_channel,
    channel_covariance,
    filter_belief,
    plugin_schedule,
    plugin_system,
    second_moments,
    stacked_moments,
)
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.montecarlo.markov_channels import sample_markov_deliveries, sample_states
from packetloss_cvx.tolerances import ROUNDING_ORDER_RTOL


def moments_by_enumeration(p, r, hg, hb, b0, N):
    """E[v_t v_s] = pi_0 P^t D P^(s-t) h for t < s (D = diag(h)), E[v_t] = pi_0 P^t h: no closed form used."""
    P = np.array([[1 - p, p], [r, 1 - r]])
    h = np.array([hg, hb])
    pi0 = np.array([b0, 1 - b0])
    R = np.empty((N, N))
    power = [np.linalg.matrix_power(P, k) for k in range(N)]      # P^k, each power computed once
    for t in range(N):
        for s in range(N):
            lo, hi = min(t, s), max(t, s)
            left = pi0 @ power[lo]
            R[t, s] = left @ h if t == s else left @ np.diag(h) @ power[hi - lo] @ h
    return R


def random_channel(rng, m, given=True):
    kwargs = {"p": rng.uniform(0, 1, m), "r": rng.uniform(0.01, 1, m), "h_good": rng.uniform(0.5, 1, m),
              "h_bad": rng.uniform(0, 0.5, m)}
    if given:
        kwargs["belief"] = rng.uniform(0, 1, m)
    return GilbertElliott(**kwargs)


@pytest.mark.parametrize("seed", range(6))
def test_second_moments_match_path_enumeration(seed):
    rng = np.random.default_rng(seed)
    ch = random_channel(rng, 2, given=seed % 2 == 0)
    N = 7
    R = second_moments(ch, N)
    for i in range(2):
        ref = moments_by_enumeration(ch.p[i], ch.r[i], ch.h_good[i], ch.h_bad[i], ch.initial_belief[i, 0], N)
        np.testing.assert_allclose(R[i], ref, rtol=1e-12, atol=1e-15)


def test_second_moments_match_sampled_deliveries():
    ch = GilbertElliott(p=[0.05, 0.4], r=[0.15, 0.3], h_good=[1.0, 0.9], h_bad=[0.0, 0.2], belief=[0.3, 1.0])
    N, S = 5, 200_000
    v = sample_markov_deliveries(ch, N, S, np.random.default_rng(7)).astype(float)
    R = second_moments(ch, N)
    for i in range(2):
        prod = v[:, :, i, None] * v[:, None, :, i]               # (S, N, N)
        mean = prod.mean(axis=0)
        se = prod.std(axis=0, ddof=1) / np.sqrt(S)
        assert np.all(np.abs(mean - R[i]) <= 4 * se), np.max(np.abs(mean - R[i]) / se)


def test_states_sample_the_chain():
    ch = GilbertElliott(p=[0.2], r=[0.1], state=["good"])
    S = 100_000
    good = sample_states(ch, 3, S, np.random.default_rng(3))[:, :, 0] == 0          # state 0: good
    assert good[:, 0].all()
    frac = good[:, 1].mean()
    assert abs(frac - 0.8) <= 4 * np.sqrt(0.8 * 0.2 / S)
    pair = (good[:, 1] & good[:, 2]).mean()                     # P(good, good) = 0.8 * 0.8
    assert abs(pair - 0.64) <= 4 * np.sqrt(0.64 * 0.36 / S)


def test_filter_is_bayes_on_the_joint_distribution():
    rng = np.random.default_rng(11)
    ch = random_channel(rng, 3)
    b = np.array([0.2, 0.5, 0.9])
    for outcome in ([True, False, True], [False, True, False]):
        got = filter_belief(ch, np.column_stack([b, 1 - b]), outcome)
        np.testing.assert_allclose(got.sum(axis=1), 1.0, rtol=1e-15)
        for i in range(3):
            # joint over (S_t, S_{t+1}) with the observation at t: enumerate the four pairs
            P = np.array([[1 - ch.p[i], ch.p[i]], [ch.r[i], 1 - ch.r[i]]])
            like = np.array([ch.h_good[i], ch.h_bad[i]]) if outcome[i] else 1 - np.array([ch.h_good[i], ch.h_bad[i]])
            joint = np.array([b[i], 1 - b[i]])[:, None] * like[:, None] * P
            assert got[i, 0] == pytest.approx(joint[:, 0].sum() / joint.sum(), rel=1e-13)


def test_gilbert_acknowledgement_reveals_the_state():
    ch = GilbertElliott(p=[0.1, 0.25], r=[0.3, 0.4])
    got = filter_belief(ch, [[0.37, 0.63], [0.61, 0.39]], [True, False])
    np.testing.assert_allclose(got, [[0.9, 0.1], [0.4, 0.6]], rtol=1e-15)
    with pytest.raises(pl.InputError, match="delivered: channel 0: outcome delivered has probability 0"):
        filter_belief(ch, [[0.0, 1.0], [0.5, 0.5]], [True, True])


def test_plugin_schedules_per_protocol():
    ch = GilbertElliott(p=[0.1], r=[0.3], belief=[0.5])
    history = [[True], [False], [False]]
    tcp, b_tcp = plugin_schedule(ch, 4, "tcp", history)
    udp, b_udp = plugin_schedule(ch, 4, "udp", history)
    assert b_tcp[0, 0] == pytest.approx(0.3)                        # the last loss revealed "bad"
    np.testing.assert_allclose(b_udp[0], ch.beliefs(4)[3, 0])       # the prior, three steps on
    np.testing.assert_allclose(tcp[:, 0], ch.delivery_schedule(4, np.array([[0.3, 0.7]]))[:, 0])
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=4, state_weight=[1.0], input_weight=[1.0], x0=[1.0], channel=ch)
    np.testing.assert_allclose(plugin_system(s, "tcp", history).mu_schedule, tcp, rtol=1e-15)
    with pytest.raises(pl.InputError, match="protocol"):
        plugin_schedule(ch, 4, "quic")


def test_memoryless_moments_are_bernoulli():
    s = pl.load_example("two_actuator")
    g = attach_channel(s, GilbertElliott(p=[0.1, 0.5], r=[0.9, 0.5]))
    np.testing.assert_allclose(g.mu_schedule, s.mu_schedule, rtol=1e-15)
    v, C = stacked_moments(g)
    v_ref, C_ref = stacked_moments(s)
    np.testing.assert_allclose(v, v_ref, rtol=ROUNDING_ORDER_RTOL)         # the chain's marginals, Bernoulli's mu
    np.testing.assert_allclose(C, C_ref, rtol=0, atol=1e-16)


@pytest.mark.parametrize(("call", "field"), [
    (lambda ch: plugin_schedule(ch, 10**9, "udp"), "horizon"),     # allocated 8 GB, then looped
    (lambda ch: channel_covariance(ch, 10**5), "horizon"),         # 80 GB
    (lambda ch: second_moments(ch, 0), "horizon"),                 # an empty array
    (lambda ch: channel_covariance(ch, -3), "horizon"),
    (lambda ch: filter_belief(ch, [[1.5, -0.5]], [True]), "belief"),      # answered 0.98
    (lambda ch: filter_belief(ch, [[0.5, 0.5]], [0.5]), "delivered"),     # half a packet: delivered?
    (lambda ch: plugin_schedule(ch, 5, "tcp", acknowledged=[[2]]), "delivered"),
    (lambda ch: ch.beliefs(3, belief=[2.0]), "belief"),
])
def test_chain_functions_refuse_what_they_cannot_mean(call, field):
    channel = pl.load_example("pendulum_bursty").channel
    with pytest.raises(InputError) as err:
        call(channel)
    assert err.value.field == field
