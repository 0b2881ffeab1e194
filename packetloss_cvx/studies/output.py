"""A design sweep on disk: ``sweep.npz`` (NumPy arrays), ``sweep.csv`` (one row per point) and,
on request, ``sweep.nc`` (NetCDF3 through xarray's scipy engine: no extra dependency)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..results import DesignSweep
from ..runfolder import RunFolder
from ..safeio import check_flag

__all__ = ["csv_header", "csv_number", "require_xarray", "save_sweep", "sweep_table", "write_sweep"]


def require_xarray() -> None:
    """Raise InputError (field ``netcdf``) unless xarray, the optional extra behind ``to_xarray`` and
    NetCDF output, can be imported; call it before a long sweep, not after. O(1) once imported.

    Examples
    --------
    >>> import sys
    >>> from unittest import mock
    >>> with mock.patch.dict(sys.modules, {"xarray": None}):       # as if the extra were not installed
    ...     require_xarray()
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: netcdf: needs the xarray extra: pip install 'packetloss-cvx[xarray]'
    """
    try:
        import xarray  # noqa: F401  lazy: the xarray extra
    except ImportError:
        raise InputError("netcdf", "needs the xarray extra: pip install 'packetloss-cvx[xarray]'") from None


def csv_number(value: float) -> str:
    """The shortest text that reads back as the same double (Python's repr), integers without
    ".0": a CSV of 0.3 says 0.3, not %.17g's 0.29999999999999999. O(1).

    Examples
    --------
    >>> [csv_number(v) for v in (0.3, 10.0, 1e-300, float("inf"), 0.1 + 0.2)]
    ['0.3', '10', '1e-300', 'inf', '0.30000000000000004']
    """
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def csv_header(result: DesignSweep) -> list[str]:
    """The CSV's columns: mu1..mum, x0_1..x0_n, horizon, then cost_tcp, cost_udp, cost_diff, radius_tcp,
    radius_udp (those computed).

    Examples
    --------
    >>> from packetloss_cvx.model.system import System
    >>> from packetloss_cvx.studies import sweep
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> csv_header(sweep(s, mu_grid=2)), csv_header(sweep(s, mu_grid=2, protocols=["udp"]))[-1]
    (['mu1', 'x0_1', 'horizon', 'cost_tcp', 'cost_udp', 'cost_diff'], 'cost_udp')
    """
    m, n = result.mu.shape[1], result.x0.shape[1]
    costs = [f"cost_{p}" for p in result.costs] + (["cost_diff"] if result.difference is not None else [])
    radii = [f"radius_{p}" for p in result.radii]
    return [f"mu{i + 1}" for i in range(m)] + [f"x0_{i + 1}" for i in range(n)] + ["horizon"] + costs + radii


def sweep_table(result: DesignSweep) -> np.ndarray:
    """One row per point, the columns of `csv_header` (mu, x0, horizon, costs, radii), as floats:
    the rows of ``sweep.csv`` and of ``sweep --json``'s ``table``. O(points (m + n)).

    Examples
    --------
    >>> from packetloss_cvx.model.system import System
    >>> from packetloss_cvx.studies import sweep
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> sweep_table(sweep(s, mu_grid=[0.0, 1.0])).tolist()   # mu, x0, N, J*_tcp, J*_udp, J_Delta; J* = 1/(1 + mu)
    [[0.0, 1.0, 1.0, 1.0, 1.0, 0.0], [1.0, 1.0, 1.0, 0.5, 0.5, 0.0]]
    """
    columns = [result.mu, result.x0, result.horizon[:, None]] + [v[:, None] for v in result.costs.values()]
    if result.difference is not None:
        columns.append(result.difference[:, None])
    columns += [v[:, None] for v in result.radii.values()]
    return np.hstack([np.asarray(c, dtype=float) for c in columns])


def save_sweep(result: DesignSweep, out: str | Path, netcdf: bool = False, *, overwrite: bool = False,
               command: str = "save_sweep") -> dict[str, Path]:
    """Write ``sweep.npz``, ``sweep.csv`` (and ``sweep.nc`` with ``netcdf=True``) into the folder ``out``,
    atomically, with its ``manifest.json`` (`RunFolder`: a folder holding
    files no manifest of this package lists is refused unless ``overwrite=True``; the package's own folder
    is replaced run for run, stale files removed). O(points (m + n)).

    Returns
    -------
    dict
        ``{"npz": path, "csv": path[, "netcdf": path]}``.

    Raises
    ------
    InputError
        ``out`` cannot be created or written (field ``out``); ``netcdf`` without xarray (field ``netcdf``);
        OutputExistsError: a folder with other files; FolderBusyError: another run is writing it.

    Examples
    --------
    >>> import tempfile
    >>> from packetloss_cvx.model.system import System
    >>> from packetloss_cvx.studies import sweep
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     paths = save_sweep(sweep(s, mu_grid=[0.0, 0.5]), tmp)
    ...     rows = paths["csv"].read_text().splitlines()
    ...     npz = dict(np.load(paths["npz"]))
    >>> last = [float(v) for v in rows[2].split(",")[-3:]]    # mu = 0.5: J*_tcp = 1/(1 + mu), J*_udp = 1 - mu/2
    >>> sorted(paths), rows[0], bool(np.allclose(last, [2 / 3, 0.75, 0.75 - 2 / 3]))
    (['csv', 'npz'], 'mu1,x0_1,horizon,cost_tcp,cost_udp,cost_diff', True)
    >>> last[0] == float(npz["cost_tcp"][1])            # 17 digits read back exactly
    True
    """
    if netcdf:
        require_xarray()        # before writing anything
    with RunFolder(out, command=command, force=check_flag(overwrite, "overwrite")) as folder:
        return write_sweep(result, folder, netcdf)


def write_sweep(result: DesignSweep, folder: RunFolder, netcdf: bool = False) -> dict[str, Path]:
    """[`save_sweep`][packetloss_cvx.studies.output.save_sweep]'s files written into an entered `RunFolder` (the
    command line's, which holds the figures too). Floats in the CSV are written with the shortest text
    that reads back exactly (`csv_number`); the CSV is streamed row by row. O(points (m + n)).

    Examples
    --------
    >>> import tempfile
    >>> from packetloss_cvx.model.system import System
    >>> from packetloss_cvx.studies import sweep
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> with tempfile.TemporaryDirectory() as tmp, RunFolder(Path(tmp) / "run", command="example") as folder:
    ...     paths = write_sweep(sweep(s, mu_grid=[0.0, 1.0]), folder)
    ...     with folder.write("note.txt", text=True) as handle:      # a file of the caller's, in the same run
    ...         _ = handle.write("two channels")
    >>> sorted(paths), folder.written
    (['csv', 'npz'], ['sweep.npz', 'sweep.csv', 'note.txt'])
    """
    paths = {"npz": folder.path / "sweep.npz", "csv": folder.path / "sweep.csv"}
    with folder.write("sweep.npz") as handle:
        np.savez(handle, dims=np.array(result.dims, dtype=str), **result.arrays())
    table = sweep_table(result)
    with folder.write("sweep.csv", text=True) as handle:
        writer = csv.writer(handle)
        writer.writerow(csv_header(result))
        writer.writerows([csv_number(v) for v in row] for row in table.tolist())   # streamed: no list of every row
    if netcdf:
        paths["netcdf"] = folder.path / "sweep.nc"
        data = result.to_xarray().to_netcdf(engine="scipy")     # bytes: NetCDF3 has no streaming writer
        with folder.write("sweep.nc") as handle:
            handle.write(bytes(data))
    return paths
