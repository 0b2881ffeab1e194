"""Error messages speak the language of the interface the user called: the command line's flags, not the API's
keyword arguments, and advice that names an option that exists."""

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.cli.parser import build_parser
from packetloss_cvx.errors import InputError
from packetloss_cvx.model.files import load_example


def _parses(*words):
    """The advice is a command line the parser accepts (an independent check that the option and value exist)."""
    build_parser().parse_args(["allocate", "pendulum_bursty", "--alpha", "60", "--beta", "1", *words])
    return True


def test_allocate_attainable_behind_a_chain_advises_flags_that_exist(capsys):
    assert load_example("pendulum_bursty").channel is not None
    argv = ["allocate", "pendulum_bursty", "--protocol", "tcp", "--alpha", "60", "--beta", "1", "--target",
            "attainable"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("packetloss-cvx: error: --target: ")
    assert "target=" not in err[0]
    assert "protocol=" not in err[0]
    assert "--protocol udp" in err[0]
    assert _parses("--protocol", "udp", "--target", "attainable")
    assert "--target paper" in err[0]
    assert _parses("--protocol", "tcp", "--target", "paper")


def test_the_api_names_its_own_arguments_with_values_they_take():
    from packetloss_cvx.allocation.api import allocate
    with pytest.raises(InputError, match="target") as info:
        allocate(load_example("pendulum_bursty"), "tcp", 60.0, [1.0], target="attainable")
    assert "target='udp'" not in str(info.value)         # no such target
    assert "protocol='udp'" in str(info.value)
