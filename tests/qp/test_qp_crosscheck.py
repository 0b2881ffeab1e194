"""The QP twin's cross-check (``qp.compare``): a plan and its cost against a reference solution.

Each side of the check must bind on its own: a disagreement in the inputs alone (costs equal) and one
in the cost alone (inputs equal) both raise :class:`CrossCheckError`; a reference equal to the plan passes.
Each band (and the QP's check of its objective against the forward cost of its own plan) is pinned on both
sides: 3 times outside raises, 0.3 times inside passes.
"""

import dataclasses
import re

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.qp.expected_cost import compare
from packetloss_cvx.tolerances import (
    CROSS_CHECK_COST_RTOL,
    CROSS_CHECK_FLOOR,
    CROSS_CHECK_INPUT_ATOL,
    PLAN_COST_RTOL,
)
from tests.references import weighted_two_actuator as _weighted


@pytest.fixture(scope="module")
def two_actuator():
    s = pl.load_example("two_actuator")
    return s, pl.closed_form(s, "tcp", method="dense")


def test_a_plan_equal_to_its_reference_passes(two_actuator):
    s, ref = two_actuator
    check = compare(np.array(ref.inputs), ref.cost, ref, s)
    assert check.max_input_diff == 0.0
    assert check.cost_rel_diff == 0.0


@pytest.mark.parametrize("entry", [(0, 0), (3, 1), (-1, 0)])
def test_inputs_that_disagree_in_one_entry_raise_with_equal_costs(two_actuator, entry):
    """One entry of Vbar U moved by 100 times the tolerance, every other entry and the cost exact: the
    largest difference (not the smallest, which is 0 here) must be compared."""
    s, ref = two_actuator
    scale = float(np.abs(s.mu_schedule * ref.inputs).max())
    planted = np.array(ref.inputs)
    planted[entry] += 100 * CROSS_CHECK_INPUT_ATOL * scale / s.mu_schedule[entry]
    with pytest.raises(pl.CrossCheckError, match=r"rel dJ = 0\.0e\+00 ") as info:
        compare(planted, ref.cost, ref, s)
    found, tolerance = map(float, re.search(r"max\|Vbar dU\| = (\S+) \(tolerance (\S+)\)", str(info.value)).groups())
    assert found == pytest.approx(100 * tolerance, rel=0.02)


def test_the_qp_twin_refuses_a_reference_whose_inputs_alone_are_wrong(two_actuator):
    """End to end: the QP agrees with the closed form's cost, but the reference's plan is wrong in one entry."""
    s, ref = two_actuator
    inputs = np.array(ref.inputs)
    inputs[2, 1] *= 1.01
    wrong = dataclasses.replace(ref, inputs=inputs)
    with pytest.raises(pl.CrossCheckError, match="disagree"):
        pl.solve_qp(s, "tcp", with_gain=False, reference=wrong)


def test_a_cost_that_disagrees_alone_raises(two_actuator):
    s, ref = two_actuator
    with pytest.raises(pl.CrossCheckError, match="rel dJ = 1.0e-06"):
        compare(np.array(ref.inputs), ref.cost * (1 + 1e-6), ref, s)


# ---------------------------------------------------------------- each band pinned on both sides

@pytest.mark.parametrize(("factor", "passes"), [(3.0, False), (0.3, True)])
def test_input_band_is_cross_check_input_atol_of_the_largest_mean_input(two_actuator, factor, passes):
    """One entry of Vbar U moved by factor CROSS_CHECK_INPUT_ATOL max|Vbar U*|, the cost exact: raises at 3,
    passes at 0.3 (reporting the difference it saw)."""
    s, ref = two_actuator
    scale = float(np.abs(s.mu_schedule * ref.inputs).max())
    planted = np.array(ref.inputs)
    planted[3, 1] += factor * CROSS_CHECK_INPUT_ATOL * scale / s.mu_schedule[3, 1]
    if passes:
        check = compare(planted, ref.cost, ref, s)
        assert check.max_input_diff == pytest.approx(factor * CROSS_CHECK_INPUT_ATOL * scale, rel=1e-6)
    else:
        with pytest.raises(pl.CrossCheckError, match="disagree"):
            compare(planted, ref.cost, ref, s)


@pytest.mark.parametrize(("factor", "passes"), [(3.0, False), (0.3, True)])
def test_cost_band_is_cross_check_cost_rtol_relative(two_actuator, factor, passes):
    """The plan exact, the cost off by factor CROSS_CHECK_COST_RTOL relative: raises at 3, passes at 0.3."""
    s, ref = two_actuator
    cost = ref.cost * (1 + factor * CROSS_CHECK_COST_RTOL)
    if passes:
        check = compare(np.array(ref.inputs), cost, ref, s)
        assert check.cost_rel_diff == pytest.approx(factor * CROSS_CHECK_COST_RTOL, rel=1e-6)
    else:
        with pytest.raises(pl.CrossCheckError, match="disagree"):
            compare(np.array(ref.inputs), cost, ref, s)


@pytest.mark.parametrize(("factor", "passes"), [(3.0, False), (0.3, True)])
def test_against_an_exact_zero_the_bands_are_taken_of_cross_check_floor_times_the_problem_scale(factor, passes):
    """No state weight: J* = 0 and U* = 0 exactly, so both bands are taken of CROSS_CHECK_FLOOR times the problem's
    own size scale = (s_J, s_x) (here (4, 2)): a cost of factor CROSS_CHECK_COST_RTOL CROSS_CHECK_FLOOR s_J, or one
    mean input of factor CROSS_CHECK_INPUT_ATOL CROSS_CHECK_FLOOR s_x, raises at 3 and passes at 0.3."""
    s = pl.System(A=[[1.1, 0.2], [0.0, 0.9]], B=[[1.0], [0.5]], horizon=3, state_weight=[0.0, 0.0],
                  input_weight=[1.0], mu=[0.5], x0=[2.0, -1.0])
    ref = pl.closed_form(s, "tcp")
    assert ref.cost == 0.0
    assert not np.any(ref.inputs)
    scale = (4.0, 2.0)
    cost = factor * CROSS_CHECK_COST_RTOL * CROSS_CHECK_FLOOR * scale[0]
    inputs = np.zeros_like(ref.inputs)
    inputs[1, 0] = factor * CROSS_CHECK_INPUT_ATOL * CROSS_CHECK_FLOOR * scale[1] / 0.5
    for plan, value in ((np.zeros_like(ref.inputs), cost), (inputs, 0.0)):
        if passes:
            compare(plan, value, ref, s, scale)
        else:
            with pytest.raises(pl.CrossCheckError, match="disagree"):
                compare(plan, value, ref, s, scale)


@pytest.mark.parametrize(("factor", "passes"), [(3.0, False), (0.3, True)])
def test_qp_objective_against_its_own_plan_binds_at_cross_check_cost_rtol(two_actuator, monkeypatch, factor, passes):
    """The QP's objective against the forward cost of its own plan (qp.plan_cost, moved by factor
    CROSS_CHECK_COST_RTOL relative): NumericalError at 3, the answer at 0.3."""
    import packetloss_cvx.qp.expected_cost as qp_module

    s, ref = two_actuator
    real = qp_module.plan_cost

    def moved(*args, **kwargs):
        value, bound = real(*args, **kwargs)
        return value * (1 + factor * CROSS_CHECK_COST_RTOL), bound

    monkeypatch.setattr(qp_module, "plan_cost", moved)
    if passes:
        assert pl.solve_qp(s, "tcp", with_gain=False, cross_check=False).cost == pytest.approx(ref.cost, rel=1e-8)
    else:
        with pytest.raises(pl.NumericalError, match="forward cost of its\\s+own plan"):
            pl.solve_qp(s, "tcp", with_gain=False, cross_check=False)


@pytest.mark.parametrize(("factor", "checked"), [(3.0, False), (0.3, True)])
def test_qp_objective_is_checked_only_where_its_plans_cost_is_resolved(two_actuator, monkeypatch, factor, checked):
    """The plan check is made where the forward cost of the QP's plan is resolved, its error bound (plan_cost) at most
    PLAN_COST_RTOL of it: with the forward cost moved by 1e-4 relative and its bound set to factor PLAN_COST_RTOL of
    it, the QP raises at 0.3 (checked) and is answered at 3 (not resolved: a fixed plan's cost on an unstable plant
    over a long horizon, where the cross-check binds instead)."""
    import packetloss_cvx.qp.expected_cost as qp_module

    s, ref = two_actuator
    real = qp_module.plan_cost

    def unresolved(*args, **kwargs):
        value = real(*args, **kwargs)[0] * (1 + 1e-4)
        return value, factor * PLAN_COST_RTOL * value

    monkeypatch.setattr(qp_module, "plan_cost", unresolved)
    if checked:
        with pytest.raises(pl.NumericalError, match="forward cost of its\\s+own plan"):
            pl.solve_qp(s, "tcp", with_gain=False, cross_check=False)
    else:
        assert pl.solve_qp(s, "tcp", with_gain=False, cross_check=False).cost == pytest.approx(ref.cost, rel=1e-7)


def test_qp_objective_check_is_skipped_on_an_unstable_plant_where_its_plan_is_not_resolved():
    """A scalar plant a = 1.5 over 200 steps (a^200 = 1.6e35): the QP's plan, right to Clarabel's accuracy, rolled
    out open loop has a forward cost of order 1e40 against a minimum of order 1 (the plan cancels the growth); its
    bound says so, the check is not made, and the QP's answer agrees with the closed form."""
    from packetloss_cvx.lq.recursion import plan_cost

    s = pl.System(A=[[1.5]], B=[[1.0]], horizon=200, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    qp = pl.solve_qp(s, "tcp", with_gain=False, cross_check=False)
    value, bound = plan_cost(s, qp.inputs, "tcp")
    assert bound > PLAN_COST_RTOL * value
    assert qp.cost == pytest.approx(pl.closed_form(s, "tcp").cost, rel=CROSS_CHECK_COST_RTOL)


def test_qp_whose_objective_disagrees_with_its_own_plan_raises():
    """At state_weight 1e14 the QP reported 1.19 while the cost cannot be below 3.0522."""
    with pytest.raises(pl.NumericalError, match="forward cost of its\\s+own plan"):
        pl.solve_qp(_weighted(1e14), "tcp", with_gain=False, cross_check=False)


def test_api_cross_check_binds():
    import dataclasses

    s = pl.load_example("two_actuator")
    wrong = dataclasses.replace(pl.closed_form(s, "tcp"), cost=3.0)
    with pytest.raises(pl.CrossCheckError, match="J\\* = 3") as info:
        pl.solve_qp(s, "tcp", with_gain=False, reference=wrong)
    assert info.value.values["qp"] == pytest.approx(2.79847, rel=1e-5)
