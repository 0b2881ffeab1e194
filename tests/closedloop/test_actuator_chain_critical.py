"""closedloop.actuator_region.actuator_critical behind a Gilbert–Elliott chain: the critical mean rate per strategy.

References: for zero the chain region engine (closedloop.markov_region.chain_critical_rate, another algorithm: the
homogeneous coupled Riccati eigenpair, with the law knowing the current state as design_modes does); for the scalar
plant behind a Gilbert channel (h_good = 1, h_bad = 0, the law knowing whether this step delivers) the hand value
``rate* = (1 - 1/a^2) / (1 - lambda)`` for every strategy:

- necessary: a bad run multiplies the second moment by at least a^2 per step (zero: x+ = a x; hold: z+ = [[a, b],
  [0, 1]] z, eigenvalues a and 1; a buffer's plan runs out and then x+ = a x, or with buffer:L:hold hold's step),
  with probability 1 - r per step, so a stabilising law needs ``a^2 (1 - r) < 1``;
- sufficient: zero and the buffer (sending zeros after the first entry) deadbeat x on every delivery; buffer:L:hold
  sending its first entry L times does what hold does. Hold: the next good step sees only x (its delivery replaces
  w), so from good step to good step x <- g(l) x, l the bad run between them, i.i.d.; with u = c x on delivery and
  ``alpha = a + c a / (a - 1)``, ``g(l) = alpha a^l + 1 - alpha / a`` and ``E g^2 = 1 + 2 alpha (E a^l - 1/a) +
  O(alpha^2)``: E a^l >= 1 > 1/a, so a small alpha < 0 gives ``E g^2 < 1`` wherever ``E a^(2l)`` is finite, i.e.
  ``a^2 (1 - r) < 1``.

With ``r = (1 - lambda) rate`` along the family (burstiness lambda kept) the threshold is the hand value.
"""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx import load_example
from packetloss_cvx.closedloop.actuator_region import actuator_critical
from packetloss_cvx.closedloop.markov_region import chain_critical_rate
from packetloss_cvx.errors import InputError
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.system import System
from packetloss_cvx.tolerances import CRITICAL_MU_TOL


def _scalar(a: float, p: float, r: float) -> System:
    return System(A=[[a]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                  channel=GilbertElliott(p=[p], r=[r]))


@pytest.mark.parametrize(("a", "p", "r"), [(1.5, 0.4, 0.4), (1.2, 0.1, 0.3)])
@pytest.mark.parametrize("actuator", ["zero", "hold", "buffer:2", "buffer:3", "buffer:2:hold"])
def test_scalar_gilbert_critical_mean_rate_is_the_hand_value_for_every_strategy(a, p, r, actuator):
    hand = (1.0 - 1.0 / a ** 2) / (1.0 - (1.0 - p - r))
    point = actuator_critical(_scalar(a, p, r), actuator, tol=CRITICAL_MU_TOL)
    assert point.lower <= hand <= point.t
    # tol wide, or stepped down (at most 4^6 tol, actuator_critical) where the crossing's side is undecided: then
    # the note says how far
    assert point.t - point.lower <= CRITICAL_MU_TOL or "below the float crossing" in point.note
    assert point.t - point.lower <= (1 + 4.0 ** 6) * CRITICAL_MU_TOL
    assert point.inside.verdict == "stable"
    # the lower end is a proof where its certificate survives, else said to be an estimate
    assert point.outside.verdict == "unstable" or "float estimate" in point.note


@pytest.mark.parametrize("system", [
    _scalar(1.5, 0.4, 0.4),
    load_example("two_actuator").with_channel(GilbertElliott(p=[0.1, 0.2], r=[0.3, 0.4], h_good=[0.9, 0.8])),
], ids=["scalar", "two_actuator"])
def test_zero_agrees_with_the_chain_region_engine_where_the_law_knows_the_current_state(system):
    ours = actuator_critical(system, "zero", tol=CRITICAL_MU_TOL)
    ref = chain_critical_rate(system, tol=CRITICAL_MU_TOL, delivery="current")
    assert max(ours.lower, ref.lower) <= min(ours.t, ref.t)         # both brackets hold the exact point
    assert abs(ours.t - ref.t) <= CRITICAL_MU_TOL
    assert ours.inside.verdict == "stable"
    assert ours.outside.verdict == "unstable"


def test_the_convention_matters_on_two_actuator_so_the_agreement_above_is_not_trivial():
    system = load_example("two_actuator").with_channel(GilbertElliott(p=[0.1, 0.2], r=[0.3, 0.4],
                                                                      h_good=[0.9, 0.8]))
    ours = actuator_critical(system, "zero", tol=CRITICAL_MU_TOL)
    other = chain_critical_rate(system, tol=CRITICAL_MU_TOL, delivery="next")
    assert abs(ours.t - other.t) > 10 * CRITICAL_MU_TOL


def test_the_critical_rate_lies_on_the_chain_family_not_on_bernoulli_links():
    # Bernoulli links at the same rate need 1 - 1/a^2 = 5/9 (a = 1.5); the chain with burstiness 0.2 needs 25/36
    point = actuator_critical(_scalar(1.5, 0.4, 0.4), "hold", tol=CRITICAL_MU_TOL)
    assert point.lower > 5 / 9 + 0.1


def test_chains_outside_the_monotonicity_proof_are_refused_with_the_reason():
    bad = _scalar(1.5, 0.4, 0.4).with_channel(GilbertElliott(p=[0.4], r=[0.4], h_bad=[0.2]))
    with pytest.raises(InputError, match="monotonicity in the mean rate is proved"):
        actuator_critical(bad, "hold")
    three = _scalar(1.5, 0.4, 0.4).with_channel(MarkovChannel(
        transition=[[[0.8, 0.2, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]]], delivery=[[1.0, 0.5, 0.0]]))
    with pytest.raises(InputError, match=r"two states.*\[3\] states"):
        actuator_critical(three, "zero")


def test_a_ray_that_never_stabilises_returns_inf_with_a_proof_at_its_end():
    # h_good = 1/2, a = 2: at the ray's end (rate 1/2, p = 0) the bad state is never met and half the packets arrive,
    # so deadbeat on delivery leaves E[x+^2] = 4 x^2 / 2 at best; below it the bad state only adds losses
    s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=GilbertElliott(p=[0.1], r=[0.3], h_good=[0.5]))
    point = actuator_critical(s, "zero", tol=CRITICAL_MU_TOL)
    assert point.t == np.inf
    assert point.outside.verdict == "unstable"


def test_a_ray_stabilised_only_at_its_end_where_the_bad_state_is_never_met():
    # a = 2, burstiness 0.6: the hand value (3/4) / 0.4 > 1 = h_good, so no mean rate below 1 stabilises; at rate 1
    # (p = 0, started from the stationary law: good for ever) every packet arrives and hold stabilises
    point = actuator_critical(_scalar(2.0, 0.1, 0.3), "hold", tol=CRITICAL_MU_TOL)
    assert point.t == 1.0
    assert 1.0 - CRITICAL_MU_TOL <= point.lower < 1.0
    assert (point.inside.verdict, point.outside.verdict) == ("stable", "unstable")
