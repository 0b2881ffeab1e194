"""The command line's grammar (cli/parser.py): an option is never guessed from a prefix of another, counted
and grouped short flags parse, and FILE's help names every packaged example; a FILE or a value that cannot be
read (too large, too deep, not a number, a path with newlines) is exit 2 with one stderr line, a byte order mark
and a negative first value are read."""

import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.model.files import dumps_system


def test_every_packaged_example_is_named_in_the_help():
    """FILE's help listed pendulum and two_actuator, not pendulum_bursty (the one Gilbert-Elliott example)."""
    from packetloss_cvx.cli.parser import FILE_HELP
    from packetloss_cvx.model.files import example_names
    assert all(name in FILE_HELP for name in example_names())



@pytest.mark.parametrize(("argv", "field"), [
    # sweep has no --x0: argparse took it as an abbreviation of --x0-scales and swept x0 times 2 and -1
    # (exit 0) where the user asked for x0 = (2, -1), as solve --x0 means
    (["sweep", "two_actuator", "--x0", "2,-1"], "arguments: one of the arguments --mu-grid"),   # no sweep kind given
    (["sweep", "two_actuator", "--x0", "0.5"], "arguments: one of the arguments --mu-grid"),
    (["sweep", "two_actuator", "--mu-grid", "3", "--x0", "0,0"], "--x0"),   # was reported as --x0-scales
    (["solve", "two_actuator", "--mu-s", "x.csv"], "--mu-s"),
    (["simulate", "two_actuator", "--samp", "10"], "--samp"),
])
def test_an_option_is_not_guessed_from_a_prefix(capsys, argv, field):
    assert main(argv + ["--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"packetloss-cvx: error: {field}"), err
    assert field.startswith("arguments") or err[0].endswith("not an option of this command (see its --help)"), err



def test_counted_and_grouped_short_flags_still_parse(capsys):
    assert main(["solve", "two_actuator", "-vv", "--no-qp"]) == 0
    assert "TCP-like" in capsys.readouterr().out


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


def test_indefinite_weight_file_exits_2(tmp_path, capsys):
    path = tmp_path / "indef.toml"
    path.write_text('[plant]\nA = [[0.5, 0.0], [0.0, 1.0]]\nB = [[0.0], [1.0]]\n[cost]\nhorizon = 5\n'
                    'state_weight = [[1e12, 0.0], [0.0, -99.0]]\ninput_weight = [1.0]\n[channel]\nmu = [1.0]\n'
                    '[state]\nx0 = [1.0, 0.0]\n')
    assert main(["solve", str(path)]) == 2
    _, err = capsys.readouterr()
    assert "cost.state_weight: expected a positive semidefinite matrix" in err


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
