"""Results beyond the double range on the command line: JSON never crashes on them; each such number goes out as
null beside a ``<key>_reason`` (the convention of simulate's ``stderr_reason``), and the text says it is an
overflow, not a value.

The plant: x+ = 3 x + v u over 200 steps, mu = 0.1 (/tmp-free: written to tmp_path). References by hand: the
TCP-like law K = 26.71 run in closed loop with the actuator zeroing a lost input multiplies E[x^2] by
mu (3 - K)^2 + (1 - mu) 9 = 64.3 a step, so its 200-step cost is about 64.3^200 = 1e361, beyond 1.8e308.
"""

from __future__ import annotations

import json
import math

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.model.files import save_system
from packetloss_cvx.model.system import System


@pytest.fixture
def exploding(tmp_path):
    system = System(A=[[3.0]], B=[[1.0]], horizon=200, state_weight=[1.0], input_weight=[1.0], mu=[0.1], x0=[1.0],
                    name="exploding")
    return str(save_system(system, tmp_path / "exploding.toml"))


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("actuator", ["all", "zero", "hold", "buffer:3"])
def test_solve_actuator_json_gives_an_overflowing_loop_cost_as_null_with_its_reason(capsys, exploding, actuator):
    code, out, err = _run(capsys, "solve", exploding, "--json", "--actuator", actuator)
    assert (code, err) == (0, "")
    rows = json.loads(out)["tcp"]["actuator"]["strategies"]
    gain = json.loads(out)["tcp"]["gain"][0][0]
    growth = 0.1 * (3 - gain) ** 2 + 0.9 * 9       # E[x^2]'s factor a step under zero
    assert 200 * math.log10(growth) > 308
    for row in rows.values():
        assert row["cost"] is None
        assert "exceed the double range" in row["cost_reason"]


def test_solve_actuator_text_says_the_loop_cost_overflows(capsys, exploding):
    code, out, _ = _run(capsys, "solve", exploding, "--actuator", "zero")
    assert code == 0
    line = next(t for t in out.splitlines() if t.strip().startswith("zero:"))
    assert "exceed the double range" in line
    assert "inf" not in line


def test_solve_actuator_out_file_is_written(capsys, exploding, tmp_path):
    target = tmp_path / "u.json"
    code, _, err = _run(capsys, "solve", exploding, "--actuator", "all", "--out", str(target))
    assert (code, err) == (0, "")
    assert json.loads(target.read_text())["tcp"]["actuator"]["strategies"]["zero"]["cost"] is None


def test_simulate_closed_loop_actuator_json_has_no_z_without_an_error_bar(capsys, exploding):
    code, out, err = _run(capsys, "simulate", exploding, "--closed-loop", "--actuator", "all", "--samples", "200",
                          "--json")
    assert (code, err) == (0, "")
    laws = json.loads(out)["actuator"]
    assert {"tcp", "udp"} <= set(laws)
    for law in (laws["tcp"], laws["udp"]):
        assert set(law) == {"zero", "hold", "buffer:200"}
        for row in law.values():
            assert row["stable"] is False
            assert row["z"] is None
            assert row["stderr"] is None
            assert row["stderr_reason"].startswith("no error bar")


def test_sweep_stability_gives_the_open_loop_radius_where_nothing_is_delivered(capsys, exploding):
    # at mu = 0 no input arrives: x+ = 3 x whatever the law, radius 3^2 = 9 (the TCP-like gain there is ~1e190)
    code, out, err = _run(capsys, "sweep", exploding, "--mu-grid", "5", "--stability", "--json")
    assert (code, err) == (0, "")
    data = json.loads(out)
    table = data["table"]
    at_zero = table["mu1"].index(0.0)
    assert table["radius_tcp"][at_zero] == pytest.approx(9.0, rel=1e-14)
    assert table["radius_udp"][at_zero] == pytest.approx(9.0, rel=1e-14)
    assert data["radius_tcp"]["min"] == min(table["radius_tcp"])
    assert data["radius_tcp"]["max"] == max(table["radius_tcp"])


def test_sweep_stability_counts_the_points_without_a_radius_and_says_why(capsys, exploding, monkeypatch):
    import packetloss_cvx.studies.engine as engine
    from packetloss_cvx.errors import NumericalError

    real = engine.mean_square_radius

    def failing_at_half(A, B, K, mu):
        if mu[0] == 0.5:
            raise NumericalError("mean-square radius: the eigenvalue routine failed (planted)")
        return real(A, B, K, mu)

    monkeypatch.setattr(engine, "mean_square_radius", failing_at_half)
    code, out, err = _run(capsys, "sweep", exploding, "--mu-grid", "5", "--stability", "--json")
    assert (code, err) == (0, "")
    data = json.loads(out)
    radii = data["table"]["radius_tcp"]
    assert radii[data["table"]["mu1"].index(0.5)] is None
    assert data["radius_tcp"]["min"] == min(r for r in radii if r is not None)
    assert data["radius_tcp"]["missing_points"] == 1
    assert "not computed at 1 of 5 points" in data["radius_tcp"]["reason"]
    code, out, _ = _run(capsys, "sweep", exploding, "--mu-grid", "5", "--stability")
    line = next(t for t in out.splitlines() if "TCP-like law in closed loop" in t)
    assert "nan" not in line
    assert "not computed at 1 of 5 points" in line
