"""Interrupts that always interrupt: a SIGINT or SIGTERM at any moment of a run ends it with 130 / 143 and one
stderr line, no traceback, its files complete or absent; never a finished run that ignored the signal.

The in-process tests place a signal exactly where a run once lost it (a library that swallows the interrupt, the
restore of the handlers); the subprocess test sends signals at seeded delays over a whole run, start-up and imports
included, from the moment the package's first handler is installed (the interpreter's own start-up is Python's).
"""

import json
import os
import random
import signal
import subprocess
import sys
import threading
import time
import tomllib
from pathlib import Path

import packetloss_cvx.cli as cli
import packetloss_cvx.cli.solve as solve
from packetloss_cvx.cli import main
from packetloss_cvx.cli.common import CommandResult

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
EXIT = {signal.SIGINT: 130, signal.SIGTERM: 143}


def test_an_interrupt_a_library_swallows_still_ends_the_run(monkeypatch, capsys, tmp_path):
    """A bare ``except:`` around a library's import swallows the interrupt after the handler has set SIGINT and
    SIGTERM to "ignore": the run must still end before it writes or prints (130, one line), not finish and exit 0
    deaf to a second Ctrl-C; and a second signal still interrupts."""
    steps = []

    def swallowing_command(args):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.01)                    # the handler runs here
        except BaseException:                   # noqa: BLE001 - what the library does
            steps.append("swallowed")
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.01)
            steps.append("deaf to the second signal")
        except KeyboardInterrupt:
            steps.append("second signal interrupted")
        return CommandResult({"status": "done"}, "done")

    monkeypatch.setattr(solve, "run", swallowing_command)
    out = tmp_path / "x.json"
    assert main(["solve", "two_actuator", "--out", str(out)]) == 130
    assert steps == ["swallowed", "second signal interrupted"]
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.splitlines() == ["packetloss-cvx: interrupted by SIGINT"]
    assert not out.exists()


def test_a_signal_while_main_restores_the_handlers_is_the_runs_exit_code(monkeypatch, capsys):
    """A SIGTERM landing while ``main`` put the previous handlers back met the first restored handler's neighbour
    still set to raise: a KeyboardInterrupt out of ``main``'s ``finally`` (exit 1 and a traceback as a program).
    Now it is recorded and the run ends 143 with its one line."""
    def mine(signum, frame):      # the caller's handlers: harmless if a signal meets them
        pass

    caller = {s: signal.signal(s, mine) for s in EXIT}
    real = signal.signal
    sent = []

    def restoring(signum, handler):
        if handler is mine and not sent:         # main's first restore: a SIGTERM arrives now
            sent.append(signum)
            os.kill(os.getpid(), signal.SIGTERM)
        return real(signum, handler)

    try:
        monkeypatch.setattr(cli.signal, "signal", restoring)
        try:
            code = main(["solve", "no-such-file.toml"])
        except KeyboardInterrupt as err:         # out of main: the program's traceback and exit 1
            code = f"raised {type(err).__name__}"
        monkeypatch.undo()
        assert sent, "the restore was not reached"
        assert code == 143
        assert capsys.readouterr().err.splitlines()[-1] == "packetloss-cvx: interrupted by SIGTERM"
    finally:
        for s, handler in caller.items():
            real(s, handler)


def test_an_interrupt_that_surfaces_as_another_error_is_the_interrupt(monkeypatch, capsys):
    """NumPy's import, interrupted, raises ImportError("... the numpy C-extensions failed ...") without the
    interrupt in its chain: the run was reported as a broken install (exit 1). The signal was received, so the
    error is the interrupt."""
    def broken_import(args):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.01)
        except KeyboardInterrupt:               # the extension's C code clears it and fails the import
            pass
        raise ImportError("Importing the numpy C-extensions failed.")

    monkeypatch.setattr(solve, "run", broken_import)
    assert main(["solve", "two_actuator"]) == 130
    assert capsys.readouterr().err.splitlines() == ["packetloss-cvx: interrupted by SIGINT"]


def test_the_console_script_enters_where_the_first_handler_is_installed():
    """The console script imports ``packetloss_cvx.__main__`` (its first lines install the early handler), not
    ``packetloss_cvx.cli``, whose imports (the grammar, tens of milliseconds) then ran under Python's handler: a
    SIGINT there printed a KeyboardInterrupt traceback."""
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts == {"packetloss-cvx": "packetloss_cvx.__main__:main"}


def _handles_sigterm(pid):
    """Whether the process catches SIGTERM (/proc's SigCgt): the package's first handler is installed."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return True
    caught = next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:"))
    return bool(int(caught, 16) >> (signal.SIGTERM - 1) & 1)


#: the console script's body (pip writes it so): import the entry point, call it
CONSOLE_SCRIPT = "import sys; from packetloss_cvx.__main__ import main; sys.exit(main())"


def test_signals_at_any_moment_of_a_run_end_it_with_one_line(tmp_path):
    """``solve two_actuator --out x.json`` (QP cross-check on: about 0.7 s, most of it imports) as ``python -m`` and
    as the console script, SIGINT or SIGTERM at seeded delays after the package's first handler is installed:
    exit 130 / 143 and exactly one stderr line, x.json absent or complete; exit 0 only for a run that had ended
    before the signal (its stderr empty, its file complete)."""
    rng = random.Random(33)
    delays = [0.0, 0.005, 0.02, 0.05, 0.1, 0.2, 0.35, 0.5]
    cases = [(k, launcher, rng.choice(list(EXIT)), delay + rng.uniform(0.0, 0.02))
             for k, (launcher, delay) in enumerate((lc, d) for d in delays for lc in ("module", "script"))]
    results = {}

    def one(k, launcher, signum, delay):
        folder = tmp_path / str(k)
        folder.mkdir()
        head = ["-m", "packetloss_cvx"] if launcher == "module" else ["-c", CONSOLE_SCRIPT]
        proc = subprocess.Popen([sys.executable, *head, "solve", "two_actuator", "--out", "x.json", "-q"],
                                cwd=folder, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        end = time.monotonic() + 30
        while proc.poll() is None and not _handles_sigterm(proc.pid) and time.monotonic() < end:
            time.sleep(0.001)
        time.sleep(delay)
        alive = proc.poll() is None
        if alive:
            proc.send_signal(signum)
        out, err = proc.communicate(timeout=60)
        results[k] = (alive, proc.returncode, out, err, folder / "x.json")

    for start in range(0, len(cases), 4):        # four at a time: two cores, shared
        threads = [threading.Thread(target=one, args=case) for case in cases[start:start + 4]]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    interrupted = 0
    for k, launcher, signum, delay in cases:
        alive, code, out, err, path = results[k]
        where = (launcher, signal.Signals(signum).name, round(delay, 3), code, err[-600:])
        if path.exists():
            assert json.loads(path.read_text())["tcp"]["protocol"] == "tcp", where
        if code == 0:        # finished before the signal was sent, or after main had returned (then ignored)
            assert err == "", where
            assert path.exists(), where
            continue
        assert alive, where
        assert code == EXIT[signum], where
        assert err.splitlines() == [f"packetloss-cvx: interrupted by {signal.Signals(signum).name}"], where
        interrupted += 1
    assert interrupted >= len(cases) // 2       # the delays lie within the run: most signals land in it
