"""safeio: atomic writes, the refusal of existing files and special files, temporary files of dead runs.

References are the file system itself: what is on disk after each step (bytes, names, modes), read
back with plain ``open``/``os`` calls, never through the module under test."""

import errno
import os
import stat
import subprocess
import sys

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.errors import InputError, OutputExistsError
from packetloss_cvx.safeio import TEMP_PREFIX, atomic_write, check_output_file, clean_temporaries, save_figure


def _names(folder):
    return sorted(os.listdir(folder))


def test_atomic_write_publishes_the_whole_file_and_nothing_else(tmp_path):
    target = tmp_path / "a.bin"
    payload = bytes(range(256)) * 4096
    with atomic_write(target) as handle:
        handle.write(payload)
        assert not target.exists()                        # nothing under the final name while writing
        assert len([n for n in _names(tmp_path) if n.startswith(TEMP_PREFIX)]) == 1
    assert target.read_bytes() == payload
    assert _names(tmp_path) == ["a.bin"]


def test_an_error_mid_write_leaves_the_previous_file_and_no_temporary(tmp_path):
    target = tmp_path / "a.txt"
    target.write_text("previous")
    for error in (RuntimeError("boom"), KeyboardInterrupt()):
        with pytest.raises(type(error)), atomic_write(target, overwrite=True, text=True) as handle:  # noqa: PT012
            handle.write("new but partial")         # the write interrupted inside its block is what is tested
            raise error
        assert target.read_text() == "previous"
        assert _names(tmp_path) == ["a.txt"]


def test_an_existing_file_is_refused_before_and_at_the_rename(tmp_path):
    target = tmp_path / "user.json"
    target.write_text("the user's")
    with pytest.raises(OutputExistsError, match="exists; pass --force"):    # before the work
        check_output_file(target, "--out")
    check_output_file(target, "--out", overwrite=True)
    with pytest.raises(OutputExistsError, match="exists; pass overwrite=True"):
        with atomic_write(target, text=True) as handle:
            handle.write("x")
    # a file that appears while we write (another writer) is not replaced either: os.link refuses
    other = tmp_path / "race.json"
    with pytest.raises(OutputExistsError, match="race.json"):     # noqa: PT012 - the race happens inside the block
        with atomic_write(other, text=True) as handle:
            handle.write("ours")
            other.write_text("theirs")
    assert other.read_text() == "theirs"
    assert target.read_text() == "the user's"
    assert not [n for n in _names(tmp_path) if n.startswith(TEMP_PREFIX)]
    assert isinstance(OutputExistsError("f", "d"), ValueError)


def test_overwrite_replaces_and_keeps_the_umask_mode(tmp_path):
    target = tmp_path / "a.txt"
    target.write_text("old")
    with atomic_write(target, overwrite=True, text=True) as handle:
        handle.write("new")
    assert target.read_text() == "new"
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask        # as open() would, not mkstemp's 0600


def test_special_files_and_bad_folders_are_refused(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for path, pattern in ((fifo, "not a regular file"), ("/dev/null", "not a regular file"),
                          (tmp_path, "it is a directory"), (tmp_path / "no" / "x.json", "no such directory"),
                          ("", "empty path")):
        with pytest.raises(InputError, match=pattern):
            check_output_file(path, "--out", overwrite=True)
    with pytest.raises(InputError, match="--out"):      # a name longer than the file system allows
        with atomic_write(tmp_path / ("x" * 5000), field="--out") as handle:
            handle.write(b"x")


def test_a_write_error_becomes_one_input_error_and_leaves_nothing(tmp_path, monkeypatch):
    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(InputError, match="No space left on device") as err:
        with atomic_write(tmp_path / "a.bin", field="--save") as handle:
            handle.write(b"data")
    assert err.value.field == "--save"
    assert _names(tmp_path) == []


def test_clean_temporaries_removes_only_dead_processes_files(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True)
    pid = int(dead.stdout)        # a process that has exited (pids are not reused this fast)
    (tmp_path / f"{TEMP_PREFIX}{pid}-0000-sweep.npz").write_bytes(b"partial")
    (tmp_path / f"{TEMP_PREFIX}{os.getpid()}-0000-live.npz").write_bytes(b"in progress")
    (tmp_path / "sweep.npz").write_bytes(b"a user's")
    assert clean_temporaries(tmp_path) == [f"{TEMP_PREFIX}{pid}-0000-sweep.npz"]
    assert _names(tmp_path) == sorted([f"{TEMP_PREFIX}{os.getpid()}-0000-live.npz", "sweep.npz"])


def test_save_figure_writes_the_format_of_the_extension(tmp_path):
    from matplotlib.figure import Figure
    figure = Figure()
    figure.add_subplot().plot([0, 1], [1, 0])
    png = save_figure(figure, tmp_path / "f")                   # no extension: PNG, .png appended
    svg = save_figure(figure, tmp_path / "f.svg")
    assert png.name == "f.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in svg.read_bytes()[:400]
    with pytest.raises(OutputExistsError):
        save_figure(figure, tmp_path / "f.svg")
    with pytest.raises(InputError, match="--plot"):
        save_figure(figure, tmp_path / "f.pgn", field="--plot")
    with pytest.raises(OutputExistsError, match="f.png"):          # `f` lands in f.png, which exists
        save_figure(figure, tmp_path / "f")
    assert _names(tmp_path) == ["f.png", "f.svg"]


def _figures():
    """Constrained-layout figures of every kind reproduce saves (log axes, a log colour bar with contours, labels and
    paths, a legend beside the axes, a suptitle, mathtext), and one without a layout engine."""
    from matplotlib.figure import Figure

    from packetloss_cvx.plots import plot_ack_break_even, plot_cost_lines, plot_log_contour, plot_region

    rng = np.random.default_rng(5)
    axis = np.linspace(0.0, 1.0, 21)
    values = np.exp(4.0 * np.add.outer(1.0 - axis, 1.0 - axis)) + rng.uniform(0.0, 0.1, (21, 21))
    nu = np.geomspace(1e-4, 1.0, 30)
    plain = Figure()
    plain.add_subplot().plot([0, 1], [1, 0])
    return {
        "lines": plot_cost_lines(nu, {"tcp": 1.0 / nu, "udp": 2.0 / nu, "diff": 1.0 / nu}, xlabel=r"$\nu$",
                                 xscale="log", marker=0.01, marker_label=r"max at $\nu$ = 0.01", title="a\nb"),
        "contour": plot_log_contour(axis, axis, values, colorbar_label=r"$J^*$ (log scale)", levels=[5.0, 20.0],
                                    allocations={"beta = (1, 1)": [(0.2, 0.9), (0.5, 0.5)]}, marker=(0.3, 0.3),
                                    title="contour\nwith levels"),
        "region": plot_region(axis, values / values.max() * 2.0, {"dp": values < 10.0, "tcp": values < 5.0},
                              title="region"),
        "ack": plot_ack_break_even([2.0, 4.0, 8.0], [0.5, float("nan"), 1.5], title="ack"),
        "no engine": plain,
    }


def test_save_figure_writes_the_bytes_of_a_plain_savefig(tmp_path):
    """save_figure runs a constrained layout once (laid_out_once) instead of letting savefig draw twice: the PNG must
    be the one Matplotlib's own ``savefig(dpi=FIGURE_DPI)`` writes, byte for byte, for a fresh copy of each figure
    (a second save of one figure is no reference: clabel's inline labels cut the contours at the first draw), and the
    figure is left as it was (engine, dpi, canvas)."""
    import io

    from packetloss_cvx.safeio import FIGURE_DPI

    mine, theirs = _figures(), _figures()
    for name, fig in mine.items():
        engine, dpi, canvas = fig.get_layout_engine(), fig.dpi, fig.canvas
        path = save_figure(fig, tmp_path / name)
        reference = io.BytesIO()
        theirs[name].savefig(reference, format="png", dpi=FIGURE_DPI)
        assert path.read_bytes() == reference.getvalue(), name
        assert (fig.get_layout_engine(), fig.dpi, fig.canvas) == (engine, dpi, canvas), name


def test_save_system_refuses_an_existing_file_unless_overwrite(tmp_path):
    path = tmp_path / "plant.toml"
    path.write_text("# the user's notes")
    system = pl.load_example("two_actuator")
    with pytest.raises(OutputExistsError, match="plant.toml"):
        pl.save_system(system, path)
    assert path.read_text() == "# the user's notes"
    pl.save_system(system, path, overwrite=True)
    assert np.array_equal(pl.load_system(path).A, system.A)


def test_a_path_ending_in_a_slash_names_a_folder_not_a_file(tmp_path):
    """``save_system(s, "newdir/")`` (and ``--out newdir/``) wrote a FILE named newdir: a trailing '/' says the
    user means a folder, so a FILE write is refused (naming the path and an example) and nothing is created."""
    system = pl.load_example("two_actuator")
    for path in (f"{tmp_path}/newdir/", f"{tmp_path}/newdir//"):
        with pytest.raises(pl.InputError, match="names a folder") as info:
            pl.save_system(system, path)
        assert info.value.field == "path"
    assert list(tmp_path.iterdir()) == []


def test_python_is_told_overwrite_where_the_command_line_is_told_force(tmp_path):
    import packetloss_cvx as pl

    path = pl.save_system(pl.load_example("two_actuator"), tmp_path / "s.toml")
    with pytest.raises(OutputExistsError, match="pass overwrite=True to replace it"):
        pl.save_system(pl.load_example("two_actuator"), path)
    assert pl.save_system(pl.load_example("two_actuator"), path, overwrite=True) == path
