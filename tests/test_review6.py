"""Review 6, a hostile new user on the day's fixes: each test is one defect found, failing before its fix."""

import json

from packetloss_cvx.cli import main


def test_solve_json_names_each_protocol_as_the_readme_says(capsys):
    # README and design.md: "each protocol has `protocol`, `cost`, ..."; solve --json left it out
    assert main(["solve", "two_actuator", "--json", "--no-qp"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["tcp"]["protocol"] == "tcp" and data["udp"]["protocol"] == "udp"
    assert main(["solve", "pendulum_bursty", "--json", "--no-qp", "--protocol", "udp"]) == 0
    assert json.loads(capsys.readouterr().out)["udp"]["protocol"] == "udp"
