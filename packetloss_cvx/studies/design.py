"""Design studies: `J*_tcp`, `J*_udp` and J_Delta over many channels, initial states or horizons.

[`sweep`][packetloss_cvx.studies.design.sweep] evaluates one of

* a grid of channel values on [0, 1]: one channel (the others as in the system), every
  actuator behind one shared channel, or both channels of a two-channel system (2-D);
* a list of m-channel points (e.g. read from a CSV file with
[`read_mu_list`][packetloss_cvx.studies.design.read_mu_list]);
* a grid over one scale of the initial state (x0 times each scale);
* a list of horizons N,

in chunks of consecutive points, each chunk one batched evaluation, in this process or on a
Dask cluster ([`.engine`][packetloss_cvx.studies.engine]); both give the same numbers bit for bit. The result is a
`DesignSweep` (``to_xarray()``, saved by [`.output.save_sweep`][packetloss_cvx.studies.output.save_sweep]).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..budgets import BUDGETS, check, count_text, estimated_seconds, sweep_work
from ..errors import InputError
from ..model.files import read_csv_rows
from ..model.protocols import PROTOCOLS, check_protocol
from ..model.system import System, numeric_array
from ..model.validation import MAX_ENTRIES, channel_range
from ..results import DesignSweep
from .engine import DEFAULT_CHUNK, chunks, run_in_process, run_on_dask

__all__ = ["MAX_SWEEP_POINTS", "read_mu_list", "sweep"]

#: The most points one sweep evaluates by default (a 1000 x 1000 grid): the ``sweep_points`` budget
#: (budgets.py; ``PACKETLOSS_CVX_BUDGET_SWEEP_POINTS`` raises it).
MAX_SWEEP_POINTS = int(BUDGETS["sweep_points"].default)

#: the argument that asks for each kind of sweep (a budget's refusal names it)
KIND_FIELDS = {"mu-grid": "mu_grid", "mu-list": "mu_list", "x0-scale": "x0_scales", "horizon": "horizons"}


def _count(value: Any, field: str, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise InputError(field, f"expected an integer >= {least}, found {value!r}")
    return int(value)


def _grid_axis(mu_grid: Any) -> np.ndarray:
    if isinstance(mu_grid, (int, np.integer)) and not isinstance(mu_grid, bool):
        count = _count(mu_grid, "mu_grid", 2)
        check("sweep_points", count, "mu_grid", f"{count_text(count)} points per channel")   # before linspace allocates
        return np.linspace(0.0, 1.0, count)
    axis = numeric_array(mu_grid, "mu_grid")
    if axis.ndim != 1 or axis.size < 1 or np.any(axis < 0) or np.any(axis > 1):
        raise InputError("mu_grid", "expected a point count K >= 2 or a list of probabilities in [0, 1]")
    return axis


def read_mu_list(path: str | Path, m: int) -> np.ndarray:
    """Channel points from a CSV file: one row per point, m probabilities per row, read by the one CSV reader
    (`read_csv_rows`: a header row, ``#`` comments and a byte-order mark skipped;
    a regular file within the ``file_bytes`` budget, a FIFO or /dev/zero refused before it is read). O(rows).

    Raises
    ------
    InputError
        A file that cannot be read, a row of the wrong length, or a value outside [0, 1]
        (field ``mu_list``, with its line in the file).
    BudgetError
        A file beyond the ``file_bytes`` budget, or more rows than the ``sweep_points`` budget.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _ = (Path(tmp) / "mu.csv").write_text("mu1,mu2\\n0.5,1\\n0,0.25\\n")
    ...     points = read_mu_list(Path(tmp) / "mu.csv", 2)
    ...     read_mu_list(Path(tmp) / "mu.csv", 3)
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: mu_list: line 2: expected 3 numbers, found 2
    >>> points.tolist()                             # the header row is skipped
    [[0.5, 1.0], [0.0, 0.25]]
    """
    csv = read_csv_rows(path, "mu_list", row_budget="sweep_points", width=m)
    return _mu_points(csv.rows, csv.where)


def _mu_points(points: Any, where: Callable[[int], str] | None = None) -> np.ndarray:
    """The points as an array; ``where(k)`` names row k (0-based) in an error (a file's line), else ``row k + 1``."""
    arr = numeric_array(points, "mu_list")
    if arr.ndim != 2 or arr.shape[0] < 1:
        raise InputError("mu_list", f"expected rows of m probabilities, found shape {arr.shape}")
    bad = np.flatnonzero(np.any((arr < 0) | (arr > 1), axis=1))
    if bad.size:
        row = f"row {bad[0] + 1}" if where is None else where(int(bad[0]))
        raise InputError("mu_list", f"{row}: expected probabilities in [0, 1]")
    return arr


def _plan(system: System, mu_grid, channel, shared, mu_list, x0_scales, horizons):
    """(kind, dims, axes, mu (points, m)) of the one sweep asked for."""
    given = [k for k, v in (("mu_grid", mu_grid), ("mu_list", mu_list), ("x0_scales", x0_scales),
                            ("horizons", horizons)) if v is not None]
    if len(given) != 1:
        raise InputError("sweep", f"expected exactly one of mu_grid, mu_list, x0_scales, horizons; found {given}")
    kind = given[0]
    if kind != "mu_grid" and (channel is not None or shared):
        raise InputError("channel" if channel is not None else "shared", "channel and shared apply to mu_grid only")
    if kind == "mu_list":
        mu = _mu_points(mu_list)
        if mu.shape[1] != system.m:
            raise InputError("mu_list", f"expected {system.m} probabilities per row, found {mu.shape[1]}")
        return "mu-list", ("point",), (np.arange(len(mu)),), mu
    if kind != "mu_grid":
        return kind, (), (), None
    axis = _grid_axis(mu_grid)
    if shared and channel is not None:
        raise InputError("channel", "give either channel or shared, not both")
    if shared or system.m == 1:
        return "mu-grid", ("nu",), (axis,), np.repeat(axis[:, None], system.m, axis=1)
    if channel is not None:
        i = _count(channel, "channel", 0)
        if i >= system.m:
            raise InputError("channel", f"expected {channel_range(system.m)}, found {i}")
        mu = np.repeat(_base_mu(system)[None], axis.size, axis=0)
        mu[:, i] = axis
        return "mu-grid", (f"mu{i + 1}",), (axis,), mu
    if system.m != 2:
        raise InputError("mu_grid", f"a grid over every channel needs m <= 2 (found m = {system.m}): "
                                    "give channel= or --channel I (one channel), or shared=True or --shared "
                                    "(every actuator behind one channel)")
    check("sweep_points", axis.size ** 2, "mu_grid",       # before meshgrid allocates K^2 points
          f"a 2-D grid of {axis.size} x {axis.size} points")
    mu1, mu2 = np.meshgrid(axis, axis)          # rows follow mu2, columns mu1
    return "mu-grid", ("mu2", "mu1"), (axis, axis), np.column_stack([mu1.ravel(), mu2.ravel()])


def _base_mu(system: System) -> np.ndarray:
    if not system.is_stationary:
        raise InputError("system", "this sweep needs a stationary channel (mu, not mu_schedule)")
    return np.array(system.mu_schedule[0], dtype=float)


def _scales(values: Any) -> np.ndarray:
    arr = numeric_array(values, "x0_scales")
    check("sweep_points", arr.size, "x0_scales", f"{arr.size} scales")
    if arr.ndim != 1 or arr.size < 1:
        raise InputError("x0_scales", f"expected a non-empty list of numbers, found shape {arr.shape}")
    return arr


def _horizons(system: System, values: Any) -> np.ndarray:
    arr = numeric_array(values, "horizons")
    check("sweep_points", arr.size, "horizons", f"{arr.size} horizons")
    if arr.ndim != 1 or arr.size < 1 or np.any(arr < 1) or np.any(arr != np.round(arr)):
        raise InputError("horizons", "expected a non-empty list of integers >= 1")
    limit = MAX_ENTRIES // max(system.n ** 2, system.m)    # the System's own bound (model), checked up front
    if np.any(arr > limit):   # before astype(int), which wraps 1e20 to a negative number
        raise InputError("horizons", f"expected horizons of at most {limit} for n = {system.n}, m = {system.m} "
                                     f"(what fits in memory), found {arr.max():.6g}")
    same = all(np.array_equal(w, system.state_weights[0]) for w in system.state_weights) and all(
        np.array_equal(w, system.input_weights[0]) for w in system.input_weights)
    if not same:
        raise InputError("horizons", "a horizon sweep needs the same weights at every step")
    _base_mu(system)
    return arr.astype(int)


def _difference(costs: dict[str, np.ndarray], mu: np.ndarray) -> np.ndarray:
    """`J*_udp` - `J*_tcp`, exactly 0 where every channel is deterministic (each mu_i in {0, 1}: the UDP-like
    term U' Vbar Omega_d (I - Vbar) U vanishes and the two problems are the same; their two evaluations
    would differ by rounding, about 1e-15 `J*`, and could make the difference negative). O(points m)."""
    diff = costs["udp"] - costs["tcp"]
    diff[np.all((mu == 0) | (mu == 1), axis=1)] = 0.0
    return diff


def sweep(system: System, *, mu_grid: int | Sequence[float] | None = None, channel: int | None = None,
          shared: bool = False, mu_list: Any = None, x0_scales: Sequence[float] | None = None,
          horizons: Sequence[int] | None = None, protocols: Sequence[str] = PROTOCOLS,
          chunk_size: int = DEFAULT_CHUNK, dask: Any = None, workers: int | None = None,
          stability: bool = False, progress: bool | None = None) -> DesignSweep:
    """`J*_tcp`, `J*_udp` and J_Delta = `J*_udp` - `J*_tcp` over one design study.

    Parameters
    ----------
    system : System
        Everything not swept is taken from it.
    mu_grid : int or sequence of float
        K points per channel on [0, 1] (``linspace(0, 1, K)``) or the grid's values: over the one
        channel of a single-channel system, over ``channel`` (0-based; the others as in the system),
        over one channel shared by every actuator (``shared=True``), or over [0, 1]^2 for m = 2
        (dims ``("mu2", "mu1")``: rows follow mu2).
    mu_list : array_like, shape (points, m)
        Channel points (see [`read_mu_list`][packetloss_cvx.studies.design.read_mu_list]).
    x0_scales : sequence of float
        The initial state ``scale * system.x0`` for each scale.
    horizons : sequence of int
        Each horizon N (the system's weights must be the same at every step).
    protocols : sequence of {"tcp", "udp"}
        Both by default (then ``difference`` is `J*_udp` - `J*_tcp`).
    chunk_size : int
        Points per batched evaluation (and per Dask task).
    dask : None, "local", a scheduler address ("tcp://host:8786") or a distributed.Client
        Where to evaluate the chunks; None: in this process. Same numbers either way.
    workers : int, optional
        Workers of ``dask="local"`` (default 2).
    stability : bool
        Also each protocol's receding-horizon law's mean-square spectral radius at each point (its
        closed loop over the point's channel is mean-square stable iff the radius < 1).
    progress : bool or None
        A progress bar on stderr (None: when stderr is a terminal).

    Returns
    -------
    DesignSweep

    Raises
    ------
    InputError
        Bad arguments (the field named), a non-stationary channel for a sweep that keeps the channel,
        per-step weights for a horizon sweep, or a Markov (Gilbert-Elliott) channel, which this
        Bernoulli evaluator does not model.
    BudgetError
        More points than the ``sweep_points`` budget, or more work than ``sweep_work``
        (`sweep_work`), refused before any point is evaluated and named by
        the argument that asked for them.

    Notes
    -----
    O(points N (n^3 + m^3)) over the design's points, plus O(points n^6) with ``stability``; memory
    O(points (m + n)).

    Examples
    --------
    >>> from packetloss_cvx.model.files import load_example
    >>> result = sweep(load_example("two_actuator"), mu_grid=3)
    >>> result.dims, result.shape, result.mu.shape
    (('mu2', 'mu1'), (3, 3), (9, 2))
    >>> bool(np.all(result.difference >= 0))            # Theorem 2
    True
    """
    if getattr(system, "channel", None) is not None:
        raise InputError("system", "it has a Gilbert-Elliott (Markov) channel; sweep evaluates independent "
                                   "Bernoulli channels (packetloss_cvx.studies.burstiness.burstiness_sweep sweeps "
                                   "burstiness)")
    protocols = tuple(dict.fromkeys(check_protocol(p, "protocols") for p in protocols))
    if not protocols:
        raise InputError("protocols", "expected at least one of 'tcp', 'udp'")
    size = _count(chunk_size, "chunk_size", 1)
    if workers is not None and dask is None:
        raise InputError("workers", "applies to dask='local' only (without dask the sweep runs in this process)")
    kind, dims, axes, mu = _plan(system, mu_grid, channel, shared, mu_list, x0_scales, horizons)
    base_mu = _base_mu(system) if mu is None else None
    if kind == "x0_scales":
        scales = _scales(x0_scales)
        kind, dims, axes = "x0-scale", ("x0_scale",), (scales,)
        x0 = scales[:, None] * np.asarray(system.x0)[None]
        horizon = np.full(scales.size, system.horizon)
    elif kind == "horizons":
        hs = _horizons(system, horizons)
        kind, dims, axes = "horizon", ("horizon",), (hs,)
        x0 = np.repeat(np.asarray(system.x0)[None], hs.size, axis=0)
        horizon = hs
    if mu is None:
        mu = np.repeat(base_mu[None], len(axes[0]), axis=0)
    else:
        x0 = np.repeat(np.asarray(system.x0)[None], len(mu), axis=0)
        horizon = np.full(len(mu), system.horizon)
        if not system.is_stationary:
            raise InputError("system", "a channel sweep replaces the channel: give a stationary mu")
    field = KIND_FIELDS[kind]
    check("sweep_points", len(mu), field, f"{len(mu)} points")
    cost = sweep_work(horizon.tolist(), system.n, system.m, len(protocols), stability, size)
    check("sweep_work", cost, field, f"{len(mu)} points of horizon up to {int(horizon.max())} "
                                     f"(n = {system.n}, m = {system.m})")
    work = chunks(mu, x0, horizon, size)
    data = system.to_dict()
    if dask is None:
        columns = run_in_process(data, protocols, work, progress, stability, estimated_seconds("sweep_work", cost))
    else:
        columns = run_on_dask(data, protocols, work, dask, workers, progress, stability,
                              estimated_seconds("sweep_work", cost))
    costs = {p: columns[f"cost_{p}"] for p in protocols}
    radii = {p: columns[f"radius_{p}"] for p in protocols} if stability else {}
    difference = _difference(costs, mu) if set(protocols) == set(PROTOCOLS) else None
    return DesignSweep(kind=kind, dims=dims, axes=axes, mu=mu, x0=x0, horizon=horizon, costs=costs,
                       difference=difference, name=system.name, chunk_size=size, radii=radii)
