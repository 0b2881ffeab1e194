"""Hostile input: a typed InputError naming the field in the API, exit 2 and one stderr line on
the command line; never a traceback, a MemoryError, a RecursionError or a warning dump."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.model.files import dumps_system, system_from_dict

BASE = {"A": [[1.0, 0.0], [0.0, 1.0]], "B": [[1.0], [0.5]], "horizon": 5, "state_weight": [1, 1],
        "input_weight": [1], "mu": [0.5], "x0": [1, 0]}


def _deep(levels: int):
    value = 1.0
    for _ in range(levels):
        value = [value]
    return value


@pytest.mark.parametrize(("change", "field", "match"), [
    ({"horizon": 1_000_000_000}, "horizon", "what fits in memory"),
    ({"horizon": 9223372036854775807}, "horizon", "what fits in memory"),
    ({"horizon": 10**23}, "horizon", "what fits in memory"),
    ({"horizon": -(10**5000)}, "horizon", "about 5001 digits"),
    ({"A": [[10**400, 0], [0, 1]]}, "A", "double range"),
    ({"x0": [10**400, 0]}, "x0", "double range"),
    ({"mu": [10**400]}, "mu", "double range"),
    ({"A": _deep(5000)}, "A", "levels of nested lists"),
    ({"A": np.zeros((0, 0)), "B": np.zeros((0, 1)), "x0": [], "state_weight": []}, "A", "n >= 1"),
    ({"B": [[], []], "input_weight": [], "mu": []}, "B", "m >= 1"),
])
def test_system_refuses_with_the_field_named(change, field, match):
    with pytest.raises(pl.InputError, match=match) as info:
        pl.System(**{**BASE, **change})
    assert info.value.field == field
    assert isinstance(info.value, ValueError)


def test_load_system_refuses_a_nul_in_the_path():
    with pytest.raises(pl.InputError, match="NUL") as info:
        pl.load_system("a\x00b")
    assert info.value.field == "file"


def _toml(tmp_path, name, old, new, prefix=b""):
    text = dumps_system(pl.load_example("two_actuator"))
    assert old in text
    path = tmp_path / name
    path.write_bytes(prefix + text.replace(old, new).encode())
    return str(path)


@pytest.mark.parametrize(("old", "new", "match"), [
    ("horizon = 10", "horizon = 1000000000", "cost.horizon: expected at most"),
    ("horizon = 10", "horizon = 9223372036854775807", "cost.horizon: expected at most"),
    ("horizon = 10", "horizon = 10^23", "not valid TOML"),
    ("x0 = [1.0, 1.0]", "x0 = [1" + "0" * 400 + ", 1.0]", "state.x0: expected numbers within the double range"),
    ("mu = [0.9, 0.5]", "mu = " + "[" * 5000 + "0.5" + "]" * 5000, "nests arrays too deeply"),
])
def test_cli_hostile_files_exit_2_with_one_line(tmp_path, capsys, old, new, match):
    path = _toml(tmp_path, "bad.toml", old, new)
    assert main(["solve", path, "--no-qp"]) == 2
    out, err = capsys.readouterr()
    assert not out
    assert err.count("\n") == 1
    assert match in err


def test_a_byte_order_mark_is_read(tmp_path, capsys):
    path = _toml(tmp_path, "bom.toml", "horizon = 10", "horizon = 10", prefix=b"\xef\xbb\xbf")
    assert main(["solve", path, "--no-qp", "--protocol", "tcp"]) == 0
    assert "J* = 2.798470088" in capsys.readouterr().out


def test_a_mu_of_5000_digits_is_a_number(capsys):
    assert main(["solve", "two_actuator", "--mu", "0." + "5" * 5000 + ",0.5", "--no-qp", "--protocol", "tcp"]) == 0
    assert main(["solve", "two_actuator", "--mu", "1" + "0" * 5000 + ",0.5", "--no-qp"]) == 2
    _, err = capsys.readouterr()
    assert err.startswith("packetloss-cvx: error: --mu:")
    assert err.count("\n") == 1


@pytest.mark.parametrize("field", ["state_weight", "noise_cov", "initial_weight"])
def test_indefinite_matrices_are_refused_relative_to_their_size(field):
    """-99 beside 1e12 passed the former absolute-floor test: the minimum was unbounded below and
    expected_cost(U = 1e6) returned -5.4e15; with noise_cov a cost of -594 came back."""
    bad = [[1e12, 0.0], [0.0, -99.0]]
    with pytest.raises(pl.InputError, match="positive semidefinite") as info:
        pl.System(**{**BASE, field: bad})
    assert info.value.field == field


def test_tiny_weights_are_judged_relative_to_themselves():
    with pytest.raises(pl.InputError, match="positive semidefinite"):
        pl.System(**{**BASE, "state_weight": [[1e-15, 0.0], [0.0, -1e-16]]})
    # rounding-level negatives are accepted and set to zero: the weight is exactly PSD
    s = pl.System(**{**BASE, "state_weight": [[1.0, 1.0], [1.0, 1.0 - 1e-15]]})
    assert np.linalg.eigvalsh(s.state_weights[0]).min() >= 0.0
    assert np.allclose(s.state_weights[0], [[1.0, 1.0], [1.0, 1.0]], atol=1e-14)


def test_indefinite_weight_file_exits_2(tmp_path, capsys):
    path = tmp_path / "indef.toml"
    path.write_text('[plant]\nA = [[0.5, 0.0], [0.0, 1.0]]\nB = [[0.0], [1.0]]\n[cost]\nhorizon = 5\n'
                    'state_weight = [[1e12, 0.0], [0.0, -99.0]]\ninput_weight = [1.0]\n[channel]\nmu = [1.0]\n'
                    '[state]\nx0 = [1.0, 0.0]\n')
    assert main(["solve", str(path)]) == 2
    _, err = capsys.readouterr()
    assert "cost.state_weight: expected a positive semidefinite matrix" in err


def test_devices_and_pipes_are_not_read(tmp_path):
    """/dev/zero read without limit (st_size is 0); a FIFO hung until killed."""
    import os

    with pytest.raises(pl.InputError, match="not a regular file"):
        pl.load_system("/dev/zero")
    fifo = tmp_path / "f.toml"
    os.mkfifo(fifo)
    with pytest.raises(pl.InputError, match="not a regular file"):
        pl.load_system(fifo)


def test_newlines_in_names_keep_one_stderr_line(tmp_path, capsys):
    assert main(["solve", "no\nsuch\nfile"]) == 2
    path = tmp_path / "nl.toml"
    path.write_text(dumps_system(pl.load_example("two_actuator")) + '"a\\nb" = 1\n')
    assert main(["solve", str(path)]) == 2
    _, err = capsys.readouterr()
    assert err.count("\n") == 2            # one line per command
    assert "no\\nsuch\\nfile" in err


def test_a_negative_first_value_is_a_value(capsys):
    """--x0 -1,1 was read as an unknown option."""
    assert main(["solve", "two_actuator", "--x0", "-1,1", "--no-qp", "--protocol", "tcp"]) == 0
    assert main(["solve", "two_actuator", "--x0=-1,1", "--no-qp", "--protocol", "tcp"]) == 0
    first, second = capsys.readouterr().out.split("two-actuator")[1:]
    assert first == second


def test_save_system_round_trips_any_name(tmp_path):
    """json.dumps wrote surrogate pairs for characters beyond U+FFFF, which TOML forbids."""
    data = pl.load_example("two_actuator").to_dict()
    data["name"] = 'pump \U0001f600 \x7f tab\t "q" \\ \u00e9'
    system = system_from_dict(data)
    assert pl.load_system(pl.save_system(system, tmp_path / "s.toml")).name == data["name"]
    with pytest.raises(pl.InputError) as info:
        pl.save_system(system, tmp_path)
    assert info.value.field == "path"


@pytest.mark.parametrize("call", [
    lambda s: pl.closed_form({}, "tcp"),
    lambda s: pl.expected_cost(None, [[0.0]], "tcp"),
    lambda s: pl.solve_qp("two_actuator", "tcp"),
    lambda s: pl.solve_qp(s, "tcp", reference="x"),
    lambda s: pl.solve_qp(s, "tcp", reference=pl.closed_form(pl.load_example("pendulum"), "tcp")),
    lambda s: pl.save_system({}, "x.toml"),
])
def test_api_misuse_is_a_typed_error(call):
    with pytest.raises(pl.InputError, match="system|reference"):
        call(pl.load_example("two_actuator"))


def test_rows_as_arrays_and_masked_arrays():
    rows = [np.array([1.0, 0.0]), np.array([0.0, 1.0])]
    assert pl.System(**{**BASE, "A": rows}).A.tolist() == [[1.0, 0.0], [0.0, 1.0]]
    with pytest.raises(pl.InputError, match="masked"):
        pl.System(**{**BASE, "x0": np.ma.array([1.0, 0.0], mask=[True, False])})


@pytest.mark.parametrize(("call", "field"), [
    # each raised an untyped error (TypeError, AttributeError) or was accepted with a meaningless value
    (lambda s, tmp: __import__("packetloss_cvx.montecarlo", fromlist=["simulate"]).simulate(
        s, 10, closed_loop="no", progress=False), "closed_loop"),
    (lambda s, tmp: pl.audit(systems="pendulum", random=0, progress=False), "systems"),
    (lambda s, tmp: pl.audit(systems=[s, "pendulum"], random=0, progress=False), "systems"),
    (lambda s, tmp: __import__("packetloss_cvx.allocation.delivery", fromlist=["power_model"]).power_model(
        "exponential", 0, scale=[1]), "m"),
    (lambda s, tmp: __import__("packetloss_cvx.allocation.delivery", fromlist=["power_model"]).power_model(
        "exponential", "2", scale=[1]), "m"),
])
def test_api_arguments_of_the_wrong_type_are_typed_input_errors(call, field, tmp_path):
    with pytest.raises(pl.InputError) as info:
        call(pl.load_example("two_actuator"), tmp_path)
    assert info.value.field == field



def test_save_system_overwrites_only_when_told_so_by_a_bool(tmp_path):
    """``overwrite="no"`` (any truthy value) replaced the file; only ``True`` does."""
    system = pl.load_example("two_actuator")
    path = pl.save_system(system, tmp_path / "s.toml")
    path.write_text("# the user's own file\n")
    for value in ("no", "False", 1, [True]):
        with pytest.raises(pl.InputError, match="^overwrite: expected True or False"):
            pl.save_system(system, path, overwrite=value)
    assert path.read_text() == "# the user's own file\n"
    pl.save_system(system, path, overwrite=True)
    assert pl.load_system(path).name == system.name
