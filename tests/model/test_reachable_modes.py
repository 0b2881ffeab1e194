"""model.chain.reachable_modes: the joint states a chain can visit from its start, and mode_chain / mode_start kept
to them. References: hand-traced chains (a transient state, a periodic pair, probabilities that underflow in the
Kronecker product); where the start reaches every state, the arrays of product_chain unchanged bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx.model.chain import mode_chain, mode_start, product_chain, reachable_modes
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel

#: state 2 is transient: it leads to 0 and 1, which never lead back to it
TRANSIENT = [[0.6, 0.4, 0.0], [0.5, 0.5, 0.0], [0.1, 0.1, 0.8]]


def _three(**start) -> MarkovChannel:
    return MarkovChannel(transition=[TRANSIENT], delivery=[[1.0, 0.5, 0.0]], **start)


@pytest.mark.parametrize(("start", "reached"), [
    ({"state": [0]}, [True, True, False]),
    ({"state": [1]}, [True, True, False]),
    ({}, [True, True, False]),                        # the stationary law: (5/9, 4/9, 0)
    ({"state": [2]}, [True, True, True]),
    ({"belief": [[0.0, 0.9, 0.1]]}, [True, True, True]),
])
def test_a_transient_state_is_reached_only_from_itself(start, reached):
    ch = _three(**start)
    assert reachable_modes(ch).tolist() == reached
    modes, T, h = mode_chain(ch)
    kept = np.flatnonzero(reached)
    assert modes.ravel().tolist() == kept.tolist()
    np.testing.assert_array_equal(T, np.array(TRANSIENT)[np.ix_(kept, kept)])
    np.testing.assert_array_equal(T.sum(axis=1), np.ones(len(kept)))      # a closed set: still stochastic
    np.testing.assert_array_equal(h.ravel(), np.array([1.0, 0.5, 0.0])[kept])
    np.testing.assert_array_equal(mode_start(ch), ch.initial_belief[0][kept])


def test_channels_that_step_together_never_meet_opposite_phases():
    flip = [[0.0, 1.0], [1.0, 0.0]]
    ch = MarkovChannel(transition=[flip, flip], delivery=[[1.0, 0.0], [1.0, 0.0]], state=[0, 0])
    assert reachable_modes(ch).tolist() == [True, False, False, True]       # (g, g) -> (b, b) -> (g, g)
    assert mode_chain(ch)[0].tolist() == [[0, 0], [1, 1]]
    np.testing.assert_array_equal(mode_chain(ch)[1], flip)
    shifted = MarkovChannel(transition=[flip, flip], delivery=[[1.0, 0.0], [1.0, 0.0]], state=[0, 1])
    assert reachable_modes(shifted).tolist() == [False, True, True, False]


def test_a_transition_that_underflows_in_the_product_is_still_reached():
    # P(good -> bad) = 1e-200 on each channel: the joint step (g, g) -> (b, b) has probability 1e-400, zero as a double
    ch = GilbertElliott(p=[1e-200, 1e-200], r=[0.0, 0.0], state=["good", "good"])
    assert product_chain(ch)[1][0, 3] == 0.0
    assert reachable_modes(ch).tolist() == [True, True, True, True]


@pytest.mark.parametrize("channel", [
    GilbertElliott(p=[0.1], r=[0.3]),
    GilbertElliott(p=[0.1, 0.2], r=[0.3, 0.05], state=["good", "bad"]),
    GilbertElliott(p=[0.0], r=[0.3], state=["bad"]),                     # bad is transient but the start
    MarkovChannel(transition=[TRANSIENT], delivery=[[1.0, 0.5, 0.0]], state=[2]),
])
def test_a_start_that_reaches_every_state_changes_nothing(channel):
    assert reachable_modes(channel).all()
    modes, T, h, start = product_chain(channel)
    for kept, full in zip((*mode_chain(channel), mode_start(channel)), (modes, T, h, start), strict=True):
        assert kept.dtype == full.dtype
        assert kept.tobytes() == full.tobytes()
