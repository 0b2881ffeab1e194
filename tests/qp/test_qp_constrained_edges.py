"""The constrained program (qp/constrained.py) at its edges: a size beyond the budgets refused before anything is
built; the state at or near zero."""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx.errors import BudgetError
from packetloss_cvx.lq.costs import closed_form
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.files import load_example
from packetloss_cvx.model.system import System
from packetloss_cvx.qp.constrained import ConstrainedQP
from packetloss_cvx.tolerances import CONSTRAINED_AGREEMENT_RTOL, CROSS_CHECK_FLOOR


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


TWO_ACTUATOR_ROWS = [Constraints(x_max=[2.0, 2.0]),
                     Constraints(u_min=[-0.5, -0.5], u_max=[0.5, 0.5], du_max=[0.3, np.inf], x_max=[2.0, 2.0],
                                 chance=[([1.0, 0.0], 1.8, 0.1)])]


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize("constraints", TWO_ACTUATOR_ROWS, ids=["x_max", "all rows"])
@pytest.mark.parametrize("x0", [0.0, 1e-300, 1e-100, 1e-30])
def test_at_a_state_near_zero_the_plan_is_the_closed_form(protocol, constraints, x0):
    """Near x0 = 0 no row binds (the bounds hold zero with room), so the plan is Theorem 1's, linear in x0: zero at
    x0 = 0 (J(U) >= 0 = J(0) without noise). The KKT check had no floor: every term was rounding of zero, and the
    answer was refused ("KKT residual 1.49 (stationarity)") for |x0| <= 1e-100."""
    s = load_example("two_actuator").with_x0([x0, x0])
    sol = ConstrainedQP(s, protocol, constraints).solve()
    reference = closed_form(s, protocol).inputs
    assert sol.binding == ()
    size = 2.0            # the data's size (the state limit x_max = 2): below a billionth of it all is rounding
    floor = CROSS_CHECK_FLOOR * size
    assert np.abs(sol.inputs - reference).max() <= CONSTRAINED_AGREEMENT_RTOL * max(np.abs(reference).max(), floor)
