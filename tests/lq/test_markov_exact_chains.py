"""The exact UDP-like minimum (markov.exact_closed_form, the augmented recursion) on odd but valid k-state chains
given as ``MarkovChannel`` (absorbing, periodic, reducible with a given start, a different k per channel, channels
that always or never deliver, beliefs at the simplex corners, one-state chains, fractional deliveries), N = 1,
time-varying weights and noise: against the minimum of the enumerated expected cost (every loss pattern, no
noise), the dense second-moment route and the QP twin; unstable plants at long horizons raise NumericalError,
never inf or nan."""

import itertools

import numpy as np
import pytest

from packetloss_cvx.errors import NumericalError
from packetloss_cvx.lq.markov_cost import exact_closed_form
from packetloss_cvx.model.chain import attach_channel, chain_matrices
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.markov import exact_qp
from tests.references import enumerated_chain_cost

CHAINS = {
    "absorbing, started outside": MarkovChannel(
        transition=[[[0.7, 0.3, 0.0], [0.0, 1.0, 0.0], [0.2, 0.3, 0.5]]], delivery=[[1.0, 0.0, 0.5]], state=[0]),
    "absorbing, stationary": MarkovChannel(
        transition=[[[0.7, 0.3, 0.0], [0.0, 1.0, 0.0], [0.2, 0.3, 0.5]]], delivery=[[1.0, 0.0, 0.5]]),
    "periodic, a given state": MarkovChannel(
        transition=[[[0, 1, 0], [0, 0, 1], [1, 0, 0]]], delivery=[[1.0, 0.0, 0.5]], state=[1]),
    "periodic two-state, stationary": MarkovChannel(transition=[[[0, 1], [1, 0]]], delivery=[[1.0, 0.0]]),
    "reducible, a given belief": MarkovChannel(
        transition=[[[1, 0, 0], [0, 1, 0], [0.3, 0.3, 0.4]]], delivery=[[1.0, 0.0, 0.6]], belief=[[0.2, 0.3, 0.5]]),
    "never delivers": MarkovChannel(transition=[[[0.5, 0.5], [0.2, 0.8]]], delivery=[[0.0, 0.0]]),
    "always delivers": MarkovChannel(transition=[[[0.5, 0.5], [0.2, 0.8]]], delivery=[[1.0, 1.0]]),
    "belief at a corner": MarkovChannel(
        transition=[[[0.9, 0.1, 0.0], [0.0, 0.8, 0.2], [0.3, 0.0, 0.7]]], delivery=[[0.9, 0.3, 0.0]],
        belief=[[0.0, 0.0, 1.0]]),
    "one state": MarkovChannel(transition=[[[1.0]]], delivery=[[0.7]]),
    "identical rows": MarkovChannel(transition=[[[0.2, 0.5, 0.3]] * 3], delivery=[[1.0, 0.4, 0.0]]),
    "fractional Gilbert-Elliott": GilbertElliott(p=[0.1], r=[0.2], h_good=[0.8], h_bad=[0.3]),
    "alternating Gilbert-Elliott": GilbertElliott(p=[0.9], r=[0.8]),
    "frozen Gilbert-Elliott": GilbertElliott(p=[0.0], r=[0.0], h_good=[0.7], h_bad=[0.2], belief=[0.4]),
    "k = 1, 2, 3 over three channels": MarkovChannel(
        transition=[[[1.0]], [[0.6, 0.4], [0.3, 0.7]], [[0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5]]],
        delivery=[[0.8], [1.0, 0.1], [1.0, 0.5, 0.0]]),
}


def enumerated_minimum(s):
    """min over U of the enumerated expected cost (every joint loss pattern): a quadratic c + g'U + U'HU in the
    N m inputs, recovered from its values at 0, +-e_i and e_i + e_j and minimised by a linear solve (inputs that
    enter no term, H_ii = 0, set to 0)."""
    N, m = s.horizon, s.m
    chains = chain_matrices(s.channel)

    def f(u):
        return enumerated_chain_cost(s.A, s.B, s.state_weights, s.input_weights, s.initial_weight, s.x0, chains,
                                     np.asarray(u, float).reshape(N, m))

    size = N * m
    c, unit = f(np.zeros(size)), np.eye(size)
    plus = np.array([f(unit[i]) for i in range(size)])
    minus = np.array([f(-unit[i]) for i in range(size)])
    H, g = np.diag((plus + minus) / 2 - c), (plus - minus) / 2
    for i, j in itertools.combinations(range(size), 2):
        H[i, j] = H[j, i] = (f(unit[i] + unit[j]) - plus[i] - plus[j] + c) / 2
    active = np.diag(H) > 1e-300
    u = np.zeros(size)
    u[active] = np.linalg.solve(2 * H[np.ix_(active, active)], -g[active])
    return c + g @ u + u @ H @ u


def system_behind(name, seed, horizon, **kwargs):
    channel = CHAINS[name]
    rng = np.random.default_rng(seed)
    return attach_channel(random_system(rng, n=2, m=channel.m, horizon=horizon, **kwargs), channel)


@pytest.mark.parametrize("horizon", [1, 2, 4])
@pytest.mark.parametrize("name", sorted(CHAINS))
def test_recursion_against_the_enumerated_minimum(name, horizon):
    if CHAINS[name].m == 3 and horizon == 4:
        horizon = 3                                   # 2^(N m) patterns
    s = system_behind(name, 17 * horizon, horizon, noise=False, time_varying=True)
    recursion = exact_closed_form(s, "udp", method="recursion").cost
    assert recursion == pytest.approx(enumerated_minimum(s), rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("name", sorted(CHAINS))
def test_recursion_against_the_dense_route_and_the_qp_twin_with_noise(name):
    s = system_behind(name, 5, 12, noise=True, time_varying=True)
    recursion = exact_closed_form(s, "udp", method="recursion")
    dense = exact_closed_form(s, "udp", method="dense")
    assert recursion.cost == pytest.approx(dense.cost, rel=1e-10)
    np.testing.assert_allclose(recursion.inputs, dense.inputs, rtol=1e-8, atol=1e-10 * np.abs(dense.inputs).max())
    assert exact_qp(s, "udp").cost == pytest.approx(recursion.cost, rel=1e-7)


@pytest.mark.parametrize(("radius", "horizon"), [(1.5, 2000), (1.2, 5000), (3.0, 700)])
def test_unstable_plant_beyond_the_double_range_raises(radius, horizon):
    s = random_system(np.random.default_rng(5), n=2, m=1, horizon=horizon, spectral_radius=radius)
    s = attach_channel(s, GilbertElliott(p=[0.05], r=[0.3]))
    with pytest.raises(NumericalError, match="shorten the horizon"):
        exact_closed_form(s, "udp")


def test_unstable_plant_just_inside_the_double_range_matches_the_dense_route():
    s = random_system(np.random.default_rng(5), n=2, m=1, horizon=300, spectral_radius=1.5, noise=False)
    s = attach_channel(s, GilbertElliott(p=[0.05], r=[0.3]))
    recursion = exact_closed_form(s, "udp", method="recursion").cost
    assert 1e100 < recursion < np.inf
    assert recursion == pytest.approx(exact_closed_form(s, "udp", method="dense").cost, rel=1e-10)
