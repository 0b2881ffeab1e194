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


@pytest.fixture
def scalar(tmp_path):
    system = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0],
                    name="scalar")
    return str(save_system(system, tmp_path / "scalar.toml"))


def test_compare_target_gives_each_strategy_its_cheapest_links_with_the_basis(capsys, scalar):
    # zero's cost from x0 is the positive root of (4 mu - 3) P^2 - 4 P - 1 = 0: 4 + 3 sqrt(2) at mu = 7/8
    target = 4 + 3 * 2 ** 0.5
    code, out, _ = _run(capsys, "compare", scalar, "--actuator", "zero,hold", "--target", repr(target),
                        "--beta", "2", "--gap", "1e-7", "--json", "-q")
    assert code == 0
    data = json.loads(out)
    assert data["target"] == {"alpha": target, "basis": "total from x0", "beta": [2.0]}
    zero = data["strategies"]["zero"]
    assert zero["links"]["verdict"] == "reachable"
    assert zero["links"]["mu"][0] == pytest.approx(0.875, abs=1e-6)
    assert zero["links"]["communication_cost"] == pytest.approx(1.75, abs=2e-6)
    assert zero["radius"] is not None
    assert "critical" in zero
    # hold costs more than zero at mu = 7/8 on this plant: it needs better links for the same target
    assert data["strategies"]["hold"]["links"]["mu"][0] > 0.875


def test_compare_target_text_has_the_new_columns_and_says_unreachable(capsys, scalar):
    code, out, _ = _run(capsys, "compare", scalar, "--actuator", "zero,hold", "--target", "4", "-q")
    assert code == 0
    lines = out.splitlines()
    assert "total noise-free cost from x0 is <= 4" in lines[0]
    assert "beta'mu" in lines[1]
    assert "mu*" in lines[1]
    rows = [line for line in lines if line.startswith(("zero", "hold"))]
    assert len(rows) == 2
    assert all("unreachable" in row and "(least 4.23607)" in row for row in rows)


@pytest.mark.parametrize(("argv", "flag"), [
    (["--beta", "1"], "--beta"),
    (["--gap", "1e-3"], "--gap"),
    (["--target", "-1"], "--target"),
    (["--target", "abc"], "--target"),
    (["--target", "8", "--beta", "1,2"], "--beta"),
])
def test_compare_target_bad_input_exits_2_with_one_line(capsys, scalar, argv, flag):
    code, out, err = _run(capsys, "compare", scalar, "--actuator", "zero", *argv, "-q")
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1
    assert flag in err


def test_compare_target_behind_a_chain_designs_the_mean_rate_along_its_family(capsys, gilbert):
    code, out, _ = _run(capsys, "compare", gilbert, "--actuator", "zero", "--target", "20", "--json", "-q")
    assert code == 0
    links = json.loads(out)["strategies"]["zero"]["links"]
    assert links["verdict"] == "reachable"
    assert links["mu"][0] > HAND                  # above the critical mean rate: the cost is finite only there
