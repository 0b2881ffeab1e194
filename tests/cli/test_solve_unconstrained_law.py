"""``solve`` with constraints prints the constrained plan's cost, and beside it the closed form's gain K and its
loop's verdict, which know nothing of the bounds: the text labels them as the unconstrained law's and names the
command for the constrained loop; the JSON adds ``law_note`` (no key renamed). Without constraints nothing changes.

Hand value: one step of x' = x + v u, Q = R = 1, x0 = 1, mu = 1/2: the TCP-like gain is 1 / (1 + mu) = 2/3, far
outside the bound |u| <= 0.01.
"""

import pytest

from packetloss_cvx.cli.parser import build_parser, join_negative_values
from packetloss_cvx.cli.solve import run
from packetloss_cvx.model.files import save_system
from packetloss_cvx.model.system import System


def solve(tmp_path, *extra):
    s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    path = str(save_system(s, tmp_path / "scalar.toml"))
    return path, run(build_parser().parse_args(join_negative_values(["solve", path, *extra])))


def lines(text: str, label: str) -> list[str]:
    return [line.strip() for line in text.splitlines() if line.strip().startswith(label)]


def test_gain_and_verdict_under_constraints_are_labelled_the_unconstrained_laws(tmp_path):
    path, result = solve(tmp_path, "--u-min", "-0.01", "--u-max", "0.01")
    tcp = result.data["tcp"]
    assert tcp["constrained"]["status"] == "optimal"
    assert tcp["constrained"]["inputs"][0][0] == pytest.approx(-0.01, abs=1e-7)     # the bound binds
    assert tcp["gain"] == [[pytest.approx(2 / 3, rel=1e-12)]]                         # the closed form's, unchanged
    for protocol in ("tcp", "udp"):
        note = result.data[protocol]["law_note"]
        assert "unconstrained law's" in note
        assert f"simulate {path} with the same constraints" in note
    assert lines(result.text, "K (u = -K x, the unconstrained law)") == ["K (u = -K x, the unconstrained law)"] * 2
    loops = lines(result.text, "closed loop")
    assert len(loops) == 2
    for line in loops:
        assert line.endswith(f"; the unconstrained law's loop (the constrained loop: simulate {path} with the same "
                             "constraints)")


def test_without_constraints_the_gain_is_not_labelled(tmp_path):
    _, result = solve(tmp_path)
    assert "law_note" not in result.data["tcp"]
    assert "unconstrained" not in result.text
    assert len(lines(result.text, "K (u = -K x)")) == 2
