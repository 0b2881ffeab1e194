"""Error messages speak the language of the interface the user called: the command line's flags, not the API's
keyword arguments, and advice that names an option that exists."""

from packetloss_cvx.cli import main
from packetloss_cvx.cli.parser import build_parser
from packetloss_cvx.model.files import load_example


def _parses(*words):
    """The advice is a command line the parser accepts (an independent check that the option and value exist)."""
    build_parser().parse_args(["allocate", "pendulum_bursty", "--alpha", "60", "--beta", "1", *words])
    return True


def test_an_api_refusal_of_the_target_is_reported_under_the_flag(capsys):
    """A file with lossy sensor links: the API refuses target 'attainable' under its argument ``target``; the command
    line reports it under --target, the option the user typed."""
    assert load_example("pendulum_sensor").sensor is not None
    argv = ["allocate", "pendulum_sensor", "--protocol", "tcp", "--alpha", "600", "--beta", "1", "--target",
            "attainable"]
    assert _parses("--protocol", "tcp", "--target", "attainable")
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("packetloss-cvx: error: --target: "), err[0]
