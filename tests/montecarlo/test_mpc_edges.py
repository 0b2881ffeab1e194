"""The constrained loop (montecarlo/mpc.py) at its edges: work and memory refused before any path is drawn, a loop
that leaves the double range, time-varying weights, a non-stationary schedule."""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx.errors import BudgetError
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo import mpc
from packetloss_cvx.tolerances import CROSS_CHECK_FLOOR


def _scalar(**extra) -> System:
    fields = dict(A=[[1.2]], B=[[1.0]], horizon=8, state_weight=[1.0], input_weight=[1.0], mu=[0.7], x0=[3.0])
    return System(**{**fields, **extra})


BOX = Constraints(u_min=[-1.0], u_max=[1.0])


@pytest.fixture
def no_paths(monkeypatch):
    """Drawing a path fails the test: a refusal must come before any array is allocated."""
    def refuse(*args, **kwargs):
        raise AssertionError("paths drawn before the budget check")
    monkeypatch.setattr(mpc, "loop_paths", refuse)


@pytest.mark.parametrize("controllers", [mpc.CONTROLLERS, ["clipped"]])
def test_a_billion_runs_are_refused_before_any_path_is_drawn(no_paths, controllers):
    with pytest.raises(BudgetError) as caught:
        mpc.simulate_mpc(_scalar(), BOX, samples=10 ** 9, controllers=controllers, progress=False)
    assert caught.value.field == "samples"
    assert caught.value.env == "PACKETLOSS_CVX_BUDGET_MPC_SOLVES"


def test_with_the_solve_budget_raised_the_memory_budget_still_refuses(no_paths, monkeypatch):
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MPC_SOLVES", "inf")
    with pytest.raises(BudgetError) as caught:
        mpc.simulate_mpc(_scalar(), BOX, samples=10 ** 9, controllers=["clipped"], progress=False)
    assert caught.value.env == "PACKETLOSS_CVX_BUDGET_MEMORY_BYTES"


def test_certainty_equivalent_mpc_keeps_an_answer_as_the_state_decays():
    """two_actuator's loop with a state limit and a chance row: as the state decays toward zero (about 1e-100
    after some hundred steps, zero to rounding of the data's size after 400) every program still gives a trusted
    answer (777 of 1200 run-steps had none: the KKT check had no floor), and the state keeps decaying."""
    from packetloss_cvx.model.files import load_example

    c = Constraints(u_min=[-0.5, -0.5], u_max=[0.5, 0.5], du_max=[0.3, 10.0], x_max=[2.0, 2.0],
                    chance=[([1.0, 0.0], 1.8, 0.1)])
    sim = mpc.simulate_mpc(load_example("two_actuator"), c, samples=3, steps=400, protocols=["tcp"],
                           controllers=["certainty-equivalent"], keep=3, progress=False)
    run = sim.runs["tcp"]["certainty-equivalent"]
    assert run.failed_steps == 0
    assert run.fallback_steps == 0
    assert np.abs(run.states[:, -1]).max() < CROSS_CHECK_FLOOR * 2.0      # zero to the data's size (x_max = 2)


@pytest.mark.parametrize("controller", mpc.CONTROLLERS)
def test_a_diverging_loop_is_a_result_for_every_controller(controller):
    """x' = 2 x + v u from x0 = 3 with |u| <= 0.1: |x_{t+1}| >= 2 |x_t| - 0.1 >= |x_t| + 2.9, so |x_t| >= 3 2^t - 0.1
    (2^t - 1) by hand, beyond the double range before step 1030, in every run and under every controller. As
    simulate's loops report a diverging law: an infinite mean stage cost (null in JSON), no warning, no exception;
    the clipped law returned inf/NaN with overflow warnings, the programs raised."""
    import json
    import warnings

    s = System(A=[[2.0]], B=[[1.0]], horizon=5, state_weight=[1.0], input_weight=[1.0], mu=[0.7], x0=[3.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim = mpc.simulate_mpc(s, Constraints(u_min=[-0.1], u_max=[0.1]), samples=4, steps=1100,
                               controllers=[controller], protocols=["tcp"], progress=False)
    run = sim.runs["tcp"][controller]
    assert run.diverged_runs == 4
    assert run.mean_stage_cost == np.inf
    entry = json.loads(json.dumps(run.to_dict(), allow_nan=False))
    assert entry["mean_stage_cost"] is None
    assert entry["diverged_runs"] == 4


def test_time_varying_weights_are_refused_naming_them(no_paths):
    """The loop's stage cost used state_weights[0] at every step, silently: a plan's weights speak of its own steps,
    not of a loop that runs past the horizon."""
    from packetloss_cvx.errors import InputError

    s = _scalar(state_weight=None, state_weights=[[1.0]] * 4 + [[5.0]] * 4)
    with pytest.raises(InputError) as caught:
        mpc.simulate_mpc(s, BOX, samples=2, steps=3, progress=False)
    assert caught.value.field == "state_weights"
    s = _scalar(input_weight=None, input_weights=[[1.0]] * 4 + [[5.0]] * 4)
    with pytest.raises(InputError) as caught:
        mpc.simulate_mpc(s, BOX, samples=2, steps=3, progress=False)
    assert caught.value.field == "input_weights"


def test_a_chance_row_the_solver_calls_infeasible_falls_back_to_the_soft_program():
    """x' = 1.1 x + v u, mu = 1/2, |u| <= 5, P(x_1 <= -1) >= 0.9 at N = 1: from x > -1/1.1 a lost packet leaves
    x_1 = 1.1 x > -1 with probability 1/2 > 0.1 whatever u, by hand, so the first step of every run (x0 = 1) has no
    plan. Its certificate is undecided (a chance row), a `SolverError`, not an `InfeasibleError`: the loop still runs
    the soft twin on such a step and counts it infeasible (once, such a step was counted failed)."""
    s = System(A=[[1.1]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    c = Constraints(u_min=[-5.0], u_max=[5.0], chance=[([1.0], -1.0, 0.1)])
    run = mpc.simulate_mpc(s, c, 4, 3, seed=2, protocols=["tcp"], controllers=["expected-cost"]
                           ).runs["tcp"]["expected-cost"]
    assert run.failed_steps == 0
    assert run.fallback_steps == run.infeasible.count >= 4
