"""The constrained program (qp/constrained.py) at its edges: a size beyond the budgets refused before anything is
built; the state at or near zero."""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx.errors import BudgetError
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.system import System
from packetloss_cvx.qp.constrained import ConstrainedQP


def _scalar(horizon: int) -> System:
    return System(A=[[0.9]], B=[[1.0]], horizon=horizon, state_weight=[1.0], input_weight=[1.0], mu=[0.7],
                  x0=[3.0])


@pytest.fixture
def no_build(monkeypatch):
    """Building the program fails the test: a refusal comes before cvxpy sees the problem."""
    monkeypatch.setattr(ConstrainedQP, "_build", lambda self: (_ for _ in ()).throw(AssertionError("built")))


@pytest.mark.parametrize(("horizon", "constraints", "env"), [
    (100_000, Constraints(u_min=[-1.0], u_max=[1.0]), "SOLVE_WORK"),            # a MemoryError of 74.5 GiB
    (1200, Constraints(u_min=[-1.0], chance=[([1.0], 5.0, 0.1)]), "MEMORY_BYTES"),   # killed at about 20 GB
])
def test_a_program_beyond_the_budgets_is_refused_before_it_is_built(no_build, monkeypatch, horizon, constraints,
                                                                      env):
    if env == "MEMORY_BYTES":            # the memory refusal on its own, the time budget raised
        monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_SOLVE_WORK", "inf")
    with pytest.raises(BudgetError) as caught:
        ConstrainedQP(_scalar(horizon), "tcp", constraints)
    assert caught.value.field == "horizon"
    assert caught.value.env == f"PACKETLOSS_CVX_BUDGET_{env}"


def test_a_small_program_is_within_the_budgets():
    """The budgets leave the programs the package is used for alone: two_actuator's horizon of 10 (or 300)."""
    sol = ConstrainedQP(_scalar(300), "tcp", Constraints(u_min=[-1.0], u_max=[1.0])).solve()
    assert sol.status == "optimal"
    assert np.all(np.abs(sol.inputs) <= 1.0 + 1e-9)
