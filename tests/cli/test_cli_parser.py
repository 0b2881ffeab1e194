"""The command line's grammar (cli/parser.py): an option is never guessed from a prefix of another, counted
and grouped short flags parse, and FILE's help names every packaged example."""

import pytest

from packetloss_cvx.cli import main


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
