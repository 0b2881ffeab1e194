"""``solve`` where a channel never delivers (mu_i = 0): the row of the receding-horizon gain on that channel is the
limit of the optimal row as mu_i -> 0 and never reaches the plant. The text says so instead of showing it as a law,
its eigenvalues and all-delivered verdict drop those rows, and where no channel ever delivers the cost is named the
open-loop cost. The JSON keeps ``gain`` and ``closed_loop_eigenvalues`` and adds ``gain_acts``, ``gain_note`` and
``cost_note``.

Hand values, one step (N = 1) of x' = a x + v u, Q = R = 1, x0 = 1: J_tcp(u) = (a + mu u)^2 + mu u^2 has its
minimiser u = -a / (1 + mu), so the TCP-like gain is a / (1 + mu), 2 for a = 2 as mu -> 0 and 1/3 for a = 0.5 at
mu = 1/2; J_udp(u) = (a + mu u)^2 + mu (1 - mu) u^2 + mu u^2 has u = -a / 2 at every mu > 0 (gain 1 for a = 2,
1/4 for a = 0.5). At mu = 0 neither cost sees u: both are the open-loop a^2 = 4.
"""

import numpy as np
import pytest

from packetloss_cvx.cli.parser import build_parser
from packetloss_cvx.cli.solve import run
from packetloss_cvx.model.files import save_system
from packetloss_cvx.model.system import System


def solve(tmp_path, system: System):
    path = str(save_system(system, tmp_path / "plant.toml"))
    return run(build_parser().parse_args(["solve", path, "--no-qp"]))


def section(text: str, protocol: str) -> str:
    """The lines of one protocol's section of the text."""
    return text.split(f"{protocol.upper()}-like")[1].split("-like")[0]


def row(text: str, label: str) -> str:
    found = [line.strip()[len(label):].strip() for line in text.splitlines() if line.strip().startswith(label)]
    assert len(found) == 1, (label, text)
    return found[0]


@pytest.mark.parametrize(("protocol", "limit_gain"), [("tcp", 2.0), ("udp", 1.0)])
def test_no_channel_delivers_shows_no_acting_gain_and_names_the_open_loop_cost(tmp_path, protocol, limit_gain):
    s = System(A=[[2.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.0], x0=[1.0])
    result = solve(tmp_path, s)
    entry = result.data[protocol]
    assert entry["cost"] == pytest.approx(4.0, rel=1e-12)             # a^2 x0^2: no input reaches the plant
    assert entry["gain"] == [[pytest.approx(limit_gain, rel=1e-12)]]   # kept: the limit as mu -> 0
    assert entry["gain_acts"] == [False]
    assert "no channel delivers" in entry["gain_note"]
    assert "open-loop cost" in entry["cost_note"]
    text = section(result.text, protocol)
    assert "open-loop cost" in row(text, "cost")
    assert "[basis: paper]" in row(text, "cost")
    assert row(text, "K (u = -K x)").startswith("no channel delivers (mu = 0): no row of K acts")
    assert "u1" not in text                                            # no gain matrix is printed
    assert row(text, "eig(A - B K)").startswith("2 ")                  # A's own eigenvalue, not a - K
    assert "all delivered" not in text


@pytest.mark.parametrize(("protocol", "gains", "acting_eig"), [
    ("tcp", [2.0, 1 / 3], "2, 0.1667"),        # the full gain's eigenvalues would read 0.1667, 0 (no flag)
    ("udp", [1.0, 0.25], "2, 0.25"),           # the full gain's would read 1, 0.25
])
def test_a_channel_that_never_delivers_has_its_gain_row_named_and_dropped_from_the_loop(tmp_path, protocol, gains,
                                                                                    acting_eig):
    s = System(A=np.diag([2.0, 0.5]), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
               mu=[0.0, 0.5], x0=[1.0, 1.0])
    result = solve(tmp_path, s)
    entry = result.data[protocol]
    assert np.allclose(np.diag(entry["gain"]), gains, rtol=1e-12)
    assert entry["gain_acts"] == [False, True]
    assert entry["gain_note"].startswith("u1 (mu = 0) is never delivered")
    assert entry["cost_note"] is None                                 # u2 is delivered: not the open-loop cost
    text = section(result.text, protocol)
    assert "open-loop" not in row(text, "cost")
    assert row(text, "never acts").startswith("u1 (mu = 0) is never delivered")
    assert row(text, "eig(A - B K)") == f"{acting_eig} (u1 dropped: never delivered)"
    # with u1 never delivered, x1 runs open loop at 2 even when every packet that can be delivered is
    assert row(text, "all delivered") == ("UNSTABLE even with every packet delivered (radius of A - B K = 2); "
                                          "u1 never delivered")


def test_every_channel_delivering_keeps_the_gain_and_adds_empty_notes(tmp_path):
    s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    result = solve(tmp_path, s)
    entry = result.data["tcp"]
    assert entry["gain_acts"] == [True]
    assert entry["gain_note"] is None
    assert entry["cost_note"] is None
    text = section(result.text, "tcp")
    assert row(text, "eig(A - B K)") == "0.3333"                     # 1 - 2/3
    assert "never" not in text
