"""markov.exact_closed_form(method="auto"): the dense route where it is estimated faster (exact_cost.dense_max) and its
condition estimate allows it, the augmented recursion beyond and wherever the dense route raises NumericalError.
References: each route asked for by name (the two are independent computations, each tested against
enumeration and the QP twin in test_markov_augmented.py), and a hand-written plan's enumerated cost."""

import importlib

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.errors import NumericalError
from packetloss_cvx.lq.markov_cost import auto_route, dense_max, exact_closed_form
from packetloss_cvx.model.chain import attach_channel
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.random_systems import random_system


def bursty(seed, horizon, m=2):
    rng = np.random.default_rng(seed)
    s = random_system(rng, n=3, m=m, horizon=horizon, noise=seed % 2 == 0, spectral_radius=0.9)
    return attach_channel(s, GilbertElliott(p=rng.uniform(0.05, 0.4, m), r=rng.uniform(0.05, 0.4, m)))


@pytest.mark.parametrize("seed", range(6))
def test_auto_takes_the_dense_route_on_small_problems_and_agrees_with_the_recursion(seed):
    s = bursty(seed, horizon=[10, 15, 20, 40, 60, 80][seed])      # short enough for the dense route to be faster
    auto = exact_closed_form(s)
    dense, recursion = exact_closed_form(s, method="dense"), exact_closed_form(s, method="recursion")
    assert auto.method == "markov-dense"
    assert auto.cost == dense.cost                               # the same route: the same floats
    np.testing.assert_array_equal(auto.inputs, dense.inputs)
    assert auto.cost == pytest.approx(recursion.cost, rel=1e-10)
    scale = max(1.0, float(np.abs(recursion.inputs).max()))
    np.testing.assert_allclose(auto.inputs, recursion.inputs, rtol=0, atol=1e-10 * scale)


def test_auto_takes_the_recursion_beyond_the_crossover():
    def scalar(horizon):
        return pl.System(A=[[0.9]], B=[[1.0]], horizon=horizon, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                         channel=GilbertElliott(p=[0.2], r=[0.3]))

    s = scalar(2000)                                  # dense about 2.4 s estimated, the recursion about 0.14 s
    assert dense_max(s) == 0
    auto = exact_closed_form(s)
    assert auto.method == "markov-recursion"
    assert auto.cost == exact_closed_form(s, method="recursion").cost
    assert dense_max(scalar(40)) == 40
    assert exact_closed_form(scalar(40)).method == "markov-dense"


def test_auto_takes_the_recursion_where_the_dense_route_would_lose_its_digits():
    """The unstable pendulum at N = 150: the condition estimate (8.7e8) is beyond DENSE_MAX_CONDITION."""
    s0 = pl.load_example("pendulum_bursty")
    s = pl.System(A=s0.A, B=s0.B, horizon=150, state_weight=np.diag(s0.state_weights[0]),
                  input_weight=s0.input_weights[0], x0=s0.x0, channel=s0.channel)
    assert exact_closed_form(s).method == "markov-recursion"


def test_auto_falls_back_to_the_recursion_when_the_dense_route_raises(monkeypatch):
    s = bursty(1, horizon=6)

    def lost(system):
        raise NumericalError("planted: the dense self-check failed")

    monkeypatch.setattr(importlib.import_module("packetloss_cvx.lq.markov_cost"), "_dense_closed_form", lost)
    assert exact_closed_form(s).method == "markov-recursion"
    with pytest.raises(NumericalError, match="planted"):
        exact_closed_form(s, method="dense")


def test_auto_on_a_hand_value():
    """N = 1, x0 = 1: E[(x0 + v u)^2 + (v u)^2] = 1 + 2 mu u + 2 mu u^2 (v^2 = v) is least at u* = -1/2, whatever
    mu: J* = 1 - mu / 2 (3/4 at mu = 1/2), against the realised cost enumerated over v in {0, 1}."""
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                  channel=GilbertElliott(p=[0.5], r=[0.5]))
    sol = exact_closed_form(s)
    assert sol.method == f"markov-{auto_route(s)}"
    u, mu = float(sol.inputs[0, 0]), float(s.mu_schedule[0, 0])
    enumerated = sum(p * ((1.0 + v * u) ** 2 + (v * u) ** 2) for v, p in ((0, 1 - mu), (1, mu)))
    assert u == pytest.approx(-0.5, rel=1e-14)
    assert sol.cost == pytest.approx(enumerated, rel=1e-14)
    assert sol.cost == pytest.approx(1.0 - mu / 2, rel=1e-14)
