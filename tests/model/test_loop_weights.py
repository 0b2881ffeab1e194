"""model.system.loop_weights: a loop's cost has one stage weight; time-varying weights (the plan's steps) are refused
by every entry point that prices a loop, in the API (InputError naming the field) and on the command line (exit 2,
one line). Reference: the same system with its weights given once, which every entry point accepts, and on which a
schedule of equal weights gives the same numbers."""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.closedloop.actuator import actuator_costs, compare_actuators
from packetloss_cvx.closedloop.moments import closed_loop, finite_horizon_costs
from packetloss_cvx.errors import InputError
from packetloss_cvx.model.files import save_system
from packetloss_cvx.model.system import System, loop_weights
from packetloss_cvx.montecarlo import closed_loop_costs, simulate
from packetloss_cvx.montecarlo.actuator import sample_actuator_loop

A, B, X0 = [[1.2, 0.1], [0.0, 0.9]], [[1.0], [0.5]], [1.0, 0.0]
GAIN = np.array([[0.8, 0.2]])


def _system(state_weights) -> System:
    return System(A=A, B=B, horizon=3, state_weights=state_weights, input_weight=[1.0], mu=[0.7], x0=X0)


VARYING = _system([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]])
EQUAL = _system([[2.0, 1.0]] * 3)
ONE = System(A=A, B=B, horizon=3, state_weight=[2.0, 1.0], input_weight=[1.0], mu=[0.7], x0=X0)

ENTRIES = {
    "simulate closed loop": lambda s: simulate(s, samples=20, steps=5, closed_loop=True, laws=["tcp"]),
    "closed_loop_costs": lambda s: closed_loop_costs(s, [GAIN], 5, 20, np.random.default_rng(0)),
    "closed_loop (moments)": lambda s: closed_loop(s, GAIN).average_stage_cost,
    "finite_horizon_costs": lambda s: finite_horizon_costs(s, GAIN, 5)[0],
    "actuator_costs hold": lambda s: actuator_costs(s, GAIN, 5, "hold")[0],
    "compare_actuators": lambda s: compare_actuators(s, GAIN, 5)["hold"]["radius"],
    "sample_actuator_loop": lambda s: sample_actuator_loop(s, GAIN, 5, "buffer:2", 20, seed=1),
}


@pytest.mark.parametrize("entry", sorted(ENTRIES))
def test_every_loop_cost_refuses_time_varying_weights(entry):
    with pytest.raises(InputError, match="one weight for every step") as info:
        ENTRIES[entry](VARYING)
    assert info.value.field == "state_weights"


@pytest.mark.parametrize("entry", ["closed_loop (moments)", "finite_horizon_costs", "actuator_costs hold",
                                   "closed_loop_costs"])
def test_a_schedule_of_equal_weights_is_one_weight(entry):
    assert np.array_equal(np.asarray(ENTRIES[entry](EQUAL)), np.asarray(ENTRIES[entry](ONE)))


def test_time_varying_input_weights_are_named_as_input_weights():
    s = System(A=A, B=B, horizon=2, state_weight=[1.0, 1.0], input_weights=[[1.0], [2.0]], mu=[0.7], x0=X0)
    with pytest.raises(InputError) as info:
        loop_weights(s)
    assert info.value.field == "input_weights"
    omega, psi = loop_weights(ONE)
    assert np.array_equal(omega, np.diag([2.0, 1.0])) and np.array_equal(psi, [1.0])


@pytest.mark.parametrize("command", [["simulate", "--closed-loop", "--samples", "20"], ["compare"]])
def test_the_command_line_refuses_a_loop_over_time_varying_weights_in_one_line(capsys, tmp_path, command):
    path = save_system(VARYING, tmp_path / "varying.toml")
    code = main([command[0], str(path), *command[1:]])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "cost.state_weights: the loop's stage cost" in err
    assert main(["simulate", str(path), "--samples", "20"]) == 0    # the open loop prices the plan over its steps


def test_solve_names_the_file_field_when_the_actuator_section_needs_one_weight(capsys, tmp_path):
    path = save_system(VARYING, tmp_path / "varying.toml")
    assert main(["solve", str(path), "--actuator", "hold"]) == 2
    assert "cost.state_weights: the loop's stage cost" in capsys.readouterr().err
    assert main(["solve", str(path)]) == 0            # Theorem 1 prices the plan over its own steps: accepted
