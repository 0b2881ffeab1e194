"""The command line's overrides of the ``[constraints]`` table (``--u-min``, ``--u-max``, ``--du-max``, ``--x-min``,
``--x-max``, ``--terminal-min``, ``--terminal-max``, ``--soft``/``--no-soft``, ``--soft-weight``) on ``solve`` and
``simulate``.

References, none taken from the code under test: the scalar x' = x + v u from 1, N = 1, Q = R = 1 solved by hand
(TCP-like u = -2/3, UDP-like u = -1/2, each clipped to the bounds; E[x_1] = 1 + mu u), and the same table written
in the file (the flags must give what the file gives)."""

from __future__ import annotations

import json

import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.files import save_system

FREE = {"tcp": -2 / 3, "udp": -0.5}           # Theorem 1 at x0 = 1, mu = 1/2


def _scalar(tmp_path, name="scalar.toml", n=1, **table):
    if n == 1:
        s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    else:
        s = pl.System(A=[[1.0, 0.0], [0.0, 1.0]], B=[[1.0], [0.0]], horizon=1, state_weight=[1.0, 1.0],
                      input_weight=[1.0], mu=[0.5], x0=[1.0, 3.0])
    return save_system(s, tmp_path / name, constraints=Constraints(**table) if table else None)


def _constrained(capsys, argv):
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    return {p: out[p]["constrained"] for p in ("tcp", "udp")}


def test_flags_make_a_table_where_the_file_has_none(tmp_path, capsys):
    path = _scalar(tmp_path)
    entries = _constrained(capsys, ["solve", str(path), "--json", "--no-stability", "--u-min", "-0.55",
                                    "--u-max", "1"])
    for protocol, entry in entries.items():
        assert entry["inputs"][0][0] == pytest.approx(max(FREE[protocol], -0.55), abs=1e-9)
        assert entry["binding"] == (["u_min[0] at t=0"] if protocol == "tcp" else [])
    # the same bounds written in the file give the same answer
    again = _constrained(capsys, ["solve", str(_scalar(tmp_path, "b.toml", u_min=[-0.55], u_max=[1.0])), "--json",
                                  "--no-stability"])
    assert again == entries


def test_a_flag_replaces_its_key_and_keeps_the_others(tmp_path, capsys):
    # the file: |u| <= 0.1 and E[x_1] <= 0.9 (hard: then infeasible, E[x_1] >= 1 - 0.05); --u-min -0.4 frees the
    # input downwards: E[x_1] = 1 + u/2 <= 0.9 needs u <= -0.2, which both protocols' optimum -2/3, -1/2 clipped to
    # -0.4 meets
    path = _scalar(tmp_path, u_min=[-0.1], u_max=[0.1], x_max=[0.9])
    entries = _constrained(capsys, ["solve", str(path), "--json", "--no-stability"])
    assert all(entry["status"] == "infeasible" for entry in entries.values())
    entries = _constrained(capsys, ["solve", str(path), "--json", "--no-stability", "--u-min", "-0.4"])
    for entry in entries.values():
        assert entry["inputs"][0][0] == pytest.approx(-0.4, abs=1e-9)
        assert entry["binding"] == ["u_min[0] at t=0"]                  # u_max 0.1 and x_max kept, not binding


def test_soft_and_its_weight_from_the_command_line(tmp_path, capsys):
    # E[x_1] <= 0.5 with |u| <= 0.1: hard infeasible; soft with weight rho the TCP-like cost (1 + u/2)^2 + u^2/2 +
    # rho (1 + u/2 - 0.5) falls on [-0.1, 0.1] (slope at -0.1: 0.95 - 0.1 + rho/2 > 0), so u = -0.1, E[x_1] = 0.95,
    # violated by 0.45, by hand
    path = _scalar(tmp_path, u_min=[-0.1], u_max=[0.1], x_max=[0.5])
    entries = _constrained(capsys, ["solve", str(path), "--json", "--no-stability", "--soft", "--soft-weight", "3"])
    for entry in entries.values():
        assert entry["status"] == "optimal"
        assert entry["inputs"][0][0] == pytest.approx(-0.1, abs=1e-9)
        assert entry["violations"] == [{"constraint": "x_max[0] at k=1", "by": pytest.approx(0.45, abs=1e-9)}]
    soft_file = _scalar(tmp_path, "soft.toml", u_min=[-0.1], u_max=[0.1], x_max=[0.5], soft=True)
    entries = _constrained(capsys, ["solve", str(soft_file), "--json", "--no-stability", "--no-soft"])
    assert all(entry["status"] == "infeasible" for entry in entries.values())


def test_one_number_stands_for_every_state_and_the_terminal_box(tmp_path, capsys):
    # x = (x1, x2) from (1, 3), only x1 actuated: --x-max 2 holds on both entries, and E[x2] = 3 > 2 whatever u
    path = _scalar(tmp_path, n=2)
    entries = _constrained(capsys, ["solve", str(path), "--json", "--no-stability", "--x-max", "2"])
    # the solver says infeasible; with the inputs unbounded its certificate cannot be checked: undecided, not a proof
    for entry in entries.values():
        assert (entry["status"], entry["solver_status"], entry["certificate"]["verdict"]) == (
            "undecided", "infeasible", "undecided")
        assert "not bounded" in entry["certificate"]["reason"]
    entries = _constrained(capsys, ["solve", str(path), "--json", "--no-stability", "--x-max", "2,inf",
                                    "--terminal-max", "0.8,inf"])
    for protocol, entry in entries.items():
        # E[x1_1] = 1 + u/2 <= 0.8 needs u <= -0.4: TCP-like's -2/3 meets it, UDP-like's -1/2 does too
        assert entry["inputs"][0][0] == pytest.approx(FREE[protocol], abs=1e-9)
    entries = _constrained(capsys, ["solve", str(path), "--json", "--no-stability", "--terminal-max", "0.7,inf"])
    # E[x1_1] <= 0.7 needs u <= -0.6: TCP-like's -2/3 meets it, UDP-like's -1/2 is cut to -0.6
    tcp, udp = entries["tcp"], entries["udp"]
    assert tcp["inputs"][0][0] == pytest.approx(-2 / 3, abs=1e-9)
    assert tcp["binding"] == []
    assert udp["inputs"][0][0] == pytest.approx(-0.6, abs=1e-9)
    assert udp["binding"] == ["terminal_max[0] at k=1"]
    assert udp["terminal_state"] == pytest.approx([0.7, 3.0], abs=1e-9)


def test_simulate_runs_the_constrained_loop_with_the_flags_table(tmp_path, capsys):
    path = _scalar(tmp_path)
    argv = ["simulate", str(path), "--json", "--samples", "2", "--mpc-samples", "2", "--steps", "2"]
    assert main([*argv, "--u-min", "-0.3", "--u-max", "0.3", "--du-max", "0.2"]) == 0
    loop = json.loads(capsys.readouterr().out)["constrained_loop"]
    assert loop["constraints"] == {"u_min": [-0.3], "u_max": [0.3], "du_max": [0.2]}
    assert main([*argv[:-4], "--steps", "2"]) == 0                     # no table, no flag: no constrained loop
    assert "constrained_loop" not in json.loads(capsys.readouterr().out)
    assert main([*argv]) == 2            # --mpc-samples without a table or a flag would change nothing: refused
    assert "--mpc-samples: needs a [constraints] table" in capsys.readouterr().err


@pytest.mark.parametrize(("command", "table", "args", "field"), [
    ("solve", None, ["--u-min", "0.5"], "--u-min"),                       # zero input outside the bounds
    ("solve", None, ["--u-max", "1,2"], "--u-max"),                       # m = 1
    ("solve", None, ["--du-max", "-1"], "--du-max"),
    ("solve", None, ["--x-min", "abc"], "--x-min"),
    ("solve", None, ["--soft-weight", "0"], "--soft-weight"),
    ("solve", None, ["--terminal-min", "1", "--terminal-max", "0"], "--terminal-min"),
    ("solve", {"x_max": [0.0]}, ["--x-min", "1"], "--x-min"),            # against the file's key: the flag named
    ("solve", {"x_min": [1.0]}, ["--x-max", "0"], "constraints.x_min"),  # the file's key named
    ("simulate", None, ["--u-max", "-0.5"], "--u-max"),
])
def test_bad_flags_exit_2_with_one_line_naming_the_flag(tmp_path, capsys, command, table, args, field):
    path = _scalar(tmp_path, **(table or {}))
    assert main([command, str(path), "--json", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert f"error: {field}" in err[0]


# ------------------------------------------------------------------------------ simulate: the loop's runs spread

def test_simulate_threads_give_the_serial_json(tmp_path, capsys):
    path = _scalar(tmp_path, u_min=[-0.3], u_max=[0.3], x_max=[0.95])
    argv = ["simulate", str(path), "--json", "--samples", "2", "--mpc-samples", "11", "--steps", "3"]
    assert main(argv) == 0
    serial = json.loads(capsys.readouterr().out)["constrained_loop"]
    assert main([*argv, "--threads", "2"]) == 0
    assert json.loads(capsys.readouterr().out)["constrained_loop"] == serial


@pytest.mark.parametrize(("args", "field"), [
    (["--mpc-samples", "100000000"], "--mpc-samples"),              # 1e8 x 3 steps x 3 programs: over mpc_solves
    (["--threads", "0"], "--threads"),
    (["--workers", "2"], "--workers"),                             # without --dask local
])
def test_simulate_spreading_refusals_exit_2_with_one_line(tmp_path, capsys, args, field):
    path = _scalar(tmp_path, u_max=[0.3])
    assert main(["simulate", str(path), "--json", "--samples", "2", "--steps", "3", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert f"error: {field}" in err[0]


def test_simulate_threads_without_a_constrained_loop_is_refused(tmp_path, capsys):
    assert main(["simulate", str(_scalar(tmp_path)), "--json", "--samples", "2", "--threads", "2"]) == 2
    assert "error: --threads" in capsys.readouterr().err


def test_a_chance_row_the_solver_calls_infeasible_is_undecided_not_infeasible(tmp_path, capsys):
    # x' = 1.1 x + v u from 1, mu = 1/2, P(x_k <= -1) >= 0.9: a lost packet leaves x_1 = 1.1 > -1 with probability
    # 1/2 > 0.1, so no plan meets it; but the certificate of a chance row is not checkable (cvxpy does not return its
    # cone multipliers whole): the status says undecided with that reason, never "infeasible"
    s = pl.System(A=[[1.1]], B=[[1.0]], horizon=5, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    path = save_system(s, tmp_path / "chance.toml", constraints=Constraints(chance=[([1.0], -1.0, 0.1)]))
    entries = _constrained(capsys, ["solve", str(path), "--json", "--no-stability"])
    for entry in entries.values():
        assert (entry["status"], entry["solver_status"], entry["certificate"]["verdict"]) == (
            "undecided", "infeasible", "undecided")
        assert "chance rows" in entry["certificate"]["reason"]
        assert entry["cost"] is None
    assert main(["solve", str(path), "--no-stability"]) == 0
    text = capsys.readouterr().out
    assert "constrained     undecided: " in text
    assert "infeasible:" not in text
