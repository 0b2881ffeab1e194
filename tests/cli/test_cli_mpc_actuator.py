"""``simulate FILE --actuator ...`` with a ``[constraints]`` table: the constrained loop under each strategy on the
same paths, named per strategy in JSON and text; bad input exit 2 with one line.

References: the scalar path walked by hand of test_cli_constrained_loop (every packet arrives: every strategy is
that loop), a fixed loss path under hold walked by hand, and `simulate_mpc` called directly on the same seed.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.files import save_system
from packetloss_cvx.montecarlo import mpc
from packetloss_cvx.montecarlo.mpc import simulate_mpc


def _scalar(tmp_path, mu=1.0, name="scalar.toml", **table):
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])
    return save_system(s, tmp_path / name, constraints=Constraints(**table) if table else None)


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_every_strategy_is_the_hand_walk_when_every_packet_arrives(tmp_path, capsys):
    # mu = 1: nothing is lost, so zero, hold and the buffer apply the same inputs: clip(-(3/5) x) to |u| <= 0.3,
    # x = 1, 0.7, 0.4, 0.16 (test_cli_constrained_loop's hand walk)
    path = _scalar(tmp_path, u_min=[-0.3], u_max=[0.3])
    code, out, _ = _run(capsys, "simulate", str(path), "--json", "--samples", "2", "--mpc-samples", "2", "--steps",
                        "4", "--actuator", "zero,hold,buffer:2:hold")
    assert code == 0
    loop = json.loads(out)["constrained_loop"]
    assert loop["constraints"] == {"u_min": [-0.3], "u_max": [0.3]}
    assert list(loop["strategies"]) == ["zero", "hold", "buffer:2:hold"]
    hand = [1.09, 0.58, 0.2176, 0.034816]
    for name, entry in loop["strategies"].items():
        assert entry["actuator"] == name
        for protocol in ("tcp", "udp"):
            assert set(entry[protocol]) == {"clipped", "certainty-equivalent", "expected-cost"}
            for run in entry[protocol].values():
                assert np.allclose(run["stage_cost_mean"], hand, rtol=1e-9)
                assert run["violations"]["u_min[0]"]["count"] == 0


def test_hold_on_a_fixed_loss_path_walked_by_hand(tmp_path, capsys, monkeypatch):
    # x' = x + v u, N = 2, the programs plan with mu = 1 (the file's), deliveries forced to 1, 0, 0, 1: the plan from
    # x is (-0.6 x, -0.2 x); hold applies -0.6 three times: x = 1, 0.4, -0.2, -0.8, then -0.6 * -0.8 = 0.48
    V = np.repeat(np.array([1, 0, 0, 1], dtype=bool)[:, None, None], 2, axis=1)
    monkeypatch.setattr(mpc, "loop_paths", lambda system, samples, steps, seed: (V[:steps], None))
    path = _scalar(tmp_path, u_max=[5.0])
    code, out, _ = _run(capsys, "simulate", str(path), "--json", "--samples", "2", "--mpc-samples", "2", "--steps",
                        "4", "--law", "tcp", "--actuator", "hold")
    assert code == 0
    run = json.loads(out)["constrained_loop"]["strategies"]["hold"]["tcp"]["expected-cost"]
    assert np.allclose(run["stage_cost_mean"], [1.36, 0.16 + 0.36, 0.04 + 0.36, 0.64 + 0.48 ** 2], rtol=1e-9)


def test_each_strategy_is_simulate_mpc_on_the_same_seed(tmp_path, capsys):
    path = _scalar(tmp_path, mu=0.6, u_min=[-0.4], u_max=[0.4], du_max=[0.25])
    code, out, _ = _run(capsys, "simulate", str(path), "--json", "--samples", "2", "--mpc-samples", "3", "--steps",
                        "5", "--seed", "4", "--law", "udp", "--actuator", "all")
    assert code == 0
    loop = json.loads(out)["constrained_loop"]
    assert list(loop["strategies"]) == ["zero", "hold", "buffer:2"]
    system = pl.load_system(path)
    for name, entry in loop["strategies"].items():
        direct = simulate_mpc(system, Constraints(u_min=[-0.4], u_max=[0.4], du_max=[0.25]), 3, 5, seed=4,
                              protocols=["udp"], actuator=name, progress=False)
        assert json.loads(json.dumps(direct.to_dict())) == entry


def test_the_text_names_each_strategys_rows(tmp_path, capsys):
    path = _scalar(tmp_path, mu=0.6, u_min=[-0.4], u_max=[0.4], du_max=[0.25])
    code, out, _ = _run(capsys, "simulate", str(path), "--samples", "2", "--mpc-samples", "2", "--steps", "3",
                        "--law", "tcp", "--actuator", "zero,buffer:2")
    assert code == 0
    for label in ("same paths for every controller and actuator strategy", "actuator zero, TCP-like information",
                  "actuator buffer:2, TCP-like information", "plays the next entry of the last plan received",
                  "the input applied last"):
        assert label in out
    assert "actuator on a loss: each law's loop" not in out              # no --closed-loop: no unconstrained part


def test_a_chain_runs_the_strategies_in_the_constrained_loop(tmp_path, capsys):
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                  channel=GilbertElliott(p=[0.3], r=[0.6]))
    path = save_system(s, tmp_path / "chain.toml", constraints=Constraints(u_min=[-0.4], u_max=[0.4]))
    code, out, _ = _run(capsys, "simulate", str(path), "--json", "--samples", "2", "--mpc-samples", "2", "--steps",
                        "3", "--actuator", "hold")
    assert code == 0
    loop = json.loads(out)["constrained_loop"]
    assert loop["channel"] == "gilbert-elliott"
    assert loop["strategies"]["hold"]["actuator"] == "hold"


@pytest.mark.parametrize(("extra", "message"), [
    (["--actuator", "buffer:0"], "--actuator: expected zero, hold or buffer:L with an integer 1 <= L <= 2"),
    (["--actuator", "buffer:3"], "<= 2 (the horizon)"),
    (["--actuator", "hold,drop"], "--actuator: expected zero, hold or buffer:L"),
    (["--actuator", "hold", "--mpc-samples", "0"], "--actuator: the actuator's strategy acts in the closed loop"),
])
def test_bad_actuator_input_is_exit_2_and_one_line(tmp_path, capsys, extra, message):
    path = _scalar(tmp_path, mu=0.6, u_max=[0.4])
    code, out, err = _run(capsys, "simulate", str(path), "--samples", "2", "--mpc-samples", "2", "--steps", "3", *extra)
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1
    assert message in err


def test_the_strategies_budget_is_summed_before_any_sampling(tmp_path, capsys, monkeypatch):
    # one solve of the scalar program (N = 2, n = m = 1, 2 rows) weighs (1600 + 0.75 * 2 * 4 + 0.055 * 4 + 3.5 * 2)
    # / 5000 = 0.322644 of a 5 ms solve (budgets.mpc_solve_size). 100 runs of 5 steps: zero alone is 3 programs and
    # 2 clipped laws, 500 (3 * 0.322644 + 2 * 2e-3) = 485.97 solves; the three strategies 3 + 4 + 4 programs
    # (certainty-equivalent per protocol under hold and buffer) and 6 clipped laws, 1780.54: over a budget of 1000
    path = _scalar(tmp_path, mu=0.6, u_max=[0.4])
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MPC_SOLVES", "1000")
    monkeypatch.setattr(mpc, "loop_paths", lambda *args: pytest.fail("sampled before the budget was checked"))
    code, out, err = _run(capsys, "simulate", str(path), "--samples", "2", "--mpc-samples", "100", "--steps", "5",
                          "--actuator", "all", "-q")
    assert code == 2
    assert out == ""
    assert err.startswith("packetloss-cvx: error: --mpc-samples: 100 runs of 5 steps x 11 programs")


def test_zero_alone_fits_the_budget_the_three_strategies_exceed(tmp_path, capsys, monkeypatch):
    """The other side of the summed budget above: zero alone, 485.97 solves, runs under the same budget."""
    path = _scalar(tmp_path, mu=0.6, u_max=[0.4])
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MPC_SOLVES", "1000")
    code, _, err = _run(capsys, "simulate", str(path), "--samples", "2", "--mpc-samples", "100", "--steps", "5",
                        "--actuator", "zero", "-q")
    assert code == 0, err
