"""Command-line runs in child processes forked from a prepared parent (a "zygote"), for the tests that are about a
process (what it imports, how it dies) but not about the interpreter's own start-up.

A :class:`Zygote` is a fresh interpreter (``python -c``, the test's environment) that imports the modules it is
given and then waits; each :meth:`Zygote.run` or :meth:`Zygote.start` forks it, and the child runs ``python -c
CODE args`` or ``python -m MODULE args`` from there: its own folder, environment, stdin (``/dev/null``), stdout and
stderr, its own exit through the interpreter's normal shutdown (atexit, ``__del__``, an uncaught KeyboardInterrupt
re-raised as the signal); what the interpreter and the preloads read from the environment at start-up (Python's
``PYTHON*`` variables, the BLAS thread counts: :func:`startup_variables`) is the zygote's, so a child asked for other
values of them is refused (ValueError), not run with the zygote's. What a child starts with is what a fresh
interpreter has after importing the same modules, no more: :attr:`Zygote.modules` lists the top-level packages
loaded, so a test of imports asserts its forbidden ones absent there, and an eager import planted in a command
still lands in the child's ``sys.modules``. The child saves Python's start-up (~20 ms) and the preloaded imports
(``packetloss_cvx.cli`` ~40 ms, NumPy ~100 ms, the plotting and solver stack ~1.3 s) per run.

The zygote reaps its children and reports each exit status; :class:`Child` mirrors the part of ``subprocess.Popen``
the tests use (``pid``, ``poll``, ``wait``, ``send_signal``, ``communicate``, ``returncode``). POSIX only (fork).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

#: the zygote: imports argv[1] (a JSON list), reports its top-level modules, then serves one JSON request a line on
#: stdin (fork; the child leaves the loop and runs the request at top level) and reports "pid" and "exit" lines
ZYGOTE_SOURCE = r"""
import importlib, json, os, select, sys
for _name in json.loads(sys.argv[1]):
    importlib.import_module(_name)
sys.stdout.write(json.dumps({"modules": sorted({m.split(".")[0] for m in sys.modules})}) + "\n")
sys.stdout.flush()


def _serve():
    pending, children = b"", set()
    while True:
        ready, _, _ = select.select([0], [], [], 0.002 if children else 0.05)
        if ready:
            chunk = os.read(0, 65536)
            if not chunk:               # closed: the test killed what still ran; reap it, leave no zombie
                for pid in children:
                    os.waitpid(pid, 0)
                return None
            pending += chunk
            while b"\n" in pending:
                line, pending = pending.split(b"\n", 1)
                request = json.loads(line)
                sys.stdout.flush()
                pid = os.fork()
                if pid == 0:
                    return request
                children.add(pid)
                sys.stdout.write(json.dumps({"id": request["id"], "pid": pid}) + "\n")
                sys.stdout.flush()
        while children:
            pid, status = os.waitpid(-1, os.WNOHANG)
            if pid == 0:
                break
            children.discard(pid)
            sys.stdout.write(json.dumps({"pid": pid, "exit": os.waitstatus_to_exitcode(status)}) + "\n")
            sys.stdout.flush()


_request = _serve()
if _request is None:
    sys.exit(0)
_null = os.open(os.devnull, os.O_RDONLY)
os.dup2(_null, 0)
for _fd, _path in ((1, _request["stdout"]), (2, _request["stderr"])):
    _file = os.open(_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    os.dup2(_file, _fd)
    os.close(_file)
os.close(_null)
os.chdir(_request["cwd"])
os.environ.clear()
os.environ.update(_request["env"])
del _serve, _null, _fd, _path, _file
if _request["module"]:
    import runpy
    sys.argv = [_request["module"], *_request["args"]]
    runpy.run_module(_request["module"], run_name="__main__", alter_sys=True)
else:
    sys.argv = ["-c", *_request["args"]]
    exec(compile(_request["code"], "<string>", "exec"), {"__name__": "__main__", "__builtins__": __builtins__})
"""


def startup_variables(env: dict[str, str]) -> dict[str, str]:
    """The variables of ``env`` an interpreter reads at start-up (Python's own, ``PYTHON*``) or its preloads read at
    import (the BLAS thread counts ``*_NUM_THREADS``, the package's ``PACKETLOSS_CVX_BLAS_THREADS``, matplotlib's
    ``MPL*``): a forked child inherits the zygote's reading of them, whatever its own environment says. O(len(env))."""
    return {k: v for k, v in env.items()
            if k.startswith(("PYTHON", "MPL")) or k.endswith("_NUM_THREADS") or k == "PACKETLOSS_CVX_BLAS_THREADS"}


class Child:
    """One forked run: the part of ``subprocess.Popen`` the tests use. ``returncode`` as Popen's (``-signum``
    when a signal ended it)."""

    def __init__(self, zygote: Zygote, pid: int, folder: Path) -> None:
        self.zygote, self.pid, self.folder = zygote, pid, folder
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            self.returncode = self.zygote.exit_of(self.pid)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        end = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            if end is not None and time.monotonic() > end:
                raise subprocess.TimeoutExpired(f"forked child {self.pid}", timeout)
            self.zygote.wait_for_news(0.05)
        return self.returncode

    def send_signal(self, signum: int) -> None:
        if self.poll() is None:       # never a pid the zygote has reaped (it may be reused)
            os.kill(self.pid, signum)

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        self.wait(timeout)
        return ((self.folder / "stdout").read_text(errors="replace"),
                (self.folder / "stderr").read_text(errors="replace"))


class Zygote:
    """A fresh interpreter that imported ``preload`` (module names) and forks a child per run. Time: one
    interpreter start and the preloads, then a fork (a few ms) per child. Close it (or use ``with``)."""

    def __init__(self, preload: list[str] | tuple[str, ...] = (), env: dict[str, str] | None = None) -> None:
        self.env = dict(os.environ if env is None else env)
        self.proc = subprocess.Popen([sys.executable, "-c", ZYGOTE_SOURCE, json.dumps(list(preload))],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=self.env, text=True)
        first = self.proc.stdout.readline()
        if not first:
            raise RuntimeError(f"the zygote did not start (exit {self.proc.wait()})")
        #: the top-level packages in the zygote's sys.modules after its preloads: every child starts with them
        self.modules = frozenset(json.loads(first)["modules"])
        self.folder = Path(tempfile.mkdtemp(prefix="zygote-"))
        self.count = 0
        self.pids: dict[int, int] = {}
        self.exits: dict[int, int] = {}
        self.news = threading.Condition()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            message = json.loads(line)
            with self.news:
                if "exit" in message:
                    self.exits[message["pid"]] = message["exit"]
                else:                   # a pid reaped before may be reused: its old exit is not this child's
                    self.exits.pop(message["pid"], None)
                    self.pids[message["id"]] = message["pid"]
                self.news.notify_all()

    def wait_for_news(self, timeout: float) -> None:
        with self.news:
            self.news.wait(timeout)

    def exit_of(self, pid: int) -> int | None:
        with self.news:
            return self.exits.get(pid)

    def start(self, args: list[str], *, module: str | None = None, code: str | None = None,
              cwd: str | os.PathLike | None = None, env: dict[str, str] | None = None) -> Child:
        """``python -m module args`` or ``python -c code args`` as a forked child, started."""
        if (module is None) == (code is None):
            raise ValueError("give exactly one of module and code")
        env = dict(self.env if env is None else env)
        if startup_variables(env) != startup_variables(self.env):   # a fresh interpreter would read them; a fork cannot
            differ = sorted(set(startup_variables(env).items()) ^ set(startup_variables(self.env).items()))
            raise ValueError(f"a forked child cannot take other start-up variables than its zygote's: "
                             f"{sorted({k for k, _ in differ})}; start a Zygote with that environment")
        with self.news:             # threads may start children at once: each its own number
            self.count += 1
            number = self.count
        folder = self.folder / str(number)
        folder.mkdir()
        request = {"id": number, "module": module, "code": code, "args": [str(a) for a in args],
                   "cwd": str(cwd or os.getcwd()), "env": env,
                   "stdout": str(folder / "stdout"), "stderr": str(folder / "stderr")}
        with self.news:
            self.proc.stdin.write(json.dumps(request) + "\n")
            self.proc.stdin.flush()
            if not self.news.wait_for(lambda: number in self.pids, timeout=60):
                raise RuntimeError("the zygote did not fork")
            pid = self.pids[number]
        return Child(self, pid, folder)

    def run(self, args: list[str], *, timeout: float = 120, **kwargs) -> subprocess.CompletedProcess:
        """:meth:`start`, then wait: a ``CompletedProcess`` (returncode, stdout, stderr), like ``subprocess.run``
        with ``capture_output=True, text=True``."""
        child = self.start(args, **kwargs)
        out, err = child.communicate(timeout)
        return subprocess.CompletedProcess(args, child.returncode, out, err)

    def close(self) -> None:
        """Kill the children still running (a test that timed out), stop the zygote, remove the output files."""
        with self.news:
            running = [pid for pid in self.pids.values() if pid not in self.exits]
        for pid in running:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        self.proc.stdin.close()
        self.proc.wait(timeout=60)
        self.reader.join(timeout=5)
        for path in sorted(self.folder.rglob("*"), reverse=True):
            path.rmdir() if path.is_dir() else path.unlink()
        self.folder.rmdir()

    def __enter__(self) -> Zygote:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
