"""Verdicts on the loop that runs: a chain state the start never reaches decides no radius, Riccati solution,
region or certificate (model.chain.reachable_modes behind closedloop.mjls, markov_region, certificates).

References: the deterministic loop's (a - K)^2 and the scalar DARE by hand (trap: p = 0 from good); for a
three-state chain whose third state is transient and unreached, the 2×2 second-moment operator written by hand
over the two states met, the exact stage costs enumerated over every path of states and deliveries, and the
mode-dependent law's sampled loop (seeded, z-test)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from packetloss_cvx.closedloop.certificates import exact_transition
from packetloss_cvx.closedloop.law_stability import loop_stability
from packetloss_cvx.closedloop.markov_region import chain_critical_rate, chain_least_radius, chain_membership
from packetloss_cvx.closedloop.mjls import coupled_riccati, jump_law_stage_costs, mean_square_radius
from packetloss_cvx.errors import NumericalError
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo.markov_loop import markov_loop_block
from packetloss_cvx.tolerances import CRITICAL_MU_TOL, SAMPLED_Z_MAX

A1, K1 = 1.2, 0.793369               # the hostile review's trap: its plug-in gain
TRANSIENT = [[0.6, 0.4, 0.0], [0.5, 0.5, 0.0], [0.1, 0.1, 0.8]]
DELIVERY = [1.0, 0.5, 0.0]


def _trap(**start) -> System:
    return System(A=[[A1]], B=[[1.0]], horizon=5, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                  channel=GilbertElliott(p=[0.0], r=[0.3], **start))


def _three(**start) -> System:
    return System(A=[[A1]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[0.5], x0=[1.0],
                  channel=MarkovChannel(transition=[TRANSIENT], delivery=[DELIVERY], **start))


@pytest.mark.parametrize("start", [{"state": ["good"]}, {}])
def test_trap_every_packet_arrives_so_the_loop_is_deterministic(start):
    s = _trap(**start)
    st = loop_stability(s, [[K1]])
    assert st.stable
    assert st.radius == pytest.approx((A1 - K1) ** 2, rel=1e-12)
    found, lam, _ = chain_least_radius(s.A, s.B, s.channel)
    assert found.verdict == "stable"
    assert lam == 0.0                                   # deadbeat K = a: x+ = 0
    res = coupled_riccati(s)                            # the scalar DARE: P^2 - a^2 P - 1 = 0, K = a P / (P + 1)
    P = (A1**2 + np.sqrt(A1**4 + 4)) / 2
    assert res.spectral_radius == pytest.approx((A1 - A1 * P / (P + 1)) ** 2, rel=1e-12)


def test_trap_from_a_start_that_meets_the_bad_state_is_unstable():
    # started bad (or on a belief that weighs it), the bad state's a^2 (1 - r) = 1.008 is met: no law stabilises
    s = _trap(state=["bad"])
    st = loop_stability(s, [[K1]])
    assert not st.stable
    assert st.radius == pytest.approx(A1**2 * 0.7, rel=1e-12)
    assert chain_membership(s.A, s.B, s.channel).verdict == "unstable"
    with pytest.raises(NumericalError, match="not mean-square stabilisable"):
        coupled_riccati(s)


def test_trap_critical_rate_is_the_rays_end():
    # below mean rate 1 (burstiness 0.7 kept) the bad state is met and lost with probability 0.7 a step: 1.008; at 1
    # the stationary law never leaves good
    point = chain_critical_rate(_trap(state=["good"]))
    assert point.t == 1.0
    assert 1.0 - CRITICAL_MU_TOL <= point.lower < 1.0
    assert (point.inside.verdict, point.outside.verdict) == ("stable", "unstable")


def _hand_radius(K: float, kept: list[int]) -> float:
    """rho of q_b <- sum_a T_ab g_a q_a over the states kept, g_a = E[(a - v K)^2 | a] (deliveries of the current
    state)."""
    T = np.array(TRANSIENT)[np.ix_(kept, kept)]
    g = np.array([DELIVERY[a] * (A1 - K) ** 2 + (1 - DELIVERY[a]) * A1**2 for a in kept])
    return float(max(abs(np.linalg.eigvals(T.T * g[None, :]))))


@pytest.mark.parametrize("start", [{"state": [0]}, {"state": [1]}, {}])
def test_three_states_radius_over_the_states_met(start):
    s = _three(**start)
    radius = mean_square_radius(s.A, s.B, s.channel, np.array([[0.9]]), "current")
    assert radius == pytest.approx(_hand_radius(0.9, [0, 1]), rel=1e-12)
    assert radius < 1.0 < _hand_radius(0.9, [0, 1, 2])          # the unreached state alone: 1.44 * 0.8
    assert loop_stability(s, [[0.9]]).stable
    # a gain per joint state (three) keeps the reached modes' rows
    three = np.array([[[0.9]], [[0.9]], [[np.nan]]])
    assert mean_square_radius(s.A, s.B, s.channel, three, "current") == radius
    assert exact_transition(s.channel).ints.shape == (2, 2)


def test_three_states_from_the_transient_state_counts_it():
    s = _three(state=[2])
    radius = mean_square_radius(s.A, s.B, s.channel, np.array([[0.9]]), "current")
    assert radius == pytest.approx(_hand_radius(0.9, [0, 1, 2]), rel=1e-12)
    assert not loop_stability(s, [[0.9]]).stable


def _enumerated_stage_costs(s: System, K: float, steps: int) -> np.ndarray:
    """E[x_t^2 + psi (v_t K x_t)^2] summed over every path of states and deliveries, from the start's law."""
    T, pi0, psi = np.array(TRANSIENT), s.channel.initial_belief[0], 0.5          # _three's input weight
    out = np.zeros(steps)
    for path in itertools.product(range(3), repeat=steps):
        weight = pi0[path[0]] * np.prod([T[a, b] for a, b in itertools.pairwise(path)])
        if weight == 0.0:
            continue
        for v in itertools.product((0, 1), repeat=steps):
            w = weight * np.prod([DELIVERY[a] if vt else 1 - DELIVERY[a] for a, vt in zip(path, v, strict=True)])
            x = 1.0
            if w == 0.0:
                continue
            for t in range(steps):
                u = v[t] * K * x
                out[t] += w * (x * x + psi * u * u)
                x = A1 * x - u
    return out


@pytest.mark.parametrize("start", [{"state": [0]}, {"state": [2]}])
def test_three_states_exact_stage_costs_match_enumeration(start):
    s = _three(**start)
    steps, K = 6, 0.9
    M = 2 if start["state"] == [0] else 3
    exact = jump_law_stage_costs(s, np.full((M, 1, 1), K), steps, "current")
    np.testing.assert_allclose(exact, _enumerated_stage_costs(s, K, steps), rtol=1e-12)
    if M == 2:              # gains for all three joint states: the reached rows
        np.testing.assert_array_equal(jump_law_stage_costs(s, np.full((3, 1, 1), K), steps, "current"), exact)


@pytest.mark.parametrize("order", [[0, 1, 2], [2, 0, 1]])
def test_three_states_mode_dependent_law_sampled_against_exact(order):
    """order: the states relabelled (the transient one last, or first: the sampled chain's state indices then differ
    from the modes' numbers)."""
    T, d = np.array(TRANSIENT)[np.ix_(order, order)], np.array(DELIVERY)[order]
    chain = MarkovChannel(transition=[T], delivery=[d], state=[order.index(0)])
    s = _three().with_channel(chain)
    with pytest.raises(NumericalError, match="not mean-square stabilisable"):   # the transient state never delivers
        coupled_riccati(s.with_channel(chain.with_belief([np.full(3, 1 / 3)])))   # and stays with 0.8: 1.152
    dp = coupled_riccati(s)
    assert sorted(order[a] for a in dp.modes.ravel()) == [0, 1]
    assert dp.spectral_radius < 1.0
    steps, samples = 30, 20000
    rng = np.random.default_rng
    cost = markov_loop_block(s, ["dp"], None, None, dp.gains, steps, samples, rng(3), rng(4))[0][0]
    exact = float(jump_law_stage_costs(s, dp.gains, steps, "current").mean())
    stderr = float(cost.std(ddof=1) / np.sqrt(samples))
    assert abs(cost.mean() - exact) <= SAMPLED_Z_MAX * stderr
