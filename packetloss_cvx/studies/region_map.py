"""Every law's stability region side by side: critical points along a ray and maps over two channels.

Laws: "dp" (the stabilisable set S itself, simulation.region), "tcp" and "udp" (the paper's
receding-horizon laws at the system's horizon, re-designed at each mu: ``closed_form(system.with_mu(mu),
p).gain``), and "fixed" (the DP gain designed once at the system's own channel, then run at every mu).
Each law's region lies inside S: a point where a law is proved stable and S is certified empty raises
CrossCheckError.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ..budgets import check
from ..closedloop.critical import critical_point, law_membership
from ..closedloop.moments import stationary_channel
from ..closedloop.region import LazyLmi, homogeneous_riccati
from ..closedloop.riccati import dp_riccati
from ..errors import CrossCheckError, InputError, NumericalError
from ..model.files import system_from_dict
from ..model.system import System
from ..model.validation import channel_range
from ..progress import progress_bar
from ..results.region import RegionMap
from ..studies.engine import dask_client
from ..tolerances import CRITICAL_MU_TOL

__all__ = ["LAWS", "REGION_TASK_POINTS", "grid_rows", "region_map"]

#: the laws a region map compares
LAWS = ("dp", "tcp", "udp", "fixed")
#: grid points per task (whole rows): a point costs about 5 ms for the four laws, so a task takes seconds,
#: well over a Dask task's overhead, and a 101 x 101 map makes 6 tasks
REGION_TASK_POINTS = 2048


def _law(system: System, name: str) -> str | np.ndarray:
    if name == "fixed":
        try:
            return dp_riccati(system).gain
        except NumericalError as err:
            raise NumericalError(f"law 'fixed' (the DP gain at the file's mu = {stationary_channel(system).tolist()}) "
                                 f"does not exist: {err}; give another --mu or leave 'fixed' out") from None
    if name not in ("dp", "tcp", "udp"):
        raise InputError("law", f"expected some of {', '.join(LAWS)}, found {name!r}")
    return name


def region_map(system: System, laws: tuple[str, ...] = LAWS, direction: npt.ArrayLike | None = None,
               grid: int | None = None, channels: tuple[int, int] = (0, 1), tol: float = CRITICAL_MU_TOL,
               progress: bool | None = False, dask: Any = None, workers: int | None = None) -> RegionMap:
    """Each law's critical point along ``mu = t * direction`` and, with ``grid``, its region over two channels.

    Time: per law O(log2(1 / tol)) memberships, plus K^2 per law on a grid.

    Parameters
    ----------
    system : System
    laws : tuple of str
        Of `LAWS`.
    direction : array_like, optional
        Nonnegative, not all zero (default: all ones).
    grid : int, optional
        K points per axis on [0, 1] for channels ``channels`` (the others at the system's mu).
    channels : (int, int)
        The two channels of the map (0-based); one-channel systems take no grid.
    tol : float
        Width of each critical bracket in t.
    progress : bool or None
        A progress bar over the grid's rows on stderr (None: when stderr is a terminal).
    dask : None, "local", a scheduler address or a distributed.Client
        Where the grid's rows run ([`dask_client`][packetloss_cvx.studies.engine.dask_client]; tasks of about
        ``REGION_TASK_POINTS`` points, `grid_rows`); the same numbers as in this process.
    workers : int, optional
        Workers of ``dask="local"``.

    Returns
    -------
    RegionMap
        ``critical`` per law (results.region.CriticalPoint); with a grid, ``stable`` (1, 0, nan where
        undecided) and ``radius`` per law, rows the second channel, columns the first. The "dp" radius is
        min_K rho(L_K) (the least any linear law reaches; < 1 iff mu is in S), the others their law's own.

    Raises
    ------
    InputError
        An unknown law, a bad direction, channels out of range or equal, a grid below 2, a Gilbert-Elliott
        or non-stationary channel (the Bernoulli region is not theirs: give ``system.with_mu(...)``).
    NumericalError
        "fixed" asked for where the file's mu has no DP law (outside S, or undecided).
    ResourceError
        (BudgetError) More law-points than the ``region_points`` budget (budgets.py).
    CrossCheckError
        A law proved stable where S is certified empty.

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> r = region_map(s, laws=("dp", "fixed"))   # DARE gain at mu = 1: k = 1.618, stable iff mu > 3 / (4k - k^2)
    >>> [round(p.t, 5) for p in r.critical]
    [0.75, 0.77839]
    """
    base = stationary_channel(system)   # a Gilbert-Elliott or non-stationary channel is refused (its own region)
    laws = tuple(laws)
    if not laws or any(name not in LAWS for name in laws):
        raise InputError("law", f"expected some of {', '.join(LAWS)}, found {list(laws)}")
    d = np.ones(system.m) if direction is None else np.asarray(direction, dtype=float).reshape(-1)
    if d.shape != (system.m,) or not np.all(np.isfinite(d)) or np.any(d < 0) or not np.any(d > 0):
        raise InputError("direction", f"expected {system.m} nonnegative numbers, not all zero")
    if grid is not None:
        _check_grid(system, grid, channels, len(laws))
    chosen = {name: _law(system, name) for name in laws}
    critical = tuple(critical_point(system, law, d, tol) for law in chosen.values())
    critical = tuple(type(p)(name, p.direction, p.t, p.lower, p.inside, p.outside)
                     for name, p in zip(laws, critical, strict=True))
    if grid is None:
        return RegionMap(laws, d, critical, None, (), None, None, None)
    i, j = (int(c) for c in channels)
    axis = np.linspace(0.0, 1.0, grid)
    fixed = chosen.get("fixed")
    size = max(1, REGION_TASK_POINTS // grid)
    work = [np.arange(k, min(k + size, grid)) for k in range(0, grid, size)]
    args = (system.to_dict(), laws, fixed, axis, (i, j), base)
    parts: list = [None] * len(work)
    with progress_bar(total=grid, desc="region map", progress=progress) as bar:
        if dask is None:
            if workers is not None:
                raise InputError("workers", "applies to dask='local' only (without dask the map runs in this process)")
            for k, rows in enumerate(work):
                parts[k] = grid_rows(*args, rows)
                bar.update(len(rows))
        else:
            with dask_client(dask, workers) as client:
                from distributed import as_completed  # lazy: the distributed extra (dask_client checked it)
                futures = [client.submit(grid_rows, *args, rows, pure=False) for rows in work]
                order = {f.key: k for k, f in enumerate(futures)}
                for future in as_completed(futures, loop=client.loop):
                    k = order[future.key]
                    parts[k] = future.result()      # a worker's error is raised here with its own type
                    bar.update(len(work[k]))
    stable = np.concatenate([p[0] for p in parts], axis=1)
    radius = np.concatenate([p[1] for p in parts], axis=1)
    return RegionMap(laws, d, critical, axis, (i, j), base, stable, radius)


def grid_rows(system_data: dict, laws: tuple[str, ...], fixed: np.ndarray | None, axis: np.ndarray,
              channels: tuple[int, int], base: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(stable, radius)`` of shape (laws, len(rows), K) for the map's rows ``rows`` (mu_J = axis[rows]): one
    task, in this process or on a Dask worker (the system rebuilt from ``System.to_dict()``, exact). The "dp"
    radius (the homogeneous Riccati eigenvalue) of all the task's points is one batch, whose eigenpairs the
    membership's "riccati" form checks as its own. Time O(len(rows) K) memberships.

    Examples
    --------
    >>> s = System(A=np.diag([2.0, 1.5]), B=np.eye(2), horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
    ...            mu=[1.0, 1.0], x0=[1.0, 1.0])
    >>> stable, radius = grid_rows(s.to_dict(), ("dp",), None, np.array([0.5, 1.0]), (0, 1), np.ones(2),
    ...                            np.array([1]))    # mu_2 = 1: stable iff mu_1 > 0.75
    >>> stable.tolist()
    [[[0.0, 1.0]]]
    """
    system = system_from_dict(system_data)
    chosen = {name: (fixed if name == "fixed" else name) for name in laws}
    i, j = channels
    stable = np.full((len(laws), len(rows), axis.size), np.nan)
    radius = np.full((len(laws), len(rows), axis.size), np.nan)
    lmi = LazyLmi(system.A, system.B)
    mus = np.repeat(np.asarray(base, dtype=float)[None], len(rows) * axis.size, axis=0)
    mus[:, i], mus[:, j] = np.tile(axis, len(rows)), np.repeat(axis[np.asarray(rows, dtype=int)], axis.size)
    # the homogeneous Riccati eigenpairs of every point in one batch: "dp"'s radius and its membership's first form
    pairs = _eigenpairs(np.asarray(system.A, float), np.asarray(system.B, float), mus) if "dp" in laws else None
    for g, mu in enumerate(mus):
        r, col = divmod(g, axis.size)
        pair = None if pairs is None else (float(pairs[0][g]), pairs[1][g], pairs[2][g])
        _fill(system, laws, chosen, mu, lmi, pair, stable[:, r, col], radius[:, r, col])
    return stable, radius


def _eigenpairs(A: np.ndarray, B: np.ndarray, mus: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """homogeneous_riccati of the batch; where a linear-algebra failure stops the batch (NumericalError), each point
    alone, a point that fails again getting a nan pair (its radius nan, its "riccati" form undecided)."""
    try:
        return homogeneous_riccati(A, B, mus)
    except NumericalError:
        n, m = B.shape
        lam, P, K = np.full(len(mus), np.nan), np.full((len(mus), n, n), np.nan), np.full((len(mus), m, n), np.nan)
        for g, mu in enumerate(mus):
            try:
                lam[g], P[g], K[g] = homogeneous_riccati(A, B, mu)
            except NumericalError:
                continue
        return lam, P, K


def _check_grid(system: System, grid: int, channels: tuple[int, int], laws: int) -> None:
    """Before any work: two channels, in range and different, K >= 2, law-points within the region_points budget."""
    if system.m < 2:
        raise InputError("grid", "a map needs two channels; this system has one (its critical points are the answer)")
    i, j = (int(c) for c in channels)
    if not (0 <= i < system.m and 0 <= j < system.m) or i == j:
        raise InputError("channels", f"expected two different channels, each {channel_range(system.m)}, found "
                                     f"{tuple(channels)!r}")
    if not (isinstance(grid, (int, np.integer)) and grid >= 2):
        raise InputError("grid", f"expected an integer >= 2, found {grid!r}")
    points = grid * grid * laws
    check("region_points", points, "grid", f"a {grid} x {grid} grid of {laws} law(s), {points} law-points")


def _fill(system: System, laws: tuple[str, ...], chosen: dict, mu: np.ndarray, lmi: LazyLmi,
          pair: tuple[float, np.ndarray, np.ndarray] | None, stable: np.ndarray, radius: np.ndarray) -> None:
    """One grid point: every law's verdict (1, 0, nan) and radius, and the containment check; ``pair`` is the
    point's homogeneous Riccati eigenpair (lambda, P, K) when "dp" is among the laws."""
    in_s = None
    for k, name in enumerate(laws):
        if name == "dp":    # the eigenpair once: lambda is the radius, and the membership's "riccati" form
            found = law_membership(system, "dp", mu, lmi=lmi, riccati=pair)
            radius[k] = pair[0]
            in_s = found.stable
        else:
            try:
                found = law_membership(system, chosen[name], mu)
            except NumericalError:
                continue   # nan: not a verdict
            radius[k] = found.radius
        stable[k] = np.nan if found.stable is None else float(found.stable)
    if in_s is False and np.any(stable == 1.0):
        bad = [name for name, v in zip(laws, stable, strict=True) if v == 1.0]
        raise CrossCheckError(f"region map at mu = {mu.tolist()}: {bad} proved stable where the stabilisable "
                              "set is certified empty", {name: float(r) for name, r in zip(laws, radius, strict=True)})
