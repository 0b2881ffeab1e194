"""``simulate FILE`` with a ``[constraints]`` table: the constrained loop's JSON keys, a path walked by hand, bad
input refused with exit 2 and one line."""

from __future__ import annotations

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.files import save_system

CONTROLLER_KEYS = {"controller", "protocol", "mean_stage_cost", "stderr", "stage_cost_mean", "violations",
                   "infeasible", "fallback_steps", "failed_steps", "slack_steps", "action"}


def _scalar(tmp_path, mu=1.0, name="scalar.toml", **table):
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])
    return save_system(s, tmp_path / name, constraints=Constraints(**table) if table else None)


def test_simulate_json_adds_the_constrained_loop_walked_by_hand(tmp_path, capsys):
    # every packet arrives (mu = 1): each program is the two-step LQ problem of x' = x + u with |u| <= 0.3;
    # unconstrained u = -(3/5) x (the two-step Riccati gain), and saturating now only makes the program want more
    # (checked on the reduced cost's slope), so u = clip(-(3/5) x): x = 1, 0.7, 0.4, 0.16 with u = -0.3, -0.3,
    # -0.24, -0.096; stage costs x^2 + u^2 by hand
    path = _scalar(tmp_path, u_min=[-0.3], u_max=[0.3])
    assert main(["simulate", str(path), "--json", "--samples", "2", "--mpc-samples", "2", "--steps", "4"]) == 0
    loop = json.loads(capsys.readouterr().out)["constrained_loop"]
    assert {"samples", "steps", "seed", "channel", "constraints", "tcp", "udp"} <= set(loop)
    assert loop["constraints"] == {"u_min": [-0.3], "u_max": [0.3]}
    hand = [1.09, 0.58, 0.2176, 0.034816]
    for protocol in ("tcp", "udp"):
        assert set(loop[protocol]) == {"clipped", "certainty-equivalent", "expected-cost"}
        for name, entry in loop[protocol].items():
            assert CONTROLLER_KEYS <= set(entry)
            assert set(entry["violations"]) == {"u_min[0]", "u_max[0]"}
            assert entry["violations"]["u_min[0]"]["count"] == 0
            assert (entry["infeasible"] is None) == (name == "clipped")
            assert np.allclose(entry["stage_cost_mean"], hand, rtol=1e-9)


def test_without_a_table_or_with_mpc_samples_0_there_is_no_constrained_loop(tmp_path, capsys):
    for path, extra in ((_scalar(tmp_path), []), (_scalar(tmp_path, name="b.toml", u_max=[0.3]),
                                                            ["--mpc-samples", "0"])):
        assert main(["simulate", str(path), "--json", "--samples", "2", *extra]) == 0
        assert "constrained_loop" not in json.loads(capsys.readouterr().out)


def test_the_text_names_the_controllers_and_the_fallback(tmp_path, capsys):
    path = _scalar(tmp_path, mu=0.6, u_min=[-0.3], u_max=[0.3], x_max=[1.05])
    assert main(["simulate", str(path), "--samples", "2", "--mpc-samples", "3", "--steps", "3", "--law", "tcp"]) == 0
    out = capsys.readouterr().out
    for label in ("unconstrained law clipped to the bounds", "certainty-equivalent MPC", "expected-cost MPC",
                  "soft program", "Wilson 95%"):
        assert label in out


@pytest.mark.parametrize(("table", "args", "field"), [
    ("u_min = [0.5]", [], "constraints.u_min"),
    ("u_max = [0.5]", ["--mpc-samples", "1"], "--mpc-samples"),
    ("u_max = [0.5]", ["--law", "dp", "--closed-loop"], "--law"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, table, args, field):
    path = _scalar(tmp_path, mu=0.5)
    path.write_text(path.read_text() + f"\n[constraints]\n{table}\n")
    assert main(["simulate", str(path), "--json", "--samples", "2", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert f"error: {field}" in err[0]
