"""Properties of the exact Markov cost over random systems behind random Gilbert–Elliott channels
(Hypothesis, derandomised in conftest.py), drawn as in test_properties.py (unstable plants, long
horizons, weights scaled up to 1e14): the closed form returns a finite, nonnegative minimum that no
other plan beats (the plug-in plan, a perturbed plan), or raises a typed refusal."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import packetloss_cvx as pl
from packetloss_cvx.lq.markov_cost import exact_closed_form, exact_cost
from packetloss_cvx.model.chain import attach_channel
from packetloss_cvx.qp.markov import exact_qp
from tests.model.test_markov_chain import random_channel
from tests.lq.test_properties import systems

REFUSALS = (pl.NumericalError, pl.ResourceError)


@settings(max_examples=150)
@given(systems(max_horizon=25), st.integers(0, 2**32 - 1))
def test_exact_minimum_is_a_minimum_or_refused(system, seed):
    rng = np.random.default_rng(seed)
    s = attach_channel(system, random_channel(rng, system.m, given=bool(seed % 2)))
    try:
        exact = exact_closed_form(s)
        plugin = exact_cost(s, pl.closed_form(s.with_mu(s.mu_schedule), "udp").inputs)
        other = exact_cost(s, exact.inputs + 1e-3 * rng.normal(size=exact.inputs.shape) * (1 + np.abs(exact.inputs)))
    except REFUSALS:
        return
    assert np.isfinite(exact.cost)
    assert exact.cost >= 0
    tol = 1e-9 * max(1.0, exact.cost)
    assert plugin >= exact.cost - tol
    assert other >= exact.cost - tol


@settings(max_examples=60)
@given(systems(max_horizon=15), st.integers(0, 2**32 - 1))
def test_exact_qp_agrees_with_the_closed_form_or_raises(system, seed):
    rng = np.random.default_rng(seed)
    s = attach_channel(system, random_channel(rng, system.m, given=bool(seed % 2)))
    try:
        qp = exact_qp(s)
    except (*REFUSALS, pl.CrossCheckError):     # a disagreement is never returned as an answer
        return
    ref = exact_closed_form(s)
    assert qp.status == "optimal"
    assert abs(qp.cost - ref.cost) <= 1e-7 * max(1.0, ref.cost)
    assert np.abs(s.mu_schedule * (qp.inputs - ref.inputs)).max() <= 1e-6 * max(1.0, np.abs(ref.inputs).max())
