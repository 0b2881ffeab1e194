"""compare, region --actuator and allocate --actuator on the command line.

References: the scalar plant by hand (x' = 2x + v u: every strategy stabilises iff mu > 1 - 1/a^2 = 3/4; zero's
optimal law is the modified Riccati equation's positive root), and bad input: exit 2 and one line.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.model.files import save_system
from packetloss_cvx.model.system import System
from packetloss_cvx.tolerances import ACTUATOR_COMPARE_TOL, ACTUATOR_DP_RTOL


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def scalar(tmp_path):
    system = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0],
                    name="scalar")
    return str(save_system(system, tmp_path / "scalar.toml"))


def test_compare_puts_the_strategies_side_by_side_with_hand_values(capsys, scalar):
    code, out, _ = _run(capsys, "compare", scalar, "--actuator", "zero,hold,buffer:2", "--json", "-q")
    assert code == 0
    rows = json.loads(out)["strategies"]
    assert list(rows) == ["zero", "hold", "buffer:2"]
    for row in rows.values():
        assert row["critical"]["t"] - ACTUATOR_COMPARE_TOL <= 0.75 + ACTUATOR_COMPARE_TOL
        assert row["critical"]["t"] >= 0.75
        assert row["critical"]["inside"]["verdict"] == "stable"
    # zero: (4 mu - 3) P^2 - 4 P - 1 = 0 at mu = 0.9 (the modified Riccati equation times 1 + P)
    a2 = 4 * 0.9 - 3
    P = (4 + np.sqrt(16 + 4 * a2)) / (2 * a2)
    assert rows["zero"]["initial_cost"] == pytest.approx(P, rel=ACTUATOR_DP_RTOL)
    assert rows["buffer:2"]["initial_cost"] <= rows["zero"]["initial_cost"] * (1 + ACTUATOR_DP_RTOL)


def test_compare_region_and_allocate_take_buffer_hold_with_the_hand_critical_mu(capsys, scalar):
    """buffer:L:hold's optimal law and region, wired like the others: critical mu 3/4 on both sides (hand), and
    mu* = 0.5 below it not stabilisable."""
    code, out, _ = _run(capsys, "compare", scalar, "--actuator", "buffer:2:hold,buffer:3:hold", "--json", "-q")
    assert code == 0
    rows = json.loads(out)["strategies"]
    assert list(rows) == ["buffer:2:hold", "buffer:3:hold"]
    for row in rows.values():
        assert row["radius"] < 1.0
        assert row["critical"]["lower"] <= 0.75 <= row["critical"]["t"]
        assert row["critical"]["inside"]["verdict"] == "stable"
        assert row["critical"]["outside"]["verdict"] == "unstable"
    code, out, _ = _run(capsys, "region", scalar, "--law", "dp", "--actuator", "buffer:2:hold", "--json", "-q")
    assert code == 0
    point = json.loads(out)["actuator"]["buffer:2:hold"]
    assert point["lower"] <= 0.75 <= point["t"]
    code, out, _ = _run(capsys, "allocate", scalar, "--protocol", "tcp", "--alpha", "1e6", "--beta", "1",
                        "--bounds", "0.5,1", "--actuator", "buffer:2:hold", "--json", "-q")
    assert code == 0
    assert json.loads(out)["actuator"]["buffer:2:hold"]["verdict"] == "unstable"


def test_compare_text_has_a_row_per_strategy(capsys, scalar):
    code, out, _ = _run(capsys, "compare", scalar, "--actuator", "zero,hold", "-q")
    assert code == 0
    assert [line.split()[0] for line in out.splitlines()[2:4]] == ["zero", "hold"]


def test_region_actuator_gives_each_strategy_its_critical_mu(capsys, scalar):
    code, out, _ = _run(capsys, "region", scalar, "--law", "dp", "--actuator", "zero,buffer:3", "--json", "-q")
    assert code == 0
    data = json.loads(out)
    for name in ("zero", "buffer:3"):
        point = data["actuator"][name]
        assert point["lower"] <= 0.75 <= point["t"]
        assert point["outside"]["verdict"] == "unstable"


def test_allocate_actuator_checks_the_allocation_under_each_strategy(capsys, scalar):
    """alpha far above the cost: mu* sits at the lower bound 0.5 < 3/4, where no strategy stabilises (hand)."""
    code, out, _ = _run(capsys, "allocate", scalar, "--protocol", "tcp", "--alpha", "1e6", "--beta", "1",
                        "--bounds", "0.5,1", "--actuator", "zero,buffer:2", "--json", "-q")
    assert code == 0
    data = json.loads(out)
    assert data["mu"] == pytest.approx([0.5])
    assert {name: row["verdict"] for name, row in data["actuator"].items()} == {"zero": "unstable",
                                                                                "buffer:2": "unstable"}


def test_allocate_udp_checks_zero_and_noise_free_hold_with_the_laws_a_udp_like_controller_runs(capsys, scalar):
    """No noise, b = 1: the UDP-like controller rebuilds the held input from the states, so hold's TCP-like laws
    are its own; mu* = 0.5 < 3/4 (hand) is not stabilisable by either."""
    code, out, _ = _run(capsys, "allocate", scalar, "--protocol", "udp", "--alpha", "1e6", "--beta", "1",
                        "--bounds", "0.5,1", "--actuator", "zero,hold")
    assert code == 0
    assert "zero at mu*" in out
    assert out.count("NOT stabilisable by any UDP-like law (proved)") == 2


@pytest.mark.parametrize(("actuator", "noise", "why"), [
    ("buffer:2", None, "the age of the plan each actuator plays is hidden"),
    ("zero,buffer:2:hold", None, "the age of the plan each actuator plays is hidden"),
    ("hold", [[0.1]], "with process noise")])
def test_allocate_udp_asking_for_a_law_only_acknowledgements_allow_is_exit_2_and_one_line(capsys, tmp_path, actuator,
                                                                                         noise, why):
    system = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0],
                    noise_cov=noise)
    path = str(save_system(system, tmp_path / "s.toml"))
    code, out, err = _run(capsys, "allocate", path, "--protocol", "udp", "--alpha", "1e6", "--beta", "1",
                          "--actuator", actuator)
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1
    assert "--actuator:" in err
    assert "without acknowledgements is not computed" in err
    assert why in err
    assert "use protocol tcp" in err


@pytest.mark.parametrize(("argv", "message"), [
    (["compare", "{f}", "--actuator", "buffer:0"], "--actuator: expected zero, hold or buffer:L"),
    (["compare", "{f}", "--actuator", "buffer:4"], "<= 3 (the horizon)"),
    (["compare", "{f}", "--actuator", "drop"], "--actuator: expected zero, hold or buffer:L"),
    (["compare", "{f}", "--direction", "1,2"], "--direction: expected 1 nonnegative"),
    (["region", "{f}", "--actuator", "buffer:9"], "--actuator: expected"),
    (["allocate", "{f}", "--protocol", "tcp", "--alpha", "2", "--beta", "1", "--actuator", "zeroes"],
     "--actuator: expected"),
])
def test_bad_actuator_input_is_exit_2_and_one_line(capsys, scalar, argv, message):
    code, out, err = _run(capsys, *[a.replace("{f}", scalar) for a in argv])
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1
    assert message in err


def test_compare_on_the_default_strategies_refuses_an_over_budget_buffer_and_compares_the_rest(capsys):
    code, out, _ = _run(capsys, "compare", "two_actuator", "--json", "-q")
    assert code == 0
    data = json.loads(out)["strategies"]
    assert data["buffer:10"]["radius"] is None
    assert "buffer:6 or shorter" in data["buffer:10"]["reason"]
    assert data["zero"]["radius"] < 1.0
    assert data["hold"]["radius"] < 1.0


def test_the_critical_points_note_is_printed_beside_its_bracket(capsys, scalar, monkeypatch):
    """Where the lower end was stepped down below the float crossing (two_actuator, buffer:2:hold: proved at 0, the
    crossing at 0.061, 45 s), the text says so as the JSON's note does. The scalar's point (a = 2: crossing 3/4, by
    hand) is given such a note here, as actuator_critical words it, so the check runs in a second."""
    import dataclasses

    from packetloss_cvx.cli import actuator_section

    real = actuator_section.actuator_critical
    note = "the lower end is proved 0.75 below the float crossing 0.75 (between them no certificate checks)"

    def stepped(*args, **kwargs):
        return dataclasses.replace(real(*args, **kwargs), note=note)

    monkeypatch.setattr(actuator_section, "actuator_critical", stepped)
    for argv in (["region", scalar, "--law", "dp", "--actuator", "buffer:2"], ["compare", scalar, "--actuator",
                                                                                "buffer:2"]):
        code, out, _ = _run(capsys, *argv, "-q")
        assert code == 0
        assert f"lower end proved unstable; {note})" in out
        code, out, _ = _run(capsys, *argv, "-q", "--json")
        rows = json.loads(out)["actuator" if argv[0] == "region" else "strategies"]
        assert (rows["buffer:2"] if argv[0] == "region" else rows["buffer:2"]["critical"])["note"] == note
