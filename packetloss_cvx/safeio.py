"""Files written safely: every file the package writes appears complete or not at all.

Every file the package writes goes through `atomic_write`: a temporary file in the target's
folder (named ``.packetloss-cvx-tmp-<pid>-<random>-<name>``), flushed and fsynced, then renamed onto
the final name, so a reader, an interrupt, a full disk or a ``kill -9`` sees the previous file or the
complete new one, never a truncated one (the technique of SQLite's and git's writes). On any error the
temporary file is removed; after a ``kill -9`` the next write into that folder removes it (its pid is
dead).

A single output FILE that exists is refused ([`OutputExistsError`][packetloss_cvx.errors.OutputExistsError]) unless
``overwrite=True`` (``--force``); the refusal is checked before the work (`check_output_file`) and
again at the rename (``os.link`` publishes without replacing, so two writers cannot both win). FIFOs,
devices and sockets are refused as outputs: they would block or never be a file. Output folders (a lock,
a manifest, the previous run replaced as a whole) are `packetloss_cvx.runfolder`'s; the one rule for
both is docs/design.md §4, "Files and runs".
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import secrets
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from .errors import InputError, OutputExistsError

__all__ = ["FIGURE_DPI", "TEMP_PREFIX", "atomic_write", "check_dpi", "check_flag", "check_output_file",
           "clean_temporaries", "exists_text", "figure_path", "file_digest", "laid_out_once", "pid_alive",
           "refuse_folder_name", "refuse_special", "save_figure"]

#: the recognisable start of every temporary file (``<prefix><pid>-<random>-<name>``)
TEMP_PREFIX = ".packetloss-cvx-tmp-"
#: the part of a final name kept in its temporary name (NAME_MAX is 255 bytes on most file systems)
_NAME_KEPT = 80


def refuse_special(path: Path, field: str) -> os.stat_result | None:
    """``path``'s stat if it exists (following links), after refusing FIFOs, devices and sockets. O(1).

    >>> refuse_special(Path("/no-such-file"), "--out") is None
    True
    >>> refuse_special(Path("/dev/zero"), "--out")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --out: cannot write '/dev/zero': not a regular file (a FIFO, device or socket)
    """
    try:
        info = path.stat()
    except FileNotFoundError:
        return None
    except OSError as err:
        raise InputError(field, f"cannot write {str(path)!r}: {err.strerror or err}") from None
    if stat.S_ISFIFO(info.st_mode) or stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode) or \
            stat.S_ISSOCK(info.st_mode):
        raise InputError(field, f"cannot write {str(path)!r}: not a regular file (a FIFO, device or socket)")
    return info


def check_flag(value: Any, field: str) -> bool:
    """``value`` if it is ``True`` or ``False`` (a NumPy bool too), else an InputError naming ``field``: leave to
    replace a user's file is given by ``True``, never by any truthy value (``overwrite="no"`` replaced the file). O(1).

    Examples
    --------
    >>> check_flag(True, "overwrite")
    True
    >>> check_flag("no", "overwrite")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: overwrite: expected True or False, found 'no'
    """
    if not (isinstance(value, bool) or type(value).__name__ == "bool_"):    # numpy.bool_, without importing NumPy
        raise InputError(field, f"expected True or False, found {value!r:.40}")
    return bool(value)


def refuse_folder_name(path: str | Path, field: str) -> None:
    """Refuse a FILE path that ends in '/': the user names a folder (``Path`` drops the slash, and ``--out newdir/``
    wrote a file named newdir). O(1).

    >>> refuse_folder_name("runs/", "--out")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --out: cannot write 'runs/': it names a folder (a trailing '/'); give a FILE, \
e.g. 'runs/result.json'
    """
    if isinstance(path, str) and path.endswith(("/", os.sep)):
        raise InputError(field, f"cannot write {path!r}: it names a folder (a trailing '/'); give a FILE, e.g. "
                                f"{path.rstrip('/' + os.sep) + '/result.json'!r}")


def check_output_file(path: str | Path, field: str, overwrite: bool = False) -> None:
    """Refuse, before any work, a FILE that cannot become a regular file here: a directory, a FIFO or device,
    a missing or unwritable folder, an existing file without ``overwrite``. Nothing is created. O(1).

    Examples
    --------
    >>> check_output_file("/dev/null", "--out")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --out: cannot write '/dev/null': not a regular file (a FIFO, device or socket)
    >>> check_output_file("/no-such-directory/out.json", "--out")
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.InputError: --out: cannot write '/no-such-directory/out.json': no such directory
    """
    target = Path(path)
    if not str(path).strip():
        raise InputError(field, "expected a file name, found an empty path")
    refuse_folder_name(path, field)
    folder = target.parent
    try:
        info = refuse_special(target, field)
        folder_ok = folder.is_dir()
    except OSError as err:       # e.g. a name too long for the file system
        raise InputError(field, f"cannot write {str(path)[:80]!r}: {err.strerror or err}") from None
    if info is not None and stat.S_ISDIR(info.st_mode):
        reason = "it is a directory"
    elif not folder_ok:
        reason = "no such directory"
    elif not os.access(folder, os.W_OK | os.X_OK):
        reason = "permission denied"
    elif info is not None and not overwrite:
        raise OutputExistsError(field, exists_text(path, field))
    else:
        return
    raise InputError(field, f"cannot write {str(path)!r}: {reason}")


def pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (on this machine); O(1).

    >>> pid_alive(os.getpid()), pid_alive(0), pid_alive(2**40)
    (True, False, False)
    """
    if pid <= 0:                 # os.kill(0, ...) would signal our own process group
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:      # another user's live process
        return True
    except (OverflowError, ValueError):
        return False
    return True


def clean_temporaries(folder: str | Path) -> list[str]:
    """Remove the temporary files of dead processes (a ``kill -9`` in mid-write) from ``folder``;
    returns their names. O(entries of the folder).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _ = (Path(tmp) / f"{TEMP_PREFIX}999999999-ab12-sweep.npz").write_bytes(b"partial")
    ...     _ = (Path(tmp) / f"{TEMP_PREFIX}{os.getpid()}-cd34-live.npz").write_bytes(b"mine")
    ...     clean_temporaries(tmp), sorted(p.name.split("-")[-1] for p in Path(tmp).iterdir())
    (['.packetloss-cvx-tmp-999999999-ab12-sweep.npz'], ['live.npz'])
    """
    removed = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in names:
        if not name.startswith(TEMP_PREFIX):
            continue
        pid = name[len(TEMP_PREFIX):].split("-", 1)[0]
        if pid.isdigit() and pid_alive(int(pid)):
            continue
        with contextlib.suppress(OSError):
            os.unlink(os.path.join(folder, name))
            removed.append(name)
    return removed


def _fsync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):      # not every file system lets a folder be opened or synced
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def exists_text(path: str | Path, field: str) -> str:
    """The refusal of an existing output file, naming the way to replace it where ``field`` is: ``--force`` on the
    command line (a field that is a flag), ``overwrite=True`` in Python.

    >>> exists_text("a.json", "--out"), exists_text("a.toml", "path")
    ("'a.json' exists; pass --force to replace it", "'a.toml' exists; pass overwrite=True to replace it")
    """
    return f"{str(path)!r} exists; pass {'--force' if field.startswith('-') else 'overwrite=True'} to replace it"


def _publish(temp: Path, path: Path, overwrite: bool, field: str) -> None:
    """Rename ``temp`` onto ``path``: ``os.replace``, or without ``overwrite`` ``os.link`` (which fails on an
    existing name, so two writers cannot both publish) with ``os.replace`` after a check where the file
    system has no hard links."""
    if overwrite:
        os.replace(temp, path)
        return
    try:
        os.link(temp, path)
    except FileExistsError:
        raise OutputExistsError(field, exists_text(path, field)) from None
    except OSError as err:
        if err.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
            raise
        if os.path.lexists(path):
            raise OutputExistsError(field, exists_text(path, field)) from None
        os.replace(temp, path)
        return
    os.unlink(temp)


@contextlib.contextmanager
def atomic_write(path: str | Path, *, overwrite: bool = False, text: bool = False,
                 field: str = "path") -> Iterator[IO[Any]]:
    """A file object whose content appears at ``path`` only when the block ends without an error.

    The data go to a temporary file in ``path``'s folder; at the end of the block it is flushed, fsynced
    and renamed onto ``path`` (then the folder is fsynced). On any exception, including an interrupt,
    the temporary file is removed and ``path`` is untouched. Without ``overwrite`` an existing ``path`` is
    refused ([`OutputExistsError`][packetloss_cvx.errors.OutputExistsError]), before and at the rename. An
    `OSError` (disk full, permission) becomes an [`InputError`][packetloss_cvx.errors.InputError] naming
    ``field``. O(size written), plus one fsync.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     target = Path(tmp) / "data.txt"
    ...     with atomic_write(target, text=True) as handle:
    ...         _ = handle.write("first")
    ...     try:
    ...         with atomic_write(target, text=True, overwrite=True) as handle:
    ...             _ = handle.write("half of the sec")
    ...             raise RuntimeError("interrupted")
    ...     except RuntimeError:
    ...         pass
    ...     target.read_text(), [p.name for p in Path(tmp).iterdir()]      # the old file, no temporary
    ('first', ['data.txt'])
    """
    check_output_file(path, field, check_flag(overwrite, "overwrite"))      # the path as given: a trailing '/'
    path = Path(path)
    clean_temporaries(path.parent)
    temp = path.parent / f"{TEMP_PREFIX}{os.getpid()}-{secrets.token_hex(4)}-{path.name[-_NAME_KEPT:]}"
    try:
        fd = os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)   # the umask applies, as for open()
    except OSError as err:
        raise InputError(field, f"cannot write {str(path)!r}: {err.strerror or err}") from None
    try:
        with open(fd, "w" if text else "wb", **({"encoding": "utf-8", "newline": ""} if text else {})) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        _publish(temp, path, overwrite, field)
        _fsync_folder(path.parent)
    except OSError as err:
        with contextlib.suppress(OSError):
            os.unlink(temp)
        raise InputError(field, f"cannot write {str(path)!r}: {err.strerror or err}") from None
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temp)
        raise


def figure_path(path: str | Path) -> Path:
    """The file a figure saved to ``path`` lands in: ``path``, or with ``.png`` appended when it has no
    extension (as Matplotlib's savefig does). O(1).

    >>> figure_path("loop").name, figure_path("loop.svg").name
    ('loop.png', 'loop.svg')
    """
    path = Path(path)
    return path if path.suffix[1:] else path.with_name(path.name + ".png")


def save_figure(fig: Any, path: str | Path, *, overwrite: bool = False, field: str = "path",
                folder: Any = None, dpi: float | None = None) -> Path:
    """Save a Matplotlib figure atomically: the format follows the extension (none: PNG, and ``.png`` is
    appended, as ``savefig`` does); with ``folder`` (a `RunFolder`),
    ``path`` is a name in that folder; ``dpi`` (default `FIGURE_DPI`) the resolution of a raster format (and
    recorded in a PNG's header). A format
    Matplotlib cannot write is an [`InputError`][packetloss_cvx.errors.InputError] naming ``field``. Returns the
    path written. O(pixels).

    >>> import tempfile
    >>> from matplotlib.figure import Figure
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = save_figure(Figure(), Path(tmp) / "empty")
    ...     path.name, path.read_bytes()[:4]
    ('empty.png', b'\x89PNG')
    """
    check_flag(overwrite, "overwrite")
    refuse_folder_name(path, field)
    dpi = FIGURE_DPI if dpi is None else check_dpi(dpi, field="dpi")
    path = figure_path(path)
    fmt = path.suffix[1:].lower()
    target = folder.write(path.name) if folder is not None else atomic_write(path, overwrite=overwrite, field=field)
    with target as handle:
        try:
            with laid_out_once(fig, fmt, dpi):
                fig.savefig(handle, format=fmt, dpi=dpi)
        except ValueError as err:          # e.g. an extension Matplotlib cannot write
            raise InputError(field, str(err)) from None
    return folder.path / path.name if folder is not None else path


#: The resolution of every figure :func:`save_figure` writes unless told (dots per inch).
FIGURE_DPI = 120


def check_dpi(dpi: Any, field: str = "dpi") -> float:
    """A figure's resolution: a finite number of dots per inch in [10, 2400] (beyond, a figure of a few inches is
    either unreadable or hundreds of megabytes), else an InputError naming ``field``. O(1).

    >>> check_dpi(300), check_dpi("72.5")
    (300, 72.5)
    >>> check_dpi(0, "--dpi")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: --dpi: expected dots per inch in [10, 2400], found 0
    """
    try:
        value = float(dpi)
    except (TypeError, ValueError):
        value = float("nan")
    if isinstance(dpi, bool) or not 10.0 <= value <= 2400.0:
        raise InputError(field, f"expected dots per inch in [10, 2400], found {dpi!r}")
    return int(value) if value.is_integer() else value          # as savefig(dpi=120) writes it, byte for byte


@contextlib.contextmanager
def laid_out_once(fig: Any, fmt: str, dpi: float = FIGURE_DPI) -> Iterator[None]:
    """Within the block, a PNG of ``fig`` with a constrained layout is drawn once: the layout is run here on the
    Agg canvas at ``dpi`` (default `FIGURE_DPI`; the renderer savefig then draws with) and the figure left
    without a layout engine, so savefig skips its layout pass (a whole draw with rendering off, made only to run
    the engine) and draws once. The same bytes as a plain ``savefig(dpi=dpi)`` (tests/house/test_safeio.py), at
    one draw less per figure. Other formats, figures without a constrained layout, and rcParams that would put
    an engine back are left to savefig. The figure's canvas, dpi and engine are restored on exit.
    O(1) besides the layout.

    >>> from matplotlib.figure import Figure
    >>> fig = Figure(layout="constrained")
    >>> _ = fig.subplots()
    >>> with laid_out_once(fig, "png"):
    ...     print(fig.get_layout_engine(), fig.dpi)
    None 120
    >>> type(fig.get_layout_engine()).__name__, fig.dpi
    ('ConstrainedLayoutEngine', 100.0)
    """
    import matplotlib as mpl
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    engine = fig.get_layout_engine()
    if (fmt != "png" or not fig.axes or not isinstance(engine, ConstrainedLayoutEngine)     # savefig runs it only
            or mpl.rcParams["figure.autolayout"] or mpl.rcParams["figure.constrained_layout.use"]):  # with axes
        yield
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas, own_dpi = fig.canvas, fig.dpi
    try:
        FigureCanvasAgg(fig)
        fig.dpi = dpi
        engine.execute(fig)
        fig.set_layout_engine(None)
        yield
    finally:
        fig.set_layout_engine(engine)
        fig.dpi = own_dpi
        fig.set_canvas(canvas)


def file_digest(path: str | Path) -> str:
    """The sha256 of a file, hex; O(size).

    >>> import tempfile
    >>> with tempfile.NamedTemporaryFile() as f:
    ...     file_digest(f.name) == hashlib.sha256(b"").hexdigest()
    True
    """
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
