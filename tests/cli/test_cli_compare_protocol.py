"""compare --protocol: a UDP-like controller's rows. Where it can run the strategy's TCP-like optimal law (zero on
Bernoulli links; hold without noise and with B of full column rank: closedloop.actuator_design.check_protocol) that
law is its optimum, so its row is the TCP-like row; elsewhere the row gives the reason, and a strategy named with
--actuator is refused (exit 2, one line)."""

import json

import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.model.files import save_system


def _json(capsys, *argv):
    code = main([*argv, "--json", "-q"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def test_udp_rows_are_the_tcp_rows_where_the_controller_can_run_the_law(capsys):
    tcp = _json(capsys, "compare", "two_actuator", "--actuator", "zero,hold,buffer:2")
    udp = _json(capsys, "compare", "two_actuator", "--actuator", "zero,hold", "--protocol", "udp")
    assert (tcp["protocol"], udp["protocol"]) == ("tcp", "udp")
    for name in ("zero", "hold"):          # two_actuator: no process noise, B = I of full column rank
        assert udp["strategies"][name] == tcp["strategies"][name]
    assert "reason" not in tcp["strategies"]["buffer:2"]


def test_udp_gives_the_reason_for_each_strategy_it_cannot_run(capsys, tmp_path):
    noisy = pl.System(A=[[1.2]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0],
                      noise_cov=[[0.1]])
    path = save_system(noisy, tmp_path / "noisy.toml")
    data = _json(capsys, "compare", str(path), "--protocol", "udp")
    rows = data["strategies"]
    assert rows["zero"]["radius"] is not None
    assert "reason" not in rows["zero"]
    for name in ("hold", "buffer:3"):       # the held input is hidden by the noise; the buffer's age always
        assert rows[name]["radius"] is None
        assert "without acknowledgements" in rows[name]["reason"]
    code = main(["compare", str(path), "--protocol", "tcp", "-q"])
    assert code == 0
    capsys.readouterr()


@pytest.mark.parametrize("actuator", ["buffer:2", "zero,buffer:2"])
def test_a_named_strategy_udp_cannot_run_is_refused_in_one_line(capsys, actuator):
    code = main(["compare", "two_actuator", "--actuator", actuator, "--protocol", "udp"])
    out, err = capsys.readouterr()
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1
    assert err.startswith("packetloss-cvx: error: --actuator: buffer:2's optimal law without acknowledgements")
