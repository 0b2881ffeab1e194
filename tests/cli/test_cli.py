"""The command line: JSON keys of DESIGN.md §4, exit codes, one-line errors."""

import json
import subprocess
import sys

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from tests.references import readme_system as _readme
from tests.references import unstable_system as _unstable
from tests.references import weighted_two_actuator as _weighted

from ..conftest import EXAMPLES


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_solve_json_two_actuator(capsys):
    code, out, err = run(capsys, "solve", str(EXAMPLES / "two_actuator.toml"), "--json")
    assert code == 0
    assert err == ""
    data = json.loads(out)
    assert set(data) == {"name", "n", "m", "horizon", "mu", "tcp", "udp"}
    assert data["mu"] == [0.9, 0.5]
    for protocol in ("tcp", "udp"):
        entry = data[protocol]
        assert {"cost", "inputs", "gain", "closed_loop_eigenvalues", "qp"} <= set(entry)
        assert len(entry["inputs"]) == 10
        assert len(entry["gain"]) == 2
        assert all(len(pair) == 2 for pair in entry["closed_loop_eigenvalues"])
        qp = entry["qp"]
        assert {"status", "cost", "solve_time", "max_input_diff", "cost_rel_diff"} <= set(qp)
        assert qp["status"] == "optimal"
        assert qp["max_input_diff"] < 1e-6
        assert abs(qp["cost"] - entry["cost"]) <= 1e-7 * entry["cost"]
    assert data["udp"]["cost"] > data["tcp"]["cost"]


def test_solve_overrides_and_text(capsys):
    code, out, _ = run(capsys, "solve", str(EXAMPLES / "two_actuator.toml"), "--protocol", "udp",
                       "--mu", "0.2,0.3", "--x0", "0,1", "--method", "recursion")
    assert code == 0
    assert "UDP-like" in out
    assert "TCP-like" not in out
    assert "(recursion)" in out


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["solve", "absent.toml"], "file: no such file"),
        (["solve", str(EXAMPLES / "two_actuator.toml"), "--mu", "0.5,0.5,0.5"], "--mu: expected shape (2,)"),
        (["solve", str(EXAMPLES / "two_actuator.toml"), "--mu", "0.5,x"], "--mu: expected comma-separated"),
        (["solve", str(EXAMPLES / "two_actuator.toml"), "--mu", "0.5,1.5"], "--mu: expected probabilities"),
        (["solve", str(EXAMPLES / "two_actuator.toml"), "--x0", "1"], "--x0: expected shape"),
        (["solve", str(EXAMPLES / "two_actuator.toml"), "--protocol", "ftp"], "invalid choice"),
        (["frobnicate"], "invalid choice"),
        ([], "required"),
    ],
)
def test_bad_input_exit_2_one_line(capsys, argv, match):
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1
    assert match in err


def test_bad_file_content_exit_2(capsys, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text((EXAMPLES / "two_actuator.toml").read_text().replace("horizon = 10", "horizon = -1"))
    code, _, err = run(capsys, "solve", str(path))
    assert code == 2
    assert "cost.horizon: expected an integer >= 1" in err


def test_unstable_long_dense_exit_1(capsys, tmp_path):
    path = tmp_path / "unstable.toml"
    text = (EXAMPLES / "two_actuator.toml").read_text().replace("horizon = 10", "horizon = 2000")
    text = text.replace("A = [[1.03, 0.005], [0.35, 1.01]]", "A = [[1.2, 0.0], [0.0, 0.5]]")
    path.write_text(text)
    code, _, err = run(capsys, "solve", str(path), "--method", "dense", "--no-qp")
    assert code == 1
    assert "NumericalError" in err
    assert err.count("\n") == 1


def test_module_entry_point_runs():
    proc = subprocess.run([sys.executable, "-m", "packetloss_cvx", "solve", str(EXAMPLES / "two_actuator.toml"),
                           "--json", "--no-qp"], capture_output=True, text=True, check=False)
    assert proc.returncode == 0
    assert json.loads(proc.stdout)["tcp"]["cost"] > 0


def _toml(data):
    """The TOML schema's structure as TOML text (arrays and strings are JSON-compatible)."""
    lines = [f"name = {json.dumps(data['name'])}"] if "name" in data else []
    for section in ("plant", "cost", "channel", "state"):
        lines.append(f"[{section}]")
        lines += [f"{key} = {json.dumps(value)}" for key, value in data[section].items()]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("seed", range(25))
def test_solve_json_on_unseen_systems(seed, tmp_path, capsys):
    """Any valid combination of the schema's keys, written to a file and solved from the CLI."""
    import numpy as np

    from packetloss_cvx.model.random_systems import random_system

    system = random_system(np.random.default_rng(5000 + seed))
    path = tmp_path / "system.toml"
    path.write_text(_toml(system.to_dict()))
    code = main(["solve", str(path), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 0
    assert data["n"] == system.n
    assert data["m"] == system.m
    assert data["horizon"] == system.horizon
    for protocol in ("tcp", "udp"):
        qp = data[protocol]["qp"]
        assert qp["status"] == "optimal"
        assert qp["max_input_diff"] < 1e-6
        assert qp["cost_rel_diff"] < 1e-7


@pytest.mark.parametrize(("argv", "first"), [
    (["simulate", "two_actuator", "--samples", "1e12"], "--samples: invalid int value: '1e12'"),
    (["sweep", "two_actuator", "--protocol", "xx", "--mu-grid", "3"], "--protocol: invalid choice: 'xx'"),
    (["allocate", "two_actuator", "--alpha", "3"], "--protocol: required"),
    (["allocate", "two_actuator", "--target", "stable"], "--beta: required"),
    (["audit", "--only", "theorem-2"], "--only: not an option of this command (see its --help)"),
    (["solve", "two_actuator", "extra"], "extra: unexpected argument"),
])
def test_a_usage_error_is_reported_under_the_option_it_is_about(capsys, argv, first):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"packetloss-cvx: error: {first}")
    assert len(err.strip().splitlines()) == 1


def test_solve_json_names_each_protocol_as_the_readme_says(capsys):
    # README and design.md: "each protocol has `protocol`, `cost`, ..."; solve --json left it out
    assert main(["solve", "two_actuator", "--json", "--no-qp"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["tcp"]["protocol"] == "tcp"
    assert data["udp"]["protocol"] == "udp"
    assert main(["solve", "pendulum_bursty", "--json", "--no-qp", "--protocol", "udp"]) == 0
    assert json.loads(capsys.readouterr().out)["udp"]["protocol"] == "udp"


def test_a_signal_inside_a_library_import_is_the_interrupt_not_a_fault(monkeypatch, capsys):
    """SIGINT landing while an extension module initialises surfaces as ImportError("initialization failed")
    raised while handling our Interrupted: that is exit 130 with the interrupt's line, not "unexpected ImportError"
    and exit 1 (seen once in the reliability test's SIGINT during a sweep's writes)."""
    import signal

    import packetloss_cvx.cli as cli
    import packetloss_cvx.cli.solve as solve

    def interrupted_import(args):
        try:
            raise cli.Interrupted(signal.SIGINT)
        except KeyboardInterrupt:
            raise ImportError("initialization failed")  # noqa: B904 - the context is the point

    monkeypatch.setattr(solve, "run", interrupted_import)
    assert main(["solve", "two_actuator"]) == 130
    err = capsys.readouterr().err
    assert err.strip().splitlines() == ["packetloss-cvx: interrupted by SIGINT"]


def test_the_program_freezes_the_collector_at_its_end_and_an_in_process_call_does_not(capsys):
    """``main()`` without argv ends the program: it freezes what is alive so the shutdown does not collect it again;
    ``main(argv)`` (tests, notebooks) leaves the caller's garbage collector alone."""
    import gc

    before = gc.get_freeze_count()
    assert main(["solve", "no-such-file.toml"]) == 2
    assert gc.get_freeze_count() == before
    probe = ("import gc, sys; from packetloss_cvx.cli import main; sys.argv = ['packetloss-cvx', 'solve', "
             "'no-such-file.toml']; code = main(); print(code, gc.get_freeze_count() > 0)")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert done.stdout.split() == ["2", "True"]
    assert done.stderr.count("\n") == 1            # the one line of bad input, and nothing from the shutdown


def test_a_signal_after_the_programs_end_is_ignored_and_an_in_process_call_restores_the_callers_handlers():
    """Once ``main()`` (the program) returns, its files are complete and its code decided: a SIGINT or SIGTERM
    landing before the process exits is ignored (the interpreter's own handlers would end it by the signal, or
    with a KeyboardInterrupt traceback, after a finished run). ``main(argv)`` puts the caller's handlers back."""
    import signal

    def mine(signum, frame):
        raise AssertionError("not expected")

    previous = {s: signal.signal(s, mine) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        assert main(["solve", "no-such-file.toml"]) == 2
        assert signal.getsignal(signal.SIGINT) is mine
        assert signal.getsignal(signal.SIGTERM) is mine
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    probe = ("import os, signal, sys; from packetloss_cvx.cli import main; sys.argv = ['packetloss-cvx', 'solve', "
             "'no-such-file.toml']; code = main(); os.kill(os.getpid(), signal.SIGINT); "
             "os.kill(os.getpid(), signal.SIGTERM); print(code, 'after both signals')")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert (done.returncode, done.stdout.strip()) == (0, "2 after both signals"), done.stderr
    assert done.stderr.count("\n") == 1            # the one line of bad input, no traceback


def test_the_program_runs_its_command_with_the_imports_frozen_and_the_collector_on(monkeypatch):
    """``main()`` without argv imports the subcommand's module with the collector off, freezes what the imports
    made and turns the collector back on before the command runs; ``main(argv)`` leaves both alone."""
    import gc

    import packetloss_cvx.cli.solve as solve

    seen = []
    run = solve.run
    monkeypatch.setattr(solve, "run", lambda args: (seen.append((gc.isenabled(), gc.get_freeze_count())), run(args))[1])
    before = gc.get_freeze_count()
    assert main(["solve", "two_actuator", "--no-qp"]) == 0
    assert seen == [(True, before)]
    assert gc.isenabled()
    probe = ("import gc, sys; import packetloss_cvx.cli.solve as s; from packetloss_cvx.cli import main; run = s.run; "
             "s.run = lambda args: (print(gc.isenabled(), gc.get_freeze_count() > 0), run(args))[1]; "
             "sys.argv = ['packetloss-cvx', 'solve', 'two_actuator', '--no-qp', '--json']; main()")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert done.stdout.splitlines()[0] == "True True", done.stderr


def test_a_closed_standard_output_is_an_error_not_a_lost_result(monkeypatch, capsys):
    """``solve --json >&-`` (standard output closed) exited 0 with its result lost: Python sets ``sys.stdout`` to None
    and print() then writes nothing. It is refused before the work (exit 2, one line), as a program and in process."""
    import os
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(root)}
    done = subprocess.run(["sh", "-c", f'"{sys.executable}" -m packetloss_cvx solve two_actuator --json --no-qp >&-'],
                          capture_output=True, text=True, timeout=60, env=env)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [
        "packetloss-cvx: error: stdout: standard output is closed, so the result would be lost; send it to a file "
        "or to /dev/null (> out.txt)"]
    monkeypatch.setattr(sys, "stdout", None)
    assert main(["solve", "two_actuator", "--no-qp"]) == 2
    assert capsys.readouterr().err.startswith("packetloss-cvx: error: stdout: standard output is closed")


def _run(capsys, *argv):
    from packetloss_cvx.cli import main

    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_cross_check_compares_the_printed_number_and_binds(capsys, monkeypatch):
    """solve --method dense compared the QP with the auto answer; now with the printed one, and a
    disagreement is exit 1 with one line naming both numbers."""
    import packetloss_cvx.cli.solve as cli

    real = cli.closed_form

    def off_by_1e3(system, protocol, method="auto"):
        sol = real(system, protocol, method)
        if method == "dense":
            import dataclasses

            return dataclasses.replace(sol, cost=sol.cost * (1 + 1e-3))
        return sol

    monkeypatch.setattr(cli, "closed_form", off_by_1e3)
    code, out, err = _run(capsys, "solve", "two_actuator", "--method", "dense", "--protocol", "tcp")
    assert code == 1
    assert "J_qp = 2.79847" in err
    assert "J* = 2.80126" in err
    assert "(dense)" in err
    assert err.count("\n") == 1
    assert not out
    code, out, _ = _run(capsys, "solve", "two_actuator", "--method", "recursion", "--protocol", "tcp")
    assert code == 0
    assert "(recursion)" in out


def test_cli_refuses_a_solve_whose_qp_cannot_fit_and_names_no_qp(capsys, tmp_path, monkeypatch):
    """N = 50000 with n = 2, m = 1: solve with the QP cross-check needs about 0.27 GiB (solve_bytes, by hand
    50000 x (260 + 60 + 40 + 3000 + 1400 + 1000) = 2.88e8 bytes), refused upfront against a 1e8-byte budget (exit 2,
    one line naming --no-qp); the closed form alone needs 1.8e7 and is answered."""
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "1e8")
    path = tmp_path / "long.toml"
    pl.save_system(_readme(1), path)
    path.write_text(path.read_text().replace("horizon = 1", "horizon = 50000"))
    code, out, err = _run(capsys, "solve", str(path), "--protocol", "tcp", "--json")
    assert (code, out) == (2, "")
    assert err.count("\n") == 1
    assert err.startswith("packetloss-cvx: error: cost.horizon: N = 50000 (n = 2, m = 1) with the QP cross-check")
    assert "--no-qp skips the cross-check" in err
    assert err.rstrip().endswith("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES=2.88e+08")
    code, out, err = _run(capsys, "solve", str(path), "--protocol", "tcp", "--json", "--no-qp")
    assert code == 0, err
    import json

    assert json.loads(out)["tcp"]["cost"] == pytest.approx(1.3044129215697624, rel=1e-9)   # the N = 200 value


def test_cli_refuses_a_solve_whose_qp_alone_cannot_fit(capsys, tmp_path, monkeypatch):
    """Twenty channels on a scalar plant over 5000 steps: solve's fitted peak with the cross-check fits a 1e8-byte
    budget (by hand 5000 x (260 + 15 + 800 + 3000 + 350 + 10000) = 7.2e7 bytes), the sparse QP's own estimate does
    not (by hand 5000 x (260 + 8000 + 13000) + 1e7 = 1.163e8, plus the closed forms' 5000 x 1075): refused upfront,
    exit 2 and one line naming --no-qp, where the QP was skipped after the closed forms (or, with ExpectedCostQP's
    own check, exit 1 in an audit)."""
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "1e8")
    s = pl.System(A=[[0.9]], B=np.ones((1, 20)), horizon=5000, state_weight=[1.0], input_weight=np.ones(20),
                  mu=np.full(20, 0.5), x0=[1.0])
    path = pl.save_system(s, tmp_path / "wide.toml")
    code, out, err = _run(capsys, "solve", str(path), "--protocol", "tcp", "--json")
    assert (code, out) == (2, "")
    assert err.count("\n") == 1
    assert err.startswith("packetloss-cvx: error: cost.horizon: N = 5000 (n = 1, m = 20) with the QP cross-check "
                          "(about 0.113 GiB)")
    assert "; --no-qp skips the cross-check, or to run it on purpose set " in err
    assert err.rstrip().endswith("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES=1.22e+08")


def test_cli_unstable_udp_reports_the_skipped_cross_check(capsys, tmp_path):
    path = pl.save_system(_unstable(1.5, 60), tmp_path / "unstable.toml")
    code, out, err = _run(capsys, "solve", str(path))
    assert code == 0, err
    assert "UDP-like" in out
    assert "QP cross-check skipped" in out
    assert "unconstrained" in out
    assert "TCP-like" in out
    assert "QP optimal" in out


def test_cli_badly_scaled_weights_exit_1_naming_the_weights(capsys, tmp_path):
    path = pl.save_system(_weighted(1e12), tmp_path / "w.toml")
    code, out, err = _run(capsys, "solve", str(path))
    assert code == 1
    assert not out
    assert "weights span 1.0e+12" in err
    assert err.count("\n") == 1
    path = pl.save_system(_weighted(1e100), tmp_path / "w100.toml")
    code, out, err = _run(capsys, "solve", str(path), "--no-qp")
    assert code == 1
    assert not out
    assert err.count("\n") == 1


def test_cli_huge_x0_prints_one_line(capsys):
    code, out, err = _run(capsys, "solve", "two_actuator", "--x0=1e200,1")
    assert code == 1
    assert not out
    assert err.count("\n") == 1
    assert "double-precision range" in err


def test_solve_skips_the_stability_verdict_above_its_size_unless_asked(tmp_path):
    from packetloss_cvx.cli import main
    from packetloss_cvx.cli.solve import STABILITY_MAX_N
    n = STABILITY_MAX_N + 1
    A = 0.5 * np.eye(n)
    A[0, 0] = 2.0                      # one unstable mode, driven by the one actuator; the rest decoupled
    B = np.zeros((n, 1))
    B[0, 0] = 1.0
    s = pl.System(A=A, B=B, horizon=2, state_weight=np.ones(n), input_weight=[1.0], mu=[0.5], x0=np.ones(n))
    path = str(pl.save_system(s, tmp_path / "big.toml"))
    out = tmp_path / "out.json"
    assert main(["solve", path, "--no-qp", "--protocol", "tcp", "-q", "--out", str(out)]) == 0
    entry = json.loads(out.read_text())["tcp"]
    assert entry["mean_square_spectral_radius"] is None
    assert entry["stable"] is False
    assert "--stability" in entry["stability_note"]
    out = tmp_path / "asked.json"          # a new file: an existing one is refused without --force
    assert main(["solve", path, "--no-qp", "--protocol", "tcp", "-q", "--stability", "--out", str(out)]) == 0
    entry = json.loads(out.read_text())["tcp"]
    k = entry["gain"][0][0]
    assert np.allclose(entry["gain"][0][1:], 0.0, atol=1e-12)
    # by hand: the decoupled modes give 0.5^2; the driven one E[x+^2] = ((2 - mu k)^2 + mu (1 - mu) k^2) x^2, and
    # the cross moments E[x_1 x_j] grow by the geometric mean of the two
    expected = max(0.25, (2 - 0.5 * k) ** 2 + 0.25 * k ** 2)
    assert entry["mean_square_spectral_radius"] == pytest.approx(expected, rel=1e-9)
    out = tmp_path / "skipped.json"
    assert main(["solve", "two_actuator", "--no-qp", "--no-stability", "-q", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["udp"]["stability_note"].startswith("not computed: skipped (--no-stability)")
