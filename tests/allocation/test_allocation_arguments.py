"""The allocation's arguments: a typed InputError naming the field in the
API, exit code 2 with one stderr line naming the flag on the command line; never a traceback,
a warning dump, a hang or a silent answer; extreme but valid arguments (alphas of 1e300 and 1e-300, rows
scaled by 1e300) answered as their plain equivalents, and the brute-force reference refusing what allocate
refuses."""


import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.allocation import allocate, best_cost_within_budget, min_cost, parse_constraint
from packetloss_cvx.allocation.brute_force import brute_force_allocation
from packetloss_cvx.cli import main

LONG_INDEX = "mu" + "1" * 5000 + " <= 1"


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"beta": ["a", 1.0]}, "beta"),
        ({"beta": [[1.0], [1.0, 2.0]]}, "beta"),
        ({"beta": {"mu1": 1.0, "mu2": 1.0}}, "beta"),
        ({"beta": [10**400, 1]}, "beta"),
        ({"beta": [np.nan, 1.0]}, "beta"),
        ({"beta": "1,1"}, "beta"),
        ({"alpha": "x"}, "alpha"),
        ({"alpha": 10**400}, "alpha"),
        ({"alpha": np.inf}, "alpha"),
        ({"alpha": True}, "alpha"),
        ({"gap": "x"}, "gap"),
        ({"gap": 1e-300}, "gap"),
        ({"gap": 1.0}, "gap"),
        ({"gap": np.nan}, "gap"),
        ({"bounds": (0.0, "a")}, "bounds"),
        ({"bounds": (0.0, np.nan)}, "bounds"),
        ({"bounds": (0.0, 1.0, 2.0)}, "bounds"),
        ({"max_boxes": 0}, "max_boxes"),
        ({"max_boxes": 2.5}, "max_boxes"),
        ({"time_limit": -1.0}, "time_limit"),
        ({"constraints": [(np.array([[np.nan, 1.0]]), [1.0])]}, r"constraints\[0\]"),
        ({"constraints": [(np.array([[1.0, 1.0]]), [np.inf])]}, r"constraints\[0\]"),
        ({"constraints": [(np.array([[1e999, 1.0]]), [1.0])]}, r"constraints\[0\]"),
        ({"constraints": [([[1.0, 1.0]], [1.0], "extra")]}, r"constraints\[0\]"),
        ({"constraints": [lambda mu: "not a constraint"]}, r"constraints\[0\]"),
        ({"constraints": [lambda mu: 1 / 0]}, r"constraints\[0\]: the callable raised ZeroDivisionError"),
        ({"constraints": "mu1 <= 1"}, "constraints"),
    ],
)
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_api_bad_argument_is_input_error(two_actuator, protocol, kwargs, field):
    args = {"alpha": 6.0, "beta": (1.0, 1.0), **kwargs}
    with pytest.raises(pl.InputError, match=f"^{field}") as info:
        allocate(two_actuator, protocol, **args)
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize("budget", [np.nan, np.inf, "x", None, [1.0, 2.0]])
def test_budget_must_be_a_number(two_actuator, budget):
    with pytest.raises(pl.InputError, match="^budget"):
        best_cost_within_budget(two_actuator, "udp", (1.0, 1.0), budget)


def test_min_cost_bad_bounds(two_actuator):
    with pytest.raises(pl.InputError, match="^bounds"):
        min_cost(two_actuator, "tcp", bounds=(0.9, 0.1))


@pytest.mark.parametrize(
    ("text", "match"),
    [("1e999*mu1 <= 1", "does not fit a float"), ("mu1 <= -1e999", "does not fit a float"),
     ("mu1 <= 1e999", "does not fit a float"), (LONG_INDEX, "channel numbers up to 6 digits"),
     ("1" * 5000 + "*mu1 <= 1", "does not fit a float"), ("mu1 <= 1e308 + 1e308", "more than a float holds"),
     (12, "expected a string")],
)
def test_parse_constraint_hostile(text, match):
    with pytest.raises(pl.InputError, match=f"^constraint: .*{match}"):
        parse_constraint(text, 2)


def test_extreme_but_finite_rows_are_scaled(two_actuator):
    """1e300*mu1 <= 3e299 is mu1 <= 0.3; mu1 <= 1e300 constrains nothing; both reach the solvers
    as unit-scaled rows (or not at all), so the answer is that of mu1 <= 0.3."""
    plain = allocate(two_actuator, "tcp", 6.0, (1.0, 1.0), constraints=[parse_constraint("mu1 <= 0.3", 2)])
    big = allocate(two_actuator, "tcp", 6.0, (1.0, 1.0),
                   constraints=[parse_constraint("1e300*mu1 <= 3e299", 2), parse_constraint("mu1 <= 1e300", 2)])
    assert np.allclose(big.mu, plain.mu, atol=1e-9)
    ref = brute_force_allocation(two_actuator, "tcp", 6.0, (1.0, 1.0), *parse_constraint("mu1 <= 0.3", 2))
    assert big.lower_bound <= ref[0] + 1e-9


def test_row_no_mu_can_meet_is_a_proof(two_actuator):
    with pytest.raises(pl.InfeasibleError, match=r"constraints\[0\]: no mu in the bounds"):
        allocate(two_actuator, "udp", 6.0, (1.0, 1.0), constraints=[parse_constraint("mu1 + mu2 >= 2.5", 2)])


@pytest.mark.parametrize(
    ("extra", "flag"),
    [
        (["--constraint", "1e999*mu1 <= 1"], "--constraint"),
        (["--constraint", "mu1 <= -1e999"], "--constraint"),
        (["--constraint", "mu1 <= 1e999"], "--constraint"),
        (["--constraint", LONG_INDEX], "--constraint"),
        (["--gap", "1e-300"], "--gap"),
        (["--gap", "x"], "--gap"),
        (["--gap", "1"], "--gap"),
        (["--alpha", "1e999"], "--alpha"),
        (["--alpha", "nan"], "--alpha"),
        (["--beta", "1," + "9" * 400], "--beta"),
        (["--bounds", "0,nan"], "--bounds"),
        (["--max-boxes", "0"], "--max-boxes"),
        (["--max-boxes", "1" * 5000], "--max-boxes"),
        (["--time-limit", "-1"], "--time-limit"),
    ],
)
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_cli_hostile_input_exit_2_one_line(capsys, protocol, extra, flag):
    argv = ["allocate", "two_actuator", "--protocol", protocol, "--alpha", "6", "--beta", "1,1", *extra]  # last wins
    assert main(argv) == 2
    out = capsys.readouterr()
    assert out.out == ""
    assert out.err.count("\n") == 1
    assert flag in out.err
    assert "Traceback" not in out.err


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_extreme_alphas(two_actuator, protocol):
    """alpha = 1e300 is met by mu = 0 (beta'mu = 0, gap 0); alpha = 1e-300 is below J* at the
    upper corner, an infeasibility proved by monotonicity before any solver runs."""
    got = allocate(two_actuator, protocol, 1e300, (1.0, 1.0))
    assert got.status == "optimal"
    assert got.communication_cost == 0.0
    assert got.lower_bound == 0.0
    corner = pl.solve_qp(two_actuator.with_mu([1.0, 1.0]), protocol, cross_check=False, with_gain=False).cost
    with pytest.raises(pl.InfeasibleError) as info:
        allocate(two_actuator, protocol, 1e-300, (1.0, 1.0))
    assert info.value.min_cost == pytest.approx(corner, rel=1e-7)


@pytest.mark.parametrize(("alpha", "beta", "G", "h", "field"), [
    (float("nan"), [1.0, 1.0], None, None, "alpha"),        # returned None ("no feasible point") before
    (3.0, [1.0, 1.0, 1.0], None, None, "beta"),
    (3.0, [1.0, -1.0], None, None, "beta"),
    (3.0, [1.0, 1.0], [[1.0, 1.0, 1.0]], [1.0], "G, h"),
    (3.0, [1.0, 1.0], [[1.0, 1.0]], [np.inf], "G, h"),
])
def test_the_brute_force_reference_refuses_what_allocate_refuses(alpha, beta, G, h, field):
    with pytest.raises(pl.InputError) as info:
        brute_force_allocation(pl.load_example("two_actuator"), "udp", alpha, beta, G, h, coarse=11, fine=11)
    assert info.value.field == field


@pytest.mark.parametrize("m", ["2", 2.0, True, 0, -3, None])
def test_parse_constraint_takes_a_positive_integer_dimension(m):
    """``parse_constraint(text, "2")`` raised a TypeError from NumPy; every m that is not a positive integer is an
    InputError under ``m``."""
    from packetloss_cvx.allocation.grammar import parse_constraint
    with pytest.raises(pl.InputError, match="^m: expected a positive integer"):
        parse_constraint("mu1 <= 1", m)
