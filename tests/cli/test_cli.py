"""The command line: JSON keys of DESIGN.md §4, exit codes, one-line errors."""

import json
import subprocess
import sys

import pytest

from packetloss_cvx.cli import main

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
