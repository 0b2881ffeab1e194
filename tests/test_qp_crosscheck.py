"""The QP twin's cross-check (``qp.compare``): a plan and its cost against a reference solution.

Each side of the check must bind on its own: a disagreement in the inputs alone (costs equal) and one
in the cost alone (inputs equal) both raise :class:`CrossCheckError`; a reference equal to the plan passes.
"""

import dataclasses
import re

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.qp import compare
from packetloss_cvx.tolerances import CROSS_CHECK_INPUT_ATOL


@pytest.fixture(scope="module")
def two_actuator():
    s = pl.load_example("two_actuator")
    return s, pl.closed_form(s, "tcp", method="dense")


def test_a_plan_equal_to_its_reference_passes(two_actuator):
    s, ref = two_actuator
    check = compare(np.array(ref.inputs), ref.cost, ref, s)
    assert check.max_input_diff == 0.0 and check.cost_rel_diff == 0.0


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
