"""Systems and channels cross process boundaries (multiprocessing, joblib, Dask) and copy.copy/deepcopy:
pickling rebuilds them through the validating constructors, bit for bit."""

import copy
import pickle

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.channel import GilbertElliott
from packetloss_cvx.random_systems import random_system

FIELDS = ("A", "B", "state_weights", "input_weights", "mu_schedule", "x0", "initial_weight", "noise_cov")


def _systems():
    rng = np.random.default_rng(7)
    out = [random_system(rng) for _ in range(30)]
    out += [pl.load_example(name) for name in ("pendulum", "two_actuator", "pendulum_bursty")]
    out.append(out[0].with_channel(GilbertElliott(p=[0.1] * out[0].m, r=[0.3] * out[0].m,
                                                  h_good=[0.9] * out[0].m, state=["bad"] * out[0].m)))
    return out


@pytest.mark.parametrize("system", _systems())
def test_a_pickled_system_is_the_same_system(system):
    back = pickle.loads(pickle.dumps(system))
    assert back is not system
    for key in FIELDS:
        assert np.array_equal(getattr(back, key), getattr(system, key)), key
        assert not getattr(back, key).flags.writeable
    assert (back.horizon, back.name, back.channel) == (system.horizon, system.name, system.channel)
    plain = system if system.channel is None else system.with_mu(system.mu_schedule)
    again = back if back.channel is None else back.with_mu(back.mu_schedule)
    assert pl.closed_form(again, "udp").cost == pl.closed_form(plain, "udp").cost


def test_copies_of_immutable_objects_are_the_objects():
    s = pl.load_example("pendulum_bursty")
    assert copy.copy(s) is s
    assert copy.deepcopy(s) is s
    assert copy.deepcopy(s.channel) is s.channel
    assert copy.deepcopy({"system": s})["system"] is s


def test_a_pickled_channel_keeps_its_known_state():
    chan = GilbertElliott(p=[0.1, 0.2], r=[0.4, 0.3], state=["bad", "good"])
    back = pickle.loads(pickle.dumps(chan))
    assert back == chan
    assert back.state_given
    assert np.array_equal(back.delivery_schedule(5), chan.delivery_schedule(5))
