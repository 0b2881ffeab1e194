"""Every result type is frozen, its arrays are read-only copies, and to_dict() is plain JSON."""

import copy
import dataclasses
import json
import pickle

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.results import Allocation, ClaimResult, Maximiser
from packetloss_cvx.studies import sweep


def _results(two_actuator):
    sol = pl.closed_form(two_actuator, "tcp")
    alloc = Allocation(mu=np.array([0.5, 0.5]), communication_cost=1.0, cost=2.0, lower_bound=0.9, gap=0.1,
                       status="optimal", method="test", protocol="tcp", alpha=3.0, beta=np.array([1.0, 1.0]))
    claim = ClaimResult("x", "s", "holds", 1, 0, 0.5, None, "")
    best = Maximiser(np.array([0.3]), 1.0, "grid")
    return [sol, alloc, claim, best]


def test_arrays_are_read_only_and_results_frozen(two_actuator):
    for result in _results(two_actuator):
        arrays = [v for v in vars(result).values() if isinstance(v, np.ndarray)]
        for arr in arrays:
            with pytest.raises(ValueError, match="read-only"):
                arr.flat[0] = 1.0
        with pytest.raises(dataclasses.FrozenInstanceError):
            result.method = "changed"  # type: ignore[misc]
        json.dumps(result.to_dict(), allow_nan=False)


def test_result_does_not_alias_the_callers_array():
    mu = np.array([0.5])
    best = Maximiser(mu, 1.0, "grid")
    mu[0] = 0.9
    assert best.point[0] == 0.5


def test_a_solution_says_which_protocol_it_solved(two_actuator):
    # a saved sol.to_json() on its own must not leave the protocol to be guessed from the cost
    for protocol in ("tcp", "udp"):
        data = json.loads(pl.closed_form(two_actuator, protocol).to_json())
        assert data["protocol"] == protocol


def test_results_keep_read_only_arrays_through_pickle_and_deepcopy(two_actuator):
    # results are frozen with read-only arrays (results/__init__.py); a result sent back from a
    # multiprocessing worker (pickle) or deep-copied skipped __post_init__ and came back writable
    sol = pl.closed_form(two_actuator, "udp")
    result = sweep(two_actuator, mu_grid=3)
    for obj in (sol, result):
        for twin in (pickle.loads(pickle.dumps(obj)), copy.deepcopy(obj)):
            assert type(twin) is type(obj)
            for name, value in vars(obj).items():
                back = vars(twin)[name]
                if hasattr(value, "flags"):
                    assert not back.flags.writeable, name
                    assert back.tobytes() == value.tobytes(), name
    twin = pickle.loads(pickle.dumps(result))
    assert not any(v.flags.writeable for v in twin.costs.values())
    assert not twin.mu.flags.writeable
