"""compare and region --actuator behind a chain (each strategy's critical mean rate), and compare --target (the
cheapest links per strategy for a cost target).

References: the scalar plant behind a Gilbert channel by hand (every strategy's critical mean rate is
``(1 - 1/a^2) / (1 - lambda)``: tests/closedloop/test_actuator_chain_critical.py derives it).
"""

from __future__ import annotations

import json

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.files import save_system
from packetloss_cvx.model.system import System
from packetloss_cvx.tolerances import ACTUATOR_COMPARE_TOL


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def gilbert(tmp_path):
    system = System(A=[[1.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                    channel=GilbertElliott(p=[0.4], r=[0.4]), name="gilbert")
    return str(save_system(system, tmp_path / "gilbert.toml"))


HAND = (1.0 - 1.0 / 1.5 ** 2) / 0.8        # 25/36: burstiness 0.2 kept


def test_region_actuator_behind_a_chain_gives_each_strategy_its_critical_mean_rate(capsys, gilbert):
    code, out, _ = _run(capsys, "region", gilbert, "--actuator", "zero,hold", "--json", "-q")
    assert code == 0
    data = json.loads(out)["actuator"]
    for name in ("zero", "hold"):
        point = data[name]
        assert point["lower"] <= HAND <= point["t"]
        assert point["t"] - HAND <= 2 * ACTUATOR_COMPARE_TOL
        assert point["inside"]["verdict"] == "stable"
        assert point["basis"].startswith("mean rate")


def test_compare_behind_a_chain_names_the_critical_mean_rate(capsys, gilbert):
    code, out, _ = _run(capsys, "compare", gilbert, "--actuator", "zero,buffer:2", "-q")
    assert code == 0
    rows = [line for line in out.splitlines() if line.startswith(("zero", "buffer:2"))]
    assert len(rows) == 2
    assert all("critical mean rate" in row and "upper end proved stable" in row for row in rows)


def test_compare_behind_a_chain_outside_the_proof_says_why_per_strategy(capsys, tmp_path):
    system = System(A=[[1.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                    channel=GilbertElliott(p=[0.4], r=[0.4], h_bad=[0.2]), name="leaky")
    path = str(save_system(system, tmp_path / "leaky.toml"))
    code, out, _ = _run(capsys, "compare", path, "--actuator", "hold", "--json", "-q")
    assert code == 0
    row = json.loads(out)["strategies"]["hold"]
    assert row["critical"]["reason"].startswith("monotonicity in the mean rate is proved")
