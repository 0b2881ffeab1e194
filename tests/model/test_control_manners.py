"""python-control and scipy manners: Q and R as python-control names them, one mu for every channel, channel
numbers that say their base, messages in the interface's own words, critical_mu giving mu beside t with one
default direction, and names kept through StateSpace conversions.

References: python-control's dlqr (the DARE gain a long horizon's first gain converges to at mu = 1) and its
StateSpace labels, hand rows of the constraint grammar, the command line's own output."""

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.allocation import allocate
from packetloss_cvx.allocation.grammar import parse_constraint
from packetloss_cvx.cli import main
from packetloss_cvx.closedloop.critical import critical_mu
from packetloss_cvx.studies import sweep
from packetloss_cvx.studies.region_map import region_map

A = [[1.0, 0.1], [0.0, 1.0]]
B = [[0.005, 0.0], [0.1, 0.05]]


def plant(**fields):
    return pl.System(A=A, B=B, horizon=fields.pop("horizon", 4), x0=[1.0, -0.5], **fields)


def test_q_and_r_are_state_weight_and_input_weight():
    Q, R = np.array([[2.0, 0.5], [0.5, 1.0]]), np.diag([1.0, 3.0])
    aliased = plant(Q=Q, R=R, mu=[0.7, 0.9])
    named = plant(state_weight=Q, input_weight=[1.0, 3.0], mu=[0.7, 0.9])
    np.testing.assert_array_equal(aliased.state_weights, named.state_weights)
    np.testing.assert_array_equal(aliased.input_weights, named.input_weights)
    assert pl.closed_form(aliased, "udp").cost == pl.closed_form(named, "udp").cost


def test_with_every_packet_delivered_the_gain_is_python_controls_dlqr():
    control = pytest.importorskip("control")
    Q, R = np.diag([1.0, 0.5]), np.diag([0.2, 0.4])
    K, _, _ = control.dlqr(np.array(A), np.array(B), Q, R)
    gain = pl.closed_form(plant(Q=Q, R=R, mu=1.0, horizon=400), "tcp").gain
    np.testing.assert_allclose(gain, K, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize(("alias", "other"), [("Q", "state_weight"), ("Q", "state_weights"), ("R", "input_weight"),
                                              ("R", "input_weights")])
def test_a_weight_given_twice_is_refused(alias, other):
    weights = {"Q": np.eye(2), "R": np.eye(2), "state_weight": [1.0, 1.0], "input_weight": [1.0, 1.0],
               "state_weights": np.ones((4, 2)), "input_weights": np.ones((4, 2))}
    given = {alias: weights[alias], other: weights[other]}
    given.setdefault("input_weight" if alias == "Q" else "state_weight", [1.0, 1.0])
    with pytest.raises(pl.InputError, match=f"python-control's name for {other.rstrip('s')}") as info:
        plant(mu=0.5, **given)
    assert info.value.field == alias
    if alias == "Q":
        assert "initial_weight" in str(info.value)


def test_a_full_input_weight_is_refused_with_the_reason():
    with pytest.raises(pl.InputError, match=r"R\[0, 1\] = 0\.5: .*diagonal Psi only") as info:
        plant(Q=np.eye(2), R=[[1.0, 0.5], [0.5, 2.0]], mu=0.5)
    assert info.value.field == "R"
    with pytest.raises(pl.InputError, match="E\\[v_i v_j\\] = mu_i mu_j") as info:
        plant(state_weight=[1.0, 1.0], input_weight=[[1.0, 0.0], [0.1, 2.0]], mu=0.5)
    assert info.value.field == "input_weight"


def test_one_mu_is_every_channels_as_on_the_command_line(capsys):
    one = plant(Q=np.eye(2), R=np.eye(2), mu=0.6)
    assert one.mu.tolist() == [0.6, 0.6]
    assert one.with_mu(0.3).mu.tolist() == [0.3, 0.3]
    with pytest.raises(pl.ProbabilityError, match="1.5"):
        plant(Q=np.eye(2), R=np.eye(2), mu=1.5)
    assert main(["solve", "two_actuator", "--mu", "0.6", "--no-qp", "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    python = pl.closed_form(pl.load_example("two_actuator").with_mu(0.6), "tcp").cost
    assert cli["tcp"]["cost"] == pytest.approx(python, rel=1e-12)


def test_parse_constraint_in_python_speaks_of_its_own_argument():
    with pytest.raises(pl.InputError, match="^constraint: unknown channel 'mu3'") as info:
        parse_constraint("mu1 + mu3 <= 1", 2)
    assert "--" not in str(info.value)


@pytest.mark.parametrize(("text", "said"), [("mu1 + mu2 >= 2.5", "mu1 + mu2 >= 2.5 (largest value 2 < 2.5)"),
                                            ("2*mu1 + mu2 <= -1", "2*mu1 + mu2 <= -1 (least value 0 > -1)"),
                                            ("mu1 - mu2 >= 1.5", "mu1 - mu2 >= 1.5 (largest value 1 < 1.5)")])
def test_an_infeasible_constraint_is_reported_as_the_user_wrote_it(text, said):
    with pytest.raises(pl.InfeasibleError) as info:
        allocate(pl.load_example("two_actuator"), "udp", 6.0, (1.0, 1.0), constraints=[parse_constraint(text, 2)])
    assert said in str(info.value)


def test_channel_numbers_say_their_base_in_python_and_on_the_command_line(capsys):
    system = pl.load_example("two_actuator")
    with pytest.raises(pl.InputError, match=r"from 0 to 1 \(0-based in Python.*command line counts from 1\)"):
        sweep(system, mu_grid=3, channel=2)
    with pytest.raises(pl.InputError, match=r"0-based in Python") as info:
        region_map(system, laws=("dp",), grid=3, channels=(0, 2))
    assert "1.." not in str(info.value)
    assert main(["sweep", "two_actuator", "--mu-grid", "3", "--channel", "3", "-q"]) == 2
    assert "from 1 to 2 (1-based on the command line: 1 is mu1; Python counts from 0)" in capsys.readouterr().err


def test_critical_mu_gives_mu_beside_t_along_the_command_lines_direction(capsys):
    system = pl.load_example("two_actuator").with_mu([0.9, 0.3])     # the file's mu is not the default ray
    point = critical_mu(system, "dp")
    assert main(["region", "two_actuator", "--mu", "0.9,0.3", "--law", "dp", "--json", "-q"]) == 0
    cli = json.loads(capsys.readouterr().out)["dp"]
    assert point.t == cli["t"]
    assert point.mu.tolist() == cli["critical_mu"]
    assert point.mu.tolist() == [point.t, point.t]                       # t * (1, 1)


@pytest.fixture
def cart():
    control = pytest.importorskip("control")
    return control.StateSpace(A, B, np.eye(2), np.zeros((2, 2)), 0.1, inputs=["F1", "F2"], states=["pos", "vel"],
                              outputs=["pos", "vel"], name="cart")


def test_names_go_through_from_and_to_statespace(cart, tmp_path):
    system = pl.System.from_statespace(cart, horizon=4, Q=np.eye(2), R=np.eye(2), mu=0.8, x0=[1.0, 0.0])
    assert (system.name, system.input_labels, system.state_labels) == ("cart", ("F1", "F2"), ("pos", "vel"))
    back = system.to_statespace()
    assert (back.name, back.input_labels, back.state_labels, back.output_labels) == (
        "cart", ["F1", "F2"], ["pos", "vel"], ["pos", "vel"])
    saved = pl.load_system(pl.save_system(system, tmp_path / "cart.toml"))
    assert (saved.input_labels, saved.state_labels) == (("F1", "F2"), ("pos", "vel"))
    renamed = pl.System.from_statespace(cart, horizon=4, Q=np.eye(2), R=np.eye(2), mu=0.8, x0=[1.0, 0.0],
                                        name="trolley")
    assert renamed.name == "trolley"


def test_python_controls_generated_names_are_not_kept():
    control = pytest.importorskip("control")
    system = pl.System.from_statespace(control.ss(A, B, np.eye(2), np.zeros((2, 2)), 0.1), horizon=4, Q=np.eye(2),
                                       R=np.eye(2), mu=0.8, x0=[1.0, 0.0])
    assert (system.name, system.input_labels, system.state_labels) == (None, None, None)


def test_the_closed_loop_names_its_noise_inputs_and_itself(cart):
    from packetloss_cvx.closedloop import closed_loop_statespace

    system = pl.System.from_statespace(cart, horizon=4, Q=np.eye(2), R=np.eye(2), mu=0.8, x0=[1.0, 0.0])
    loop = closed_loop_statespace(system, pl.closed_form(system, "tcp").gain)
    assert (loop.name, loop.input_labels, loop.output_labels) == ("cart closed loop", ["w_pos", "w_vel"],
                                                                  ["pos", "vel"])
    unnamed = closed_loop_statespace(pl.System(A=A, B=B, horizon=4, Q=np.eye(2), R=np.eye(2), mu=0.8, x0=[1.0, 0.0]),
                                     np.zeros((2, 2)))
    assert (unnamed.name, unnamed.input_labels) == ("closed loop", ["w[0]", "w[1]"])


def test_an_infeasible_power_row_is_reported_in_powers():
    """Power rows are read on x = P / cap: the message spoke of mu and of the scaled row (1.5*mu1 >= 2)."""
    from packetloss_cvx.allocation.delivery import power_model
    from packetloss_cvx.allocation.power import least_power

    row = parse_constraint("P1 + 2*P2 >= 5", 2, name="P")
    with pytest.raises(pl.InfeasibleError) as info:
        least_power(pl.load_example("two_actuator"), "tcp", power_model("exponential", 2, scale=1.0), 8.0,
                    constraints=[row], max_power=[1.5, 1.0])
    # largest P1 + 2 P2 in the caps: 1.5 + 2 * 1 = 3.5
    assert "no P in the box [0, 1.5] x [0, 1] satisfies P1 + 2*P2 >= 5 (largest value 3.5 < 5)" in str(info.value)
