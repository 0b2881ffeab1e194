"""Output folders written by one run at a time, listed in a manifest (docs/design.md §4, "Files and runs").

* A folder is refused if it holds a file that no manifest of this package lists, or a listed file that is no
  longer the one its complete manifest describes (size and sha256: edited since), unless ``force=True``
  (``--force``): a user's files are never replaced silently. An empty folder is accepted.
* The folder carries ``manifest.json`` (command, version, time, each file with its size and sha256,
  ``"complete": true``, and the sha256 of its own content, ``"digest"``), written last and atomically. While a run
  writes, the manifest says ``"complete": false`` and lists every name the run (or the run it replaces) may have
  left, each file the run has finished with its size and sha256 as soon as it is finished, so the package's folder
  is always recognisably its own and a file edited after an interrupted run is seen as after a complete one. The
  one file in flight is listed by name only: such an entry makes a file the package's only if it is not older
  than the manifest (the run's last write); an older one is a user's file.
* A manifest edited by hand (its digest no longer matches) is a changed file: refused without ``force``.
* A new run of the same command (`same_command`: the manifest's command line, ignoring the options that only
  change what is printed) into the package's own folder replaces the run as a whole: files of the previous run
  that this one does not write are removed before its manifest is written. A complete run of a different command
  is refused unless ``force=True``: its files (data, figures in another format) would be replaced or removed.
  With ``--force`` in a folder holding other files, those files are left alone and are not listed.
* One run at a time: ``.packetloss-cvx.lock`` (created with O_CREAT|O_EXCL, holding the pid) makes a
  second run refuse ([`FolderBusyError`][packetloss_cvx.errors.FolderBusyError], naming the pid); a lock whose pid
  is dead (a ``kill -9``) is stale and taken over, and the dead run's temporary files are removed.

Every file goes through `packetloss_cvx.safeio.atomic_write`.
"""

from __future__ import annotations

import contextlib
import datetime
import hashlib
import json
import os
import secrets
import shlex
import stat
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from .errors import FolderBusyError, InputError, OutputExistsError
from .printable import printable
from .safeio import TEMP_PREFIX, atomic_write, check_flag, clean_temporaries, file_digest, pid_alive, refuse_special

__all__ = ["LOCK_NAME", "MANIFEST_NAME", "RunFolder", "manifest_digest", "read_manifest", "same_command"]

LOCK_NAME = ".packetloss-cvx.lock"
MANIFEST_NAME = "manifest.json"
#: options that change only what a command prints (or whether it may replace files), not the files it writes
PRINT_ONLY = frozenset({"-q", "--quiet", "-v", "-vv", "-vvv", "--verbose", "--force", "--json"})


def same_command(earlier: object, now: str) -> bool:
    """Whether a run folder's manifest's ``command`` (``earlier``) is the command line ``now`` up to the options
    that only change what is printed (`PRINT_ONLY`): re-running it regenerates the folder's files. O(length).

    >>> same_command("packetloss-cvx sweep pendulum --mu-grid 5 --out s", "packetloss-cvx sweep pendulum "
    ...              "--mu-grid 5 --out s -q --force")
    True
    >>> same_command("packetloss-cvx sweep pendulum --mu-grid 5 --out s", "packetloss-cvx sweep pendulum "
    ...              "--mu-grid 5 --out s --format pdf")
    False
    """
    if not isinstance(earlier, str):
        return False
    try:
        words = [[w for w in shlex.split(text) if w not in PRINT_ONLY] for text in (earlier, now)]
    except ValueError:          # unbalanced quotes: a manifest edited by hand (its digest says so too)
        return earlier == now
    return words[0] == words[1]


def read_manifest(folder: str | Path) -> dict[str, Any] | None:
    """``folder``'s manifest if it is one of this package's (a JSON object with ``"packetloss_cvx"`` and a
    list of ``"files"``), else None. O(size of the manifest).

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _ = (Path(tmp) / MANIFEST_NAME).write_text('{"files": []}')      # not ours: no version key
    ...     read_manifest(tmp)
    """
    try:
        data = json.loads((Path(folder) / MANIFEST_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or "packetloss_cvx" not in data or not isinstance(data.get("files"), list):
        return None
    if not all(isinstance(f, dict) and isinstance(f.get("name"), str) for f in data["files"]):
        return None
    return data


def manifest_digest(data: dict[str, Any]) -> str:
    """The sha256 of a manifest's content without its ``"digest"`` (keys sorted, as JSON): what the manifest records
    of itself, so that an edit inside it is seen. O(size).

    >>> manifest_digest({"b": 1, "a": [2], "digest": "x"}) == manifest_digest({"a": [2], "b": 1})
    True
    """
    body = {key: value for key, value in data.items() if key != "digest"}
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


class RunFolder:
    """An output folder written by one run: locked, checked, listed in a manifest (the module's rule).

    Use as a context manager, entered before the long work (so a refusal costs nothing); ``write(name)``
    gives an `atomic_write` handle for each file. A block that ends without an error removes the
    previous run's files that this run did not write and writes ``manifest.json`` (complete) last; one
    that raises leaves the files written so far under a manifest that says ``"complete": false``. The
    lock is released either way. O(entries) to enter; O(total bytes) to hash at the end.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     out = Path(tmp) / "run"
    ...     with RunFolder(out, command="example") as folder:
    ...         with folder.write("a.txt", text=True) as handle:
    ...             _ = handle.write("one")
    ...     with RunFolder(out, command="example") as folder:          # the package's folder: accepted
    ...         with folder.write("b.txt", text=True) as handle:
    ...             _ = handle.write("two")
    ...     manifest = read_manifest(out)
    ...     sorted(p.name for p in out.iterdir()), manifest["complete"], [f["name"] for f in manifest["files"]]
    (['b.txt', 'manifest.json'], True, ['b.txt'])
    """

    def __init__(self, path: str | Path, *, command: str, force: bool = False, field: str = "out") -> None:
        if not str(path).strip():        # an unset $DIR: not the current folder
            raise InputError(field, "expected a folder, found an empty path")
        self.path = Path(path)
        self.command = command
        self.force = check_flag(force, "force")
        self.field = field
        self.written: list[str] = []
        self.done: dict[str, dict[str, Any]] = {}     # the files this run finished: their entries (size, sha256)
        self.previous: list[str] = []       # names the previous run (complete or not) left
        self.carried: dict[str, dict[str, Any]] = {}  # their entries, with the sha256 of what is there
        self.created = False
        self.locked = False
        self.marked = False                  # the manifest says "complete": false for this run

    # -- entering: checks, lock, ownership ---------------------------------------------------------------
    def __enter__(self) -> RunFolder:
        self._claim()
        try:
            self._check_owner()
        except BaseException:
            self._release()
            raise
        return self

    def _fail(self, err: OSError) -> InputError:
        return InputError(self.field, f"cannot use {str(self.path)!r}: {err.strerror or err}")

    def _claim(self) -> None:
        try:
            info = refuse_special(self.path, self.field)
            if info is not None and not stat.S_ISDIR(info.st_mode):
                raise InputError(self.field, f"cannot use {str(self.path)!r}: it is a file, not a folder")
            if info is None:
                self.path.mkdir(parents=True)
                self.created = True
        except FileExistsError:
            return self._claim()            # created meanwhile by another run: look again
        except OSError as err:
            raise self._fail(err) from None
        try:
            self._lock()
        except BaseException:
            if self.created:                # a folder this run made and could not lock (a full disk): not left behind
                with contextlib.suppress(OSError):
                    self.path.rmdir()
            raise
        clean_temporaries(self.path)

    def _lock(self) -> None:
        lock = self.path / LOCK_NAME
        for _ in range(5):
            try:
                fd = os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                pid = self._lock_owner(lock)
                if pid is None or pid_alive(pid):
                    raise self._busy(pid) from None
                self._take_over(lock, pid)
                continue
            except OSError as err:
                raise self._fail(err) from None
            try:
                os.write(fd, f"{os.getpid()}\n".encode())
            except OSError as err:          # a full disk: no lock of ours stays behind (it would look busy), exit 2
                os.close(fd)
                with contextlib.suppress(OSError):
                    os.unlink(lock)
                raise self._fail(err) from None
            os.close(fd)
            self.locked = True
            return
        raise FolderBusyError(self.field, f"{str(self.path)!r}: its lock changes hands too often; try again")

    def _busy(self, pid: int | None) -> FolderBusyError:
        who = f"pid {pid}" if pid is not None else "a process that is starting"
        return FolderBusyError(self.field, f"{str(self.path)!r} is being written by another run ({who}); wait "
                                           "for it or choose another folder")

    def _take_over(self, lock: Path, dead: int) -> None:
        """Remove a stale lock of the dead pid ``dead``. It is first renamed aside (one rename wins), then
        read again: if another run replaced the stale lock meanwhile, its fresh lock is put back and this
        run refuses, so two runs that found the same stale lock cannot both take the folder."""
        aside = self.path / f"{TEMP_PREFIX}{os.getpid()}-{secrets.token_hex(4)}-lock"
        try:
            os.rename(lock, aside)
        except FileNotFoundError:        # another run moved it first: try to create ours again
            return
        except OSError as err:
            raise self._fail(err) from None
        owner = self._lock_owner(aside)
        if owner == dead or (owner is not None and not pid_alive(owner)):
            os.unlink(aside)
            return
        try:
            os.link(aside, lock)            # a live run's lock: back under its name (unless a third run's is there)
        except OSError:
            pass
        finally:
            os.unlink(aside)
        raise self._busy(owner)

    @staticmethod
    def _lock_owner(lock: Path) -> int | None:
        """The pid in a lock; None while its writer has not written it yet (then it is young)."""
        try:
            text = lock.read_text(encoding="ascii", errors="replace").split("\n", 1)[0].strip()
            age = time.time() - lock.stat().st_mtime
        except OSError:
            return None
        if text.isdigit():
            return int(text)
        return None if age < 5 else 0        # an empty lock older than 5 s: its writer died (pid 0 is dead)

    def _check_owner(self) -> None:
        manifest = read_manifest(self.path)
        entries = {f["name"]: f for f in manifest["files"]} if manifest else {}
        ours = {LOCK_NAME, MANIFEST_NAME} if manifest else {LOCK_NAME}
        try:
            present = [name for name in os.listdir(self.path) if name not in ours and not name.startswith(TEMP_PREFIX)]
            written = (self.path / MANIFEST_NAME).stat().st_mtime if manifest else 0.0
        except OSError as err:
            raise self._fail(err) from None
        foreign = sorted(name for name in present if name not in entries)
        verified = {name: self._verified(entries[name], written) for name in present if name in entries}
        changed = sorted(name for name, entry in verified.items() if entry is None)
        if manifest is not None and "digest" in manifest and manifest["digest"] != manifest_digest(manifest):
            changed.append(MANIFEST_NAME)   # edited by hand (a manifest without a digest is an earlier version's)
        if (foreign or changed) and not self.force:
            if foreign:
                names = foreign
                what = "no manifest of packetloss-cvx lists" if manifest else \
                    "it holds files packetloss-cvx did not write:"
            else:
                what, names = "files changed since packetloss-cvx wrote them:", changed
            shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
            raise OutputExistsError(self.field, f"refusing to write into {str(self.path)!r}: {what} {shown}; "
                                                "pass --force to write there anyway")
        self.previous = sorted(name for name in present if name in entries and name not in changed)
        if (self.previous and not self.force and manifest is not None and manifest.get("complete") is True
                and not same_command(manifest.get("command"), self.command)):
            shown = ", ".join(self.previous[:3]) + (f" and {len(self.previous) - 3} more"
                                                    if len(self.previous) > 3 else "")
            raise OutputExistsError(self.field, f"refusing to replace the run in {str(self.path)!r} written by "
                                                f"`{printable(str(manifest.get('command')))[:200]}` ({shown}): a "
                                                "different command; pass --force to replace it, or choose another "
                                                "folder")
        self.carried = {name: verified[name] for name in self.previous}    # listed by this run's unfinished manifest

    def _verified(self, entry: dict[str, Any], written: float) -> dict[str, Any] | None:
        """The file a manifest entry names, as an entry with its size and sha256, if it is the package's: the one the
        entry describes (its size and sha256), or, where the entry has no hash (the file an unfinished run was
        writing when it stopped) or marks the file as being rewritten (``"writing"``), a file not older than the
        manifest (``written``, its mtime): it appeared after the run listed it. None for a file edited since, one
        older than an entry without a hash (a user's file the list names), or a folder. O(size of the file)."""
        path, hashed = self.path / entry["name"], "sha256" in entry
        try:
            if not path.is_file():
                return None
            info = path.stat()
            if hashed and info.st_size == entry.get("bytes", info.st_size):
                now = self._entry(entry["name"])
                if now["sha256"] == entry["sha256"]:
                    return now
            if (not hashed or entry.get("writing") is True) and info.st_mtime >= written:
                return self._entry(entry["name"])
        except OSError:
            pass
        return None

    def _entry(self, name: str) -> dict[str, Any]:
        """The manifest entry of the file ``name`` as it is now: its size and sha256. O(size of the file)."""
        path = self.path / name
        return {"name": name, "bytes": path.stat().st_size, "sha256": file_digest(path)}

    # -- writing ----------------------------------------------------------------------------------------
    def _manifest(self, complete: bool) -> dict[str, Any]:
        data: dict[str, Any] = {"packetloss_cvx": _version(), "command": self.command, "complete": complete,
                                "written": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")}
        if complete:
            data["files"] = [self.done.get(name) or self._entry(name) for name in self.written]
        else:
            files = []
            for name in sorted(set(self.previous) | set(self.written)):
                if name in self.done:                   # finished by this run
                    files.append(self.done[name])
                elif name in self.carried:              # the previous run's, perhaps being rewritten now
                    files.append({**self.carried[name], "writing": name in self.written})
                else:                                   # in flight: its content is not known yet
                    files.append({"name": name})
            data["files"] = files
            data["note"] = "a run that did not finish: these files may come from different runs"
        data["digest"] = manifest_digest(data)
        return data

    def _write_manifest(self, complete: bool) -> None:
        text = json.dumps(self._manifest(complete), indent=1) + "\n"
        with atomic_write(self.path / MANIFEST_NAME, overwrite=True, text=True, field=self.field) as handle:
            handle.write(text)

    def write(self, name: str, *, text: bool = False) -> contextlib.AbstractContextManager[IO[Any]]:
        """An `atomic_write` handle for ``name`` in the folder (replacing the previous run's file).
        The name is listed in the (incomplete) manifest before the file appears."""
        if not self.locked:
            raise RuntimeError("RunFolder.write outside its with block")
        if name in (MANIFEST_NAME, LOCK_NAME) or name.startswith(TEMP_PREFIX) or Path(name).name != name:
            raise InputError(self.field, f"{name!r} is not a file name this folder can hold")
        if name not in self.written:
            self.written.append(name)
        self.done.pop(name, None)
        self._write_manifest(complete=False)
        self.marked = True
        return self._writing(name, text)

    @contextlib.contextmanager
    def _writing(self, name: str, text: bool) -> Iterator[IO[Any]]:
        """`atomic_write` of ``name``; once it is in place, its size and sha256 go into the unfinished manifest
        (an edit after an interrupted run is then seen). O(size) to hash."""
        with atomic_write(self.path / name, overwrite=True, text=text, field=self.field) as handle:
            yield handle
        try:
            self.done[name] = self._entry(name)
        except OSError as err:
            raise self._fail(err) from None
        self._write_manifest(complete=False)

    # -- leaving ----------------------------------------------------------------------------------------
    def __exit__(self, kind: type[BaseException] | None, *rest: object) -> None:
        try:
            if kind is None:
                self._commit()
            elif self.created and not self.written:      # nothing written into a folder this run made
                self._release()
                with contextlib.suppress(OSError):
                    self.path.rmdir()
        finally:
            self._release()

    def _commit(self) -> None:
        if not self.written and not self.previous and self.created:
            return                                        # nothing to list
        for name in self.previous:
            if name not in self.written:                  # the previous run's: stale beside this one
                with contextlib.suppress(FileNotFoundError):
                    try:
                        os.unlink(self.path / name)
                    except IsADirectoryError:
                        pass
        self._write_manifest(complete=True)

    def _release(self) -> None:
        if self.locked:
            with contextlib.suppress(OSError):
                os.unlink(self.path / LOCK_NAME)
            self.locked = False


def _version() -> str:
    """The package's version: its ``__init__`` ran before any of its modules (no upward import)."""
    return str(getattr(sys.modules[__package__], "__version__", "unknown"))
