"""``--mu-schedule``, a non-stationary channel: ``solve`` says which loop its stability verdict is on (step 0's
receding-horizon law run for ever over the first step's channel) in its text and JSON, and the commands whose loop
runs for ever over one channel (``region``, ``compare``) do not offer the option.

Hand value: x' = x + v u with P(v = 1) = mu under u = -K x has E[x'^2] = (mu (1 - K)^2 + 1 - mu) E[x^2], so the
second-moment radius over a channel mu is mu (1 - K)^2 + 1 - mu.
"""

import json

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.model.files import save_system
from packetloss_cvx.model.system import System

#: the schedule: delivered 9 times in 10 at step 0, then 2 in 10
SCHEDULE = [[0.9], [0.2], [0.2]]


def scheduled(tmp_path):
    s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    path = save_system(s, tmp_path / "scalar.toml")
    csv = tmp_path / "mu.csv"
    csv.write_text("".join(f"{row[0]}\n" for row in SCHEDULE))
    return str(path), str(csv)


def test_solve_says_its_verdict_is_step_0s_law_over_the_first_steps_channel(tmp_path, capsys):
    path, csv = scheduled(tmp_path)
    assert main(["solve", path, "--mu-schedule", csv, "--no-qp", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert main(["solve", path, "--mu-schedule", csv, "--no-qp"]) == 0
    text = capsys.readouterr().out
    loops = [line for line in text.splitlines() if line.strip().startswith("closed loop")]
    assert len(loops) == 2
    for protocol, line in zip(("tcp", "udp"), loops, strict=True):
        entry = data[protocol]
        K = entry["gain"][0][0]
        first, later = SCHEDULE[0][0], SCHEDULE[1][0]
        assert entry["mean_square_spectral_radius"] == pytest.approx(first * (1 - K) ** 2 + 1 - first, rel=1e-12)
        assert entry["mean_square_spectral_radius"] != pytest.approx(later * (1 - K) ** 2 + 1 - later, rel=1e-3)
        note = entry["stability_note"]
        assert "non-stationary" in note
        assert "step 0's receding-horizon law run for ever over the first step's channel" in note
        assert "least mu per channel: 0.2" in note
        assert "over the first step's mu = 0.9" in line
        assert note in line                        # the text says it too, not only the JSON


@pytest.mark.parametrize("command", ["region", "compare"])
def test_commands_that_need_a_stationary_channel_do_not_offer_a_schedule(tmp_path, capsys, command):
    path, csv = scheduled(tmp_path)
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    assert "--mu-schedule" not in capsys.readouterr().out
    assert main([command, path, "--mu-schedule", csv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["packetloss-cvx: error: --mu-schedule: not an option of this command (see its --help)"]


@pytest.mark.parametrize("command", ["solve", "simulate"])
def test_commands_that_take_a_schedule_still_offer_it(capsys, command):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert "--mu-schedule CSV" in capsys.readouterr().out
