"""The command line's output files: complete or absent when it is interrupted, killed, raced and starved of disk,
and a user's files never replaced without --force.

Each hostile case runs the real command line in a subprocess (or, for a full disk, in process on a
2 MB tmpfs) and then reads every file left with an independent reader (``np.load``, ``csv``, ``json``,
the PNG chunk layout, ``hashlib`` against the manifest): each is absent or complete, never truncated.
Interrupt times are seeded; a signal is sent a seeded delay after the first temporary file appears, so
it lands in the writes (the dangerous part), not only in the computation. Subprocesses run at the same
time to keep the module within a few seconds on two cores. A run interrupted in its writes is forked from a
parent that already imported the package and its numerical stack (tests/processes.py: the interpreter's start-up
and the imports are not what it tests; its own ``python -m packetloss_cvx`` entry, signal handlers, writes and
exit are); the run interrupted during its imports starts a fresh interpreter.
"""

import csv
import hashlib
import json
import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.runfolder import LOCK_NAME, MANIFEST_NAME
from packetloss_cvx.safeio import TEMP_PREFIX

from ..processes import Zygote

ROOT = Path(__file__).resolve().parents[2]
POINTS = 40_000            # a sweep whose CSV takes about half a second to write: room for a signal to land in it
EXIT = {signal.SIGINT: 130, signal.SIGTERM: 143, signal.SIGKILL: -signal.SIGKILL}


ENV = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
#: what the forked runs find imported: the command modules of sweep and reproduce and their numerical stack
PRELOAD = ["packetloss_cvx.cli", "packetloss_cvx.cli.sweep", "packetloss_cvx.cli.reproduce",
           "packetloss_cvx.plots.figures", "packetloss_cvx.studies", "cvxpy", "scipy.linalg", "matplotlib.figure",
           "matplotlib.backends.backend_agg"]


@pytest.fixture(scope="module")
def zygote():
    with Zygote(PRELOAD, env=ENV) as parent:
        yield parent


def _start(args, cwd, zygote=None):
    """``python -m packetloss_cvx args -q`` in ``cwd``: a fresh interpreter, or forked from ``zygote``."""
    if zygote is not None:
        return zygote.start([*args, "-q"], module="packetloss_cvx", cwd=cwd, env=ENV)
    return subprocess.Popen([sys.executable, "-m", "packetloss_cvx", *args, "-q"], cwd=cwd, env=ENV,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _wait_for(predicate, proc, timeout=60.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end and proc.poll() is None:
        if predicate():
            return True
        time.sleep(0.005)
    return False


def _temporaries(folder):
    return [n for n in os.listdir(folder) if n.startswith(TEMP_PREFIX)] if folder.is_dir() else []


def _handles_sigterm(pid):
    """Whether the process catches SIGTERM (/proc's SigCgt mask): the package's handler is installed. Before
    that the interpreter is still starting (its own start-up, before the package's first line, is Python's)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return True              # no /proc: the start-up is not observable; the seeded delay decides
    caught = next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:"))
    return bool(int(caught, 16) >> (signal.SIGTERM - 1) & 1)


def _interrupt(proc, folder, signum, delay, first_write=True):
    """Send ``signum`` ``delay`` seconds after the first temporary file appears, or (``first_write``
    False) after the package's signal handler is installed: in the imports."""
    if first_write:
        _wait_for(lambda: bool(_temporaries(folder)), proc)
    else:
        _wait_for(lambda: _handles_sigterm(proc.pid), proc)
    time.sleep(delay)
    if proc.poll() is None:
        proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    return proc.returncode, err


def _png_complete(data):
    """A PNG's signature, then chunks (length, type, data, crc) up to IEND, with nothing after it."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        return False
    k = 8
    while k + 8 <= len(data):
        length = int.from_bytes(data[k:k + 4], "big")
        kind = data[k + 4:k + 8]
        k += 12 + length
        if kind == b"IEND":
            return k == len(data)
    return False


def _check_file(path, points):
    """Raises unless the file reads back whole."""
    if path.suffix == ".npz":
        with np.load(path) as npz:
            arrays = {k: npz[k] for k in npz.files}
        assert arrays["cost_tcp"].shape == (points,)
        assert arrays["mu"].shape[0] == points
        return arrays
    if path.suffix == ".csv":
        with path.open(newline="") as handle:
            rows = list(csv.reader(handle))
        assert len(rows) == points + 1
        assert len(rows[-1]) == len(rows[0])
        return rows
    if path.suffix == ".png":
        assert _png_complete(path.read_bytes()), path.name
    elif path.suffix == ".json":
        json.loads(path.read_text())
    elif path.suffix == ".md":
        assert path.read_text(encoding="utf-8").endswith("\n"), path.name
    else:
        raise AssertionError(f"unexpected file {path.name}")
    return None


def _check_folder(folder, points, killed):
    """Every file absent or complete; a complete manifest matches the files byte for byte; nothing
    of ours left behind unless the run was killed (then the next run cleans it)."""
    if not folder.exists():
        return "absent"
    names = sorted(os.listdir(folder))
    leftovers = [n for n in names if n.startswith(TEMP_PREFIX) or n == LOCK_NAME]
    assert killed or not leftovers, leftovers
    data = {}
    for name in names:
        if name not in leftovers and name != MANIFEST_NAME:
            data[name] = _check_file(folder / name, points)
    if MANIFEST_NAME in names:
        manifest = json.loads((folder / MANIFEST_NAME).read_text())
        listed = {f["name"] for f in manifest["files"]}
        assert set(data) <= listed, set(data) - listed            # every file there is the package's
        if manifest["complete"]:
            assert listed == set(data)
            for f in manifest["files"]:
                raw = (folder / f["name"]).read_bytes()
                assert (len(raw), hashlib.sha256(raw).hexdigest()) == (f["bytes"], f["sha256"]), f["name"]
    else:
        assert not data, "files without a manifest"
    if "sweep.npz" in data and "sweep.csv" in data and MANIFEST_NAME in names and \
            json.loads((folder / MANIFEST_NAME).read_text())["complete"]:
        column = data["sweep.csv"][0].index("cost_tcp")          # the two files come from one run
        assert np.array_equal([float(row[column]) for row in data["sweep.csv"][1:]], data["sweep.npz"]["cost_tcp"])
    return "complete" if MANIFEST_NAME in names and json.loads((folder / MANIFEST_NAME).read_text())["complete"] \
        else "partial"


def _one_line(err, signum):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0] == f"packetloss-cvx: interrupted by {signal.Signals(signum).name}"


def test_interrupted_and_killed_runs_leave_only_complete_files(tmp_path, zygote):
    """Two sweeps (SIGINT, SIGKILL in their writes), a reproduce --quick (a seeded signal at a seeded point)
    and a SIGINT during the imports, all at once; then a run into the killed one's folder cleans up. (SIGTERM
    in a sweep's writes: the two-writer test below.)"""
    rng = random.Random(20)
    sweep = ["sweep", "two_actuator", "--x0-scales", f"0:1:{POINTS}", "--out"]
    cases = [(sweep + ["s-int"], "s-int", signal.SIGINT, rng.uniform(0.0, 0.8), True),
             (sweep + ["s-kill"], "s-kill", signal.SIGKILL, rng.uniform(0.0, 0.8), True),
             (["reproduce", "--quick", "--out", "rep"], "rep", rng.choice(list(EXIT)), rng.uniform(0.0, 0.5), True),
             (sweep + ["s-import"], "s-import", signal.SIGINT, rng.uniform(0.0, 0.3), False)]
    results = {}

    def one(args, name, signum, delay, first_write):   # in the writes: forked; in the imports: a fresh interpreter
        proc = _start(args, tmp_path, zygote if first_write else None)
        results[name] = _interrupt(proc, tmp_path / name, signum, delay, first_write)

    threads = [threading.Thread(target=one, args=case) for case in cases]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    tried = 0
    for _args, name, signum, _, _ in cases:
        code, err = results[name]
        killed = signum == signal.SIGKILL
        assert code in (EXIT[signum], 0), (name, code, err)       # 0: the run finished before the signal
        if code == 0:
            assert err == ""
        elif not killed:
            _one_line(err, signum)
        points = POINTS if name.startswith("s-") else 0
        if name == "rep":
            for png in (tmp_path / name).glob("*.png") if (tmp_path / name).exists() else ():
                assert _png_complete(png.read_bytes())
            _check_folder_reproduce(tmp_path / name, killed)
        else:
            _check_folder(tmp_path / name, points, killed)
        tried += 1
    assert tried == len(cases)
    # after a kill: the stale lock and the dead run's temporary files go with the next run into the folder
    small = ["sweep", "two_actuator", "--x0-scales", "0:1:7", "--out", str(tmp_path / "s-kill"), "-q"]
    assert main(small) == 0
    assert _check_folder(tmp_path / "s-kill", 7, killed=False) == "complete"


def _check_folder_reproduce(folder, killed):
    if not folder.exists():
        return
    names = os.listdir(folder)
    assert killed or not [n for n in names if n.startswith(TEMP_PREFIX) or n == LOCK_NAME]
    for name in names:
        if name.endswith(".json"):
            json.loads((folder / name).read_text())
    if MANIFEST_NAME in names:
        manifest = json.loads((folder / MANIFEST_NAME).read_text())
        present = {n for n in names if not n.startswith(TEMP_PREFIX) and n not in (LOCK_NAME, MANIFEST_NAME)}
        assert present <= {f["name"] for f in manifest["files"]}
        if manifest["complete"]:
            for f in manifest["files"]:
                raw = (folder / f["name"]).read_bytes()
                assert hashlib.sha256(raw).hexdigest() == f["sha256"]


def test_two_runs_into_one_folder_cannot_interleave(tmp_path, capsys, zygote):
    """The second run refuses at once (exit 2, one line naming the folder and the first run's pid); the
    first, terminated in its writes, leaves only complete files of its own."""
    out = tmp_path / "shared"
    first = _start(["sweep", "two_actuator", "--x0-scales", f"0:1:{POINTS}", "--out", str(out)], tmp_path, zygote)
    def locked():       # the lock is created, then its pid written: the refusal names the pid only after that
        try:
            return (out / LOCK_NAME).read_text().strip().isdigit()
        except OSError:
            return False

    assert _wait_for(locked, first)
    code = main(["sweep", "two_actuator", "--x0-scales", "0:2:7", "--out", str(out), "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1
    assert f"'{out}' is being written by another run (pid {first.pid})" in err[0]
    code, stderr = _interrupt(first, out, signal.SIGTERM, random.Random(3).uniform(0.0, 0.8))
    assert code in (143, 0), stderr
    if code == 143:
        _one_line(stderr, signal.SIGTERM)
    assert _check_folder(out, POINTS, killed=False) in ("complete", "partial", "absent")


@pytest.fixture
def small_disk(tmp_path):
    """A 2 MB tmpfs (root only; else skipped with the reason)."""
    mount = tmp_path / "disk"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mount)], capture_output=True,
                          text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here (needs root): {done.stderr.strip()[:80]}")
    yield mount
    subprocess.run(["umount", str(mount)], check=True)


def test_a_full_disk_leaves_no_partial_file(small_disk, capsys):
    """sweep.npz of 30 000 points (3.1 MB) cannot fit in 2 MB; a JSON or a PNG beside a ballast filling the
    disk cannot either: each is one line naming its option, and nothing partial is left."""
    assert main(["sweep", "two_actuator", "--x0-scales", "0:1:30000", "--out", str(small_disk / "s"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "No space left on device" in err[0]
    assert err[0].startswith("packetloss-cvx: error: --out")
    assert _check_folder(small_disk / "s", 30000, killed=False) in ("partial", "absent")
    assert not (small_disk / "s" / "sweep.npz").exists()
    free = os.statvfs(small_disk)
    (small_disk / "ballast").write_bytes(b"\0" * (free.f_bavail * free.f_frsize))
    assert main(["solve", "two_actuator", "--no-qp", "--out", str(small_disk / "r.json"), "-q"]) == 2
    assert "No space left on device" in capsys.readouterr().err
    assert main(["simulate", "two_actuator", "--samples", "20", "--steps", "3", "--closed-loop", "--plot",
                 str(small_disk / "p.png"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("packetloss-cvx: error: --plot: ")
    assert "No space left" in err[0]
    assert sorted(os.listdir(small_disk)) == ["ballast", "s"]         # no 0-byte r.json or p.png, no temporary



def test_a_full_disk_leaves_no_lock_and_is_one_line(small_disk, capsys):
    """On a disk with no block left the folder's lock could be created but not written: the run exited 1
    ("unexpected OSError") and left an empty .packetloss-cvx.lock (and the folder it made). Now: exit 2, one line
    naming --out, nothing left; a folder that was there keeps only what it held."""
    (small_disk / "old").mkdir()
    free = os.statvfs(small_disk)
    (small_disk / "ballast").write_bytes(b"\0" * (free.f_bavail * free.f_frsize))
    for name in ("new", "old"):
        assert main(["sweep", "two_actuator", "--mu-grid", "3", "--out", str(small_disk / name), "-q"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1, err
        assert err[0].startswith(f"packetloss-cvx: error: --out: cannot use '{small_disk / name}': No space left")
    assert sorted(os.listdir(small_disk)) == ["ballast", "old"]
    assert os.listdir(small_disk / "old") == []

def test_a_users_files_are_never_replaced_without_force(tmp_path, capsys, monkeypatch):
    """Every command that writes, pointed at a user's files: exit 2, one line naming the path and --force,
    the files byte for byte as they were; with --force the run goes through."""
    monkeypatch.chdir(tmp_path)          # and back after the test: the files after this one run from the root
    (tmp_path / "mine").mkdir()
    user = {"r.json": b"{}", "s.npz": b"not ours", "p.png": b"a photo", "mine/sweep.csv": b"a,b\n"}
    for name, raw in user.items():
        (tmp_path / name).write_bytes(raw)
    commands = [["solve", "two_actuator", "--no-qp", "--out", "r.json"],
                ["simulate", "two_actuator", "--samples", "20", "--save", "s.npz"],
                ["simulate", "two_actuator", "--samples", "20", "--steps", "3", "--closed-loop", "--plot", "p.png"],
                ["simulate", "two_actuator", "--samples", "20", "--steps", "3", "--closed-loop", "--plot", "p"],
                ["sweep", "two_actuator", "--mu-grid", "3", "--out", "mine"],
                ["sweep", "pendulum_bursty", "--burstiness", "0,0.5", "--out", "mine"],
                ["reproduce", "--quick", "--out", "mine"]]
    for command in commands:
        assert main([*command, "-q"]) == 2, command
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1, err
        assert "--force" in err[0], err
    for name, raw in user.items():
        assert (tmp_path / name).read_bytes() == raw, name
    assert main(["solve", "two_actuator", "--no-qp", "--out", "r.json", "-q", "--force"]) == 0
    assert json.loads((tmp_path / "r.json").read_text())["name"] == "two-actuator"
