"""runfolder: the output-folder rule (a user's files refused, the package's folder replaced as a whole), the
manifest (checked against hashlib on the files themselves), and the lock (live, stale, empty)."""

import hashlib
import json
import os
import subprocess
import sys
import time

import pytest

from packetloss_cvx.errors import FolderBusyError, InputError, OutputExistsError
from packetloss_cvx.runfolder import LOCK_NAME, MANIFEST_NAME, RunFolder
from packetloss_cvx.safeio import TEMP_PREFIX


def _run(folder, files, **kwargs):
    with RunFolder(folder, command="test", **kwargs) as run:
        for name, payload in files.items():
            with run.write(name) as handle:
                handle.write(payload)


def _manifest(folder):
    return json.loads((folder / MANIFEST_NAME).read_text())


def _dead_pid():
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                          check=True)
    return int(done.stdout)


def test_the_manifest_lists_each_file_with_its_size_and_sha256(tmp_path):
    out = tmp_path / "run"
    files = {"a.bin": os.urandom(3000), "b.csv": b"x,y\n1,2\n"}
    _run(out, files)
    manifest = _manifest(out)
    assert manifest["complete"] is True
    assert manifest["command"] == "test"
    assert manifest["packetloss_cvx"]
    assert {f["name"]: (f["bytes"], f["sha256"]) for f in manifest["files"]} == {
        name: (len(data), hashlib.sha256(data).hexdigest()) for name, data in files.items()}
    assert sorted(os.listdir(out)) == ["a.bin", "b.csv", MANIFEST_NAME]      # the lock is gone


def test_a_rerun_replaces_the_run_as_a_whole(tmp_path):
    out = tmp_path / "run"
    _run(out, {"sweep.png": b"1-D figure", "sweep.npz": b"old"})
    _run(out, {"sweep.npz": b"new", "sweep_tcp.png": b"2-D figure"})
    assert sorted(os.listdir(out)) == [MANIFEST_NAME, "sweep.npz", "sweep_tcp.png"]    # no stale sweep.png
    assert (out / "sweep.npz").read_bytes() == b"new"


def test_a_folder_with_a_users_file_is_refused_unless_force(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("the user's")
    with pytest.raises(OutputExistsError, match=r"notes.txt; pass --force") as err:
        _run(out, {"sweep.npz": b"x"})
    assert isinstance(err.value, ValueError)
    assert err.value.field == "out"
    assert sorted(os.listdir(out)) == ["notes.txt"]                        # refused before anything, lock gone
    _run(out, {"sweep.npz": b"x"}, force=True)
    _run(out, {"sweep.csv": b"y"}, force=True)                             # forced again: the user's file stays
    assert sorted(os.listdir(out)) == [MANIFEST_NAME, "notes.txt", "sweep.csv"]
    assert [f["name"] for f in _manifest(out)["files"]] == ["sweep.csv"]
    # the package's folder with an extra file someone added: refused too
    (tmp_path / "ours").mkdir()
    _run(tmp_path / "ours", {"a": b"1"})
    (tmp_path / "ours" / "added.txt").write_text("later")
    with pytest.raises(OutputExistsError, match="no manifest of packetloss-cvx lists added.txt"):
        _run(tmp_path / "ours", {"a": b"2"})



def test_a_run_file_edited_since_is_refused_unless_force_and_kept_if_not_rewritten(tmp_path):
    """A file the complete manifest lists but whose size or sha256 no longer match (edited by hand since) is the
    user's now: a rerun is refused without --force; forced, a file the new run does not write stays, unlisted.
    A manifest entry whose hash matches no file of that name (a hand-made manifest) does not make it the package's."""
    out = tmp_path / "run"
    _run(out, {"sweep.csv": b"x,y\n1,2\n", "sweep.png": b"figure"})
    (out / "sweep.csv").write_bytes(b"x,y\n1,2\nmy annotations\n")        # longer: the size differs
    (out / "sweep.png").write_bytes(b"FIGURE")                              # same size: only the sha256 differs
    with pytest.raises(OutputExistsError, match=r"changed since packetloss-cvx wrote them: sweep.csv, sweep.png; "
                                                r"pass --force"):
        _run(out, {"sweep.npz": b"new"})
    assert (out / "sweep.csv").read_bytes().endswith(b"my annotations\n")
    _run(out, {"sweep.csv": b"new"}, force=True)                            # forced: the rewritten one is replaced
    assert (out / "sweep.png").read_bytes() == b"FIGURE"                     # the edited one not rewritten stays
    assert [f["name"] for f in _manifest(out)["files"]] == ["sweep.csv"]
    made = tmp_path / "made"
    made.mkdir()
    (made / "notes.txt").write_text("the user's")
    (made / MANIFEST_NAME).write_text(json.dumps({"packetloss_cvx": "0.1.0", "complete": True,
                                                  "files": [{"name": "notes.txt", "sha256": "x"}]}))
    with pytest.raises(OutputExistsError, match="changed since packetloss-cvx wrote them: notes.txt"):
        _run(made, {"a": b"1"})
    assert (made / "notes.txt").read_text() == "the user's"

def test_an_empty_folder_is_accepted_and_special_paths_refused(tmp_path):
    (tmp_path / "empty").mkdir()
    _run(tmp_path / "empty", {"a": b"1"})
    (tmp_path / "file").write_text("x")
    os.mkfifo(tmp_path / "fifo")
    for path, pattern in ((tmp_path / "file", "not a folder"), (tmp_path / "fifo", "FIFO"), (" ", "empty path")):
        with pytest.raises(InputError, match=pattern):
            _run(path, {"a": b"1"})


def test_a_failed_run_leaves_an_incomplete_manifest_and_no_folder_it_made_empty(tmp_path):
    out = tmp_path / "run"
    _run(out, {"a": b"1", "b": b"2"})
    with pytest.raises(RuntimeError), RunFolder(out, command="test") as run:   # noqa: PT012 - a failing run's block
        with run.write("c") as handle:
            handle.write(b"3")
        raise RuntimeError("the sweep failed")
    manifest = _manifest(out)
    assert manifest["complete"] is False
    assert sorted(f["name"] for f in manifest["files"]) == ["a", "b", "c"]       # every file there is listed
    _run(out, {"a": b"4"})                                                       # and the next run accepts it
    assert sorted(os.listdir(out)) == ["a", MANIFEST_NAME]
    with pytest.raises(RuntimeError), RunFolder(tmp_path / "new", command="test"):
        raise RuntimeError("failed before writing")
    assert not (tmp_path / "new").exists()


def test_a_live_lock_refuses_a_second_run_naming_its_pid(tmp_path):
    out = tmp_path / "run"
    with RunFolder(out, command="first"):
        with pytest.raises(FolderBusyError, match=rf"being written by another run \(pid {os.getpid()}\)"):
            _run(out, {"a": b"1"})
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        (out / LOCK_NAME).write_text(f"{other.pid}\n")
        with pytest.raises(FolderBusyError, match=f"pid {other.pid}"):
            _run(out, {"a": b"1"})
        assert (out / LOCK_NAME).read_text() == f"{other.pid}\n"                 # the live lock is untouched
    finally:
        other.kill()
        other.wait()


def test_a_stale_lock_and_dead_runs_temporaries_are_taken_over(tmp_path):
    out = tmp_path / "run"
    _run(out, {"a": b"1"})
    pid = _dead_pid()
    (out / LOCK_NAME).write_text(f"{pid}\n")
    (out / f"{TEMP_PREFIX}{pid}-abcd-a").write_bytes(b"half")
    _run(out, {"a": b"2"})
    assert sorted(os.listdir(out)) == ["a", MANIFEST_NAME]
    # an empty lock: its writer is starting (refused) or died before writing its pid (stale after 5 s)
    (out / LOCK_NAME).write_text("")
    with pytest.raises(FolderBusyError, match="starting"):
        _run(out, {"a": b"3"})
    old = time.time() - 60
    os.utime(out / LOCK_NAME, (old, old))
    _run(out, {"a": b"3"})
    assert (out / "a").read_bytes() == b"3"


def test_names_outside_the_folder_are_refused(tmp_path):
    with RunFolder(tmp_path / "run", command="test") as run:
        for name in ("../escape", MANIFEST_NAME, LOCK_NAME):
            with pytest.raises(InputError, match="not a file name"):
                run.write(name)


def test_two_runs_taking_over_one_stale_lock_cannot_both_win(tmp_path, monkeypatch):
    """Run B read the stale pid; before B removes the lock, run A (live) has replaced it with its own. B
    must put A's lock back and refuse, naming A."""
    out = tmp_path / "run"
    out.mkdir()
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        (out / LOCK_NAME).write_text(f"{other.pid}\n")                     # A's fresh lock, on disk
        dead = _dead_pid()
        reads = iter([dead])                                               # B's first read saw the stale one
        real = RunFolder._lock_owner
        monkeypatch.setattr(RunFolder, "_lock_owner", staticmethod(lambda lock: next(reads, None) or real(lock)))
        with pytest.raises(FolderBusyError, match=f"pid {other.pid}"):
            _run(out, {"a": b"1"})
        assert (out / LOCK_NAME).read_text() == f"{other.pid}\n"           # A still holds the folder
        assert sorted(os.listdir(out)) == [LOCK_NAME]                      # nothing else written or left aside
    finally:
        other.kill()
        other.wait()


def _interrupted(folder, files, failing="c"):
    """A run that writes ``files`` and is interrupted while writing ``failing`` (its temporary file removed)."""
    try:
        with RunFolder(folder, command="test") as run:
            for name, payload in files.items():
                with run.write(name) as handle:
                    handle.write(payload)
            with run.write(failing) as handle:
                handle.write(b"half")
                raise KeyboardInterrupt
    except KeyboardInterrupt:
        return
    raise AssertionError("the run was not interrupted")


def test_a_file_an_interrupted_run_finished_and_the_user_edited_is_the_users(tmp_path):
    """After an interrupted sweep the user appended a note to its sweep.csv: the next run replaced it without
    --force, because an unfinished run's manifest listed names only. Each file the run finishes is listed with
    its size and sha256 at once, so an edit is seen as after a complete run."""
    out = tmp_path / "run"
    _interrupted(out, {"sweep.npz": b"arrays", "sweep.csv": b"x,y\n1,2\n"}, failing="sweep.png")
    manifest = _manifest(out)
    assert manifest["complete"] is False
    assert {f["name"]: f.get("sha256") for f in manifest["files"]} == {
        "sweep.npz": hashlib.sha256(b"arrays").hexdigest(), "sweep.csv": hashlib.sha256(b"x,y\n1,2\n").hexdigest(),
        "sweep.png": None}
    with (out / "sweep.csv").open("ab") as handle:
        handle.write(b"# my note\n")
    with pytest.raises(OutputExistsError, match="changed since packetloss-cvx wrote them: sweep.csv"):
        _run(out, {"sweep.csv": b"new", "sweep.npz": b"new"})
    assert (out / "sweep.csv").read_bytes() == b"x,y\n1,2\n# my note\n"
    (out / "sweep.csv").write_bytes(b"x,y\n1,2\n")                           # the note taken back: ours again
    _run(out, {"sweep.csv": b"new"})
    assert sorted(os.listdir(out)) == [MANIFEST_NAME, "sweep.csv"]


def test_an_unfinished_manifest_naming_a_users_file_does_not_let_a_run_delete_it(tmp_path):
    """An unfinished manifest lists the file in flight by name only (its content unknown): such an entry is taken as
    the package's only for a file that appeared after that manifest was written (the run's own last write); an older
    file of that name is the user's (a hand-made or stale manifest naming thesis.tex let the next run delete it)."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "thesis.tex").write_text("the user's")
    old = time.time() - 60
    os.utime(out / "thesis.tex", (old, old))
    (out / MANIFEST_NAME).write_text(json.dumps({"packetloss_cvx": "0.1.0", "complete": False,
                                                 "files": [{"name": "thesis.tex"}]}))
    with pytest.raises(OutputExistsError, match="changed since packetloss-cvx wrote them: thesis.tex"):
        _run(out, {"sweep.npz": b"x"})
    assert (out / "thesis.tex").read_text() == "the user's"
    # the run's own file in flight when it stopped (written after its manifest): the package's
    later = time.time() + 60
    (out / "thesis.tex").write_text("written by the run")
    os.utime(out / "thesis.tex", (later, later))
    _run(out, {"sweep.npz": b"x"})
    assert sorted(os.listdir(out)) == [MANIFEST_NAME, "sweep.npz"]


def test_a_users_edit_inside_the_manifest_is_refused_unless_force(tmp_path):
    """The manifest carries the sha256 of its own content: a user's edit inside it (a note in its command) was
    replaced silently by the next run; now it is refused as a changed file, and --force replaces it."""
    out = tmp_path / "run"
    _run(out, {"a": b"1"})
    manifest = _manifest(out)
    manifest["command"] += "  # the run of the paper's table 2"
    (out / MANIFEST_NAME).write_text(json.dumps(manifest, indent=1) + "\n")
    with pytest.raises(OutputExistsError, match="changed since packetloss-cvx wrote them: manifest.json"):
        _run(out, {"a": b"2"})
    assert "table 2" in (out / MANIFEST_NAME).read_text()
    _run(out, {"a": b"2"}, force=True)
    assert "table 2" not in (out / MANIFEST_NAME).read_text()
    _run(out, {"a": b"3"})                                      # the package's manifest again: no --force needed
    assert (out / "a").read_bytes() == b"3"


def test_a_complete_run_of_another_command_is_refused_unless_force(tmp_path):
    out = tmp_path / "run"
    with RunFolder(out, command="packetloss-cvx sweep f --mu-grid 3 --out run --format svg") as run:
        for name in ("sweep.npz", "sweep_tcp.svg"):
            with run.write(name) as handle:
                handle.write(b"earlier " + name.encode())
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(OutputExistsError, match="--format svg` .*a different command; pass --force"):
        with RunFolder(out, command="packetloss-cvx sweep f --mu-grid 3 --out run --format pdf"):
            pass
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before          # nothing replaced, nothing removed
    with RunFolder(out, command="packetloss-cvx sweep f --mu-grid 3 --out run --format svg -q --force") as run:
        with run.write("sweep.npz") as handle:                               # the same command: a re-run
            handle.write(b"again")
    assert sorted(os.listdir(out)) == [MANIFEST_NAME, "sweep.npz"]
    with RunFolder(out, command="packetloss-cvx sweep f --mu-grid 5 --out run", force=True) as run:
        with run.write("sweep.npz") as handle:
            handle.write(b"forced")
    assert (out / "sweep.npz").read_bytes() == b"forced"
