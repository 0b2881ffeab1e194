"""Defects found when the session's branches met on main."""

import pytest

import packetloss_cvx as pl
from packetloss_cvx.errors import NumericalError
from packetloss_cvx.markov import bursty_twin, coupled_riccati


def test_coupled_riccati_without_stabilising_gains_is_a_numerical_error():
    """two_actuator behind Gilbert channels with lambda = 0.95: the coupled iteration diverged, and
    its overflowing S made np.linalg.solve raise LinAlgError ('unexpected LinAlgError' in simulate)."""
    system = bursty_twin(pl.load_example("two_actuator"), 0.95)
    with pytest.raises(NumericalError, match="not mean-square stabilisable"):
        coupled_riccati(system)
