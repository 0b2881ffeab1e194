"""Systems and channels cross process boundaries (multiprocessing, joblib, Dask) and copy.copy/deepcopy:
pickling rebuilds them through the validating constructors, bit for bit."""

import copy
import pickle
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx import errors
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.random_systems import random_system

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


def _closed_form_cost(mu):
    return pl.closed_form(pl.load_example("two_actuator").with_mu(mu), "udp", method="recursion").cost



@pytest.mark.parametrize("error", [
    errors.InputError("channel.mu", "expected probabilities in [0, 1], found 1.5"),
    errors.DimensionError("B", "expected (2, m)"), errors.ProbabilityError("mu", "found 1.5"),
    errors.SolverError("infeasible", "Clarabel says so"), errors.SolverError("max_iter"),
    errors.InfeasibleError("alpha below the least cost", 1.92), errors.NumericalError("overflow"),
    errors.CrossCheckError("J differs", {"dense": 1.0, "qp": 2.0}), errors.ResourceError("too big", 1e12, 4e9),
])
def test_every_error_pickles_as_itself(error):
    # a multiprocessing / joblib worker's exception is pickled to the caller: InputError(field, detail)
    # could not be rebuilt from its args (TypeError), SolverError's message doubled, min_cost was lost
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is type(error)
    assert str(back) == str(error)
    assert vars(back) == vars(error)



def test_a_workers_input_error_reaches_the_caller_and_spares_the_other_tasks():
    # the typed error and its message cross the process boundary; the pool survives it for the other tasks
    with ProcessPoolExecutor(2) as pool:
        futures = [pool.submit(_closed_form_cost, mu) for mu in ([0.5, 0.5], [1.5, 0.5], [0.9, 0.9])]
        with pytest.raises(errors.ProbabilityError, match=r"mu: expected probabilities in \[0, 1\]"):
            futures[1].result(timeout=120)
        assert futures[0].result(timeout=120) == _closed_form_cost([0.5, 0.5])
        assert futures[2].result(timeout=120) == _closed_form_cost([0.9, 0.9])
