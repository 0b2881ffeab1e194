"""The constrained commands at their edges: infinite bounds in strict JSON, work refused before it starts, the
chain file, the costs' bases, soft rows' violations in the text."""

from __future__ import annotations

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.files import save_system


def _scalar(tmp_path, name="scalar.toml", horizon=8, a=1.2, mu=0.7, **table):
    s = pl.System(A=[[a]], B=[[1.0]], horizon=horizon, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[3.0])
    return save_system(s, tmp_path / name, constraints=Constraints(**table) if table else None)


def test_infinite_bounds_are_null_in_the_json_of_simulate_and_solve(tmp_path, capsys):
    """An infinite entry leaves a bound out (design.md's own example has one): the JSON is strict (no inf), the
    entry null in its place, on stdout and in --out."""
    path = _scalar(tmp_path, u_min=[-1.0], u_max=[np.inf], du_max=[np.inf])
    out = tmp_path / "o.json"
    assert main(["simulate", str(path), "--json", "--quiet", "--samples", "2", "--mpc-samples", "2", "--steps", "3",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    for text in (printed, out.read_text()):
        loop = json.loads(text, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))["constrained_loop"]
        assert loop["constraints"] == {"u_min": [-1.0], "u_max": [None], "du_max": [None]}
    assert main(["solve", "two_actuator", "--json", "--quiet", "--u-max", "0.5,inf", "--du-max", "0.3,inf"]) == 0
    data = json.loads(capsys.readouterr().out, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
    assert data["tcp"]["constrained"]["status"] == "optimal"


@pytest.mark.parametrize("extra", [["--mpc-samples", "1000000000"], ["--steps", "10000000", "--mpc-samples", "2"],
                                   ["--mpc-samples", "100000", "--steps", "1000"]])
def test_the_constrained_loop_beyond_its_budget_is_refused_before_any_sampling(tmp_path, capsys, monkeypatch, extra):
    """Exit 2, one line naming --mpc-samples and the variable that raises the budget; the open-loop sampling, which
    runs first, never starts."""
    import packetloss_cvx.cli.simulate as command

    monkeypatch.setattr(command, "simulate", lambda *a, **k: (_ for _ in ()).throw(AssertionError("sampled")))
    path = _scalar(tmp_path, u_min=[-1.0], u_max=[1.0])
    assert main(["simulate", str(path), "--quiet", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "error: --mpc-samples:" in err[0]
    assert "PACKETLOSS_CVX_BUDGET_MPC_SOLVES=" in err[0]


def test_solve_refuses_a_constrained_program_beyond_its_budget_naming_the_horizon(tmp_path, capsys, monkeypatch):
    """A horizon of 1e5 with an input box died in a MemoryError of 74.5 GiB after 26 s: refused before any work,
    exit 2, one line naming cost.horizon; --no-qp (no constrained program) still solves."""
    import packetloss_cvx.cli.solve as command

    path = _scalar(tmp_path, horizon=100_000, a=0.9, u_min=[-1.0], u_max=[1.0])
    real = command.closed_form
    monkeypatch.setattr(command, "closed_form", lambda *a, **k: (_ for _ in ()).throw(AssertionError("solved")))
    assert main(["solve", str(path), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "error: cost.horizon: the constrained program of N = 100000" in err[0]
    assert "PACKETLOSS_CVX_BUDGET_SOLVE_WORK=" in err[0]
    monkeypatch.setattr(command, "closed_form", real)
    assert main(["solve", str(path), "--quiet", "--no-qp", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["tcp"]["constrained"]["status"] == "skipped"
