"""Where a sweep's points are evaluated: in this process, or chunk by chunk on a Dask cluster.

The points are split into chunks of ``chunk_size`` consecutive points; each chunk is one call of
`evaluate_chunk` (one batched [`CostEvaluator`][packetloss_cvx.lq.evaluator.CostEvaluator] evaluation per
protocol and per distinct horizon, channels and initial states batched together). Both
paths call the same function on the same chunks, with the system rebuilt from the same plain
dictionary (``System.to_dict()``, exact for every float), so their results are identical bit for
bit. Dask is optional (the ``distributed`` extra) and imported only when asked for.
"""

from __future__ import annotations

import contextlib
import logging
import re
import signal
import threading
import time
from collections.abc import Iterator, Sequence
from multiprocessing import resource_tracker
from typing import Any

import numpy as np

from ..budgets import check, count_text
from ..closedloop.stability import mean_square_radius
from ..errors import InputError, NumericalError
from ..lq.evaluator import CostEvaluator
from ..model.files import system_from_dict
from ..progress import progress_bar
from ..threads import blas_limited

__all__ = ["DEFAULT_CHUNK", "LOCAL_WORKERS", "NO_WORKER_TIMEOUT", "chunks", "dask_client", "evaluate_chunk",
           "run_in_process", "run_on_dask"]

#: Points per chunk unless asked otherwise (docs/dask.md: a chunk should take well over the
#: ~1-10 ms a Dask task costs, and there should be several chunks per worker).
DEFAULT_CHUNK = 2048

#: Workers of ``dask="local"`` (one thread each: the evaluator is NumPy on small matrices).
LOCAL_WORKERS = 2

#: Seconds a Dask sweep waits while its scheduler has no worker (the last one died or was killed, or none
#: ever joined) before it stops with an InputError naming ``dask``; a worker that joins resets the clock.
NO_WORKER_TIMEOUT = 60.0

#: Seconds between two looks at the scheduler's workers while no chunk finishes, at most. The first look comes
#: POLL_FIRST_SECONDS after a batch and the wait doubles from there (about 7 looks, then one every POLL_SECONDS):
#: a sweep of quick chunks is no longer held up to 0.5 s per wait (a pendulum sweep of 3 points on a running
#: cluster: 0.51 -> 0.04 s wall, benchmarks/dask_latency.py; the same arrays).
POLL_SECONDS = 0.5
POLL_FIRST_SECONDS = 0.005

Chunk = tuple[np.ndarray, np.ndarray, np.ndarray]


def chunks(mu: np.ndarray, x0: np.ndarray, horizon: np.ndarray, size: int) -> list[Chunk]:
    """Consecutive slices of ``size`` points (the last may be shorter). O(points).

    Examples
    --------
    >>> mu, x0, horizon = np.zeros((5, 2)), np.ones((5, 1)), np.arange(5)
    >>> [len(c[0]) for c in chunks(mu, x0, horizon, 2)], chunks(mu, x0, horizon, 2)[2][2].tolist()
    ([2, 2, 1], [4])
    """
    return [(mu[k:k + size], x0[k:k + size], horizon[k:k + size]) for k in range(0, len(mu), size)]


@blas_limited
def evaluate_chunk(system_data: dict[str, Any], protocols: Sequence[str], mu: np.ndarray, x0: np.ndarray,
                   horizon: np.ndarray, stability: bool = False) -> dict[str, np.ndarray]:
    """J* of each protocol at each point of one chunk (and the mean-square radius of its law).

    Parameters
    ----------
    system_data : dict
        The system in the TOML schema's structure (``System.to_dict()``): plain data, so it
        travels to a Dask worker (a [`System`][packetloss_cvx.model.system.System] is immutable and not pickled).
    protocols : sequence of {"tcp", "udp"}
    mu : ndarray, shape (points, m)
    x0 : ndarray, shape (points, n)
    horizon : ndarray of int, shape (points,)
    stability : bool
        Also the spectral radius of the second-moment operator of each protocol's receding-horizon
        law ``u = -K x`` run in closed loop over the point's channel
        ([`mean_square_radius`][packetloss_cvx.closedloop.stability.mean_square_radius]; mean-square stable iff < 1).

    Returns
    -------
    dict
        ``"cost_<protocol>"`` -> costs, shape (points,); with ``stability``, ``"radius_<protocol>"`` too (nan
        where the radius cannot be computed in double precision).

    Notes
    -----
    The points are grouped by horizon; each group is one batched evaluation per protocol (channels
    and initial states per point). O(points N (n^3 + m^3)) work, or O(points (N m)^3) where the evaluator
    takes the dense path (it picks the faster exact path, by N, m and the batch's size).

    Examples
    --------
    One step of x' = x + v u from x0 = 1 (Q = R = 1): `J*_tcp` = 1/(1 + mu), `J*_udp` = 1 - mu/2.

    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> out = evaluate_chunk(s.to_dict(), ["tcp", "udp"], np.array([[0.0], [0.5]]), np.ones((2, 1)), np.ones(2, int))
    >>> bool(np.allclose(out["cost_tcp"], [1, 2 / 3]) and np.allclose(out["cost_udp"], [1, 0.75]))
    True
    """
    base = system_from_dict(system_data)
    names = [f"{what}_{p}" for p in protocols for what in (("cost", "radius") if stability else ("cost",))]
    out = {name: np.empty(len(mu)) for name in names}
    for N in np.unique(horizon):
        idx = np.flatnonzero(horizon == N)
        system = base if N == base.horizon else _with_horizon(base, system_data, int(N))
        for p in protocols:
            evaluator = CostEvaluator(system, p)
            if not stability:
                out[f"cost_{p}"][idx] = evaluator.costs(mu[idx], x0[idx])
                continue
            batch = evaluator.solve(mu[idx], x0[idx])
            out[f"cost_{p}"][idx] = batch.costs
            out[f"radius_{p}"][idx] = [_radius(system, K, point) for K, point in zip(batch.gains, mu[idx], strict=True)]
    return out


def _radius(system, K: np.ndarray, mu: np.ndarray) -> float:
    """The law's mean-square radius at one point; nan where it cannot be computed in double precision (a
    NumericalError: the sweep's summary counts these points and says why)."""
    try:
        return mean_square_radius(system.A, system.B, K, mu)
    except NumericalError:
        return float("nan")


def _with_horizon(base, system_data: dict[str, Any], horizon: int):
    data = {**system_data, "cost": {**system_data["cost"], "horizon": horizon}}
    data["channel"] = {"mu": base.mu_schedule[0].tolist()}
    return system_from_dict(data)


def _assemble(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}


def run_in_process(system_data: dict[str, Any], protocols: Sequence[str], work: list[Chunk],
                   progress: bool | None = None, stability: bool = False,
                   estimate: float | None = None) -> dict[str, np.ndarray]:
    """Every chunk here, in order. O(points N (n^3 + m^3)).

    Examples
    --------
    >>> from packetloss_cvx.model.system import System
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> mu = np.array([[0.0], [0.5], [1.0]])            # J*_tcp = 1/(1 + mu), in two chunks
    >>> out = run_in_process(s.to_dict(), ["tcp"], chunks(mu, np.ones((3, 1)), np.ones(3, int), 2))
    >>> bool(np.allclose(out["cost_tcp"], 1 / (1 + mu[:, 0])))
    True
    """
    parts = []
    with progress_bar(total=sum(len(c[0]) for c in work), desc="sweep", progress=progress, estimate=estimate) as bar:
        for chunk in work:
            parts.append(evaluate_chunk(system_data, protocols, *chunk, stability))
            bar.update(len(chunk[0]))
    return _assemble(parts)


def run_on_dask(system_data: dict[str, Any], protocols: Sequence[str], work: list[Chunk], dask: Any,
                workers: int | None = None, progress: bool | None = None,
                stability: bool = False, estimate: float | None = None) -> dict[str, np.ndarray]:
    """Every chunk as one Dask task; results put back in chunk order.

    Parameters
    ----------
    dask : "local", an address such as ``"tcp://host:8786"``, or a ``distributed.Client``
        ``"local"`` starts a `distributed.LocalCluster` of ``workers`` processes
        (default `LOCAL_WORKERS`, one thread each, at most the ``dask_workers`` budget) and closes
        it afterwards; an address connects to a running scheduler; a client (e.g. on a dask-jobqueue or
        Kubernetes cluster) is used as it is.

    Raises
    ------
    InputError
        A scheduler that cannot be reached (the failed client is closed at once: no 20 s wait, no traceback
        at exit), or one left without any worker for `NO_WORKER_TIMEOUT` seconds (named ``dask``).
    BudgetError
        More local workers than the ``dask_workers`` budget, before any is started.
    """
    with dask_client(dask, workers) as client:
        from distributed import as_completed  # lazy: the `distributed` extra (dask_client refused its absence)
        futures = [client.submit(evaluate_chunk, system_data, tuple(protocols), *chunk, stability, pure=False)
                   for chunk in work]
        order = {f.key: k for k, f in enumerate(futures)}
        parts: list[dict[str, np.ndarray] | None] = [None] * len(work)
        with progress_bar(total=sum(len(c[0]) for c in work), desc="sweep (dask)", progress=progress,
                          estimate=estimate) as bar:     # the estimate is one process's: divide by the workers
            finished = as_completed(futures, loop=client.loop)   # not the default client's loop
            alone_since: float | None = None
            pause = POLL_FIRST_SECONDS
            while not finished.is_empty():
                batch = finished.next_batch(block=False)
                if not batch:        # nothing finished: is anyone working?
                    alone_since = _no_worker_clock(client, alone_since, sum(p is not None for p in parts), len(work))
                    time.sleep(pause)
                    pause = min(2.0 * pause, POLL_SECONDS)
                    continue
                alone_since, pause = None, POLL_FIRST_SECONDS
                for future in batch:
                    k = order[future.key]
                    parts[k] = future.result()      # a worker's error is raised here with its own type
                    bar.update(len(work[k][0]))
        return _assemble(parts)      # type: ignore[arg-type]


@contextlib.contextmanager
def dask_client(dask: Any, workers: int | None = None) -> Iterator[Any]:
    """A ``distributed.Client`` for ``dask`` ("local", a scheduler address, or a Client used as it is); a
    cluster or client made here is closed on leaving (quietly: no traceback after the error line). Shared
    by every command that runs on Dask (sweep, region maps). O(1) plus the cluster's start.

    Raises
    ------
    InputError
        Field ``dask`` (not installed, a malformed or unreachable address: the failed client is closed at
        once, no 20 s wait, no traceback at exit; another type) or ``workers``.
    BudgetError
        More local workers than the ``dask_workers`` budget, before any is started.

    Examples
    --------
    >>> try:
    ...     with dask_client("no address"):
    ...         pass
    ... except InputError as err:
    ...     print(err.field)
    dask
    """
    try:
        from distributed import Client, LocalCluster  # lazy: the `distributed` extra
    except ImportError:
        raise InputError("dask", "needs the distributed extra: pip install 'packetloss-cvx[distributed]'") from None
    if workers is not None and not (isinstance(dask, str) and dask == "local"):
        raise InputError("workers", "applies to dask='local' only (a running cluster has its own workers)")
    owned: list[Any] = []
    try:
        if isinstance(dask, str) and dask == "local":
            count = LOCAL_WORKERS if workers is None else workers
            if isinstance(count, bool) or not isinstance(count, int) or count < 1:
                raise InputError("workers", f"expected an integer >= 1, found {count!r}")
            check("dask_workers", count, "workers", f"{count_text(count)} worker processes")   # before any is started
            # logs at CRITICAL only: a worker's error comes back as its task's exception, the scheduler's loss as
            # the no-worker InputError; what distributed logged at ERROR was noise after an interrupt ("Failed to
            # communicate with scheduler during heartbeat", 30-75 lines from the workers in 3 of 6 SIGINTs)
            cluster = _deaf_to_sigint(lambda: LocalCluster(n_workers=count, threads_per_worker=1, processes=True,
                                                           dashboard_address=None, silence_logs=logging.CRITICAL))
            owned.append(cluster)
            client = Client(cluster, set_as_default=False)
            owned.insert(0, client)
        elif isinstance(dask, str):
            if not re.fullmatch(r"[a-z]+://\S+|[\w.-]+:\d+", dask):
                raise InputError("dask", f"expected 'local' or a scheduler address such as tcp://host:8786, "
                                         f"found {dask!r}")
            made: list[Any] = []

            class Tracked(Client):          # keeps the instance even when its constructor fails
                def __init__(self, *args: Any, **kwargs: Any) -> None:
                    made.append(self)
                    super().__init__(*args, **kwargs)

            try:
                # not the process's default client: a failed one would stay registered as the default
                # and break the caller's later dask / xarray work (distributed registers it before connecting)
                client = Tracked(dask, timeout="10s", set_as_default=False)
            except Exception as err:    # noqa: BLE001  any failure to connect (ucx:// without ucx-py: TypeError)
                for failed in made:     # else its __del__ waits 20 s at exit and prints a 9-line traceback
                    _close_quietly(failed)
                raise InputError("dask", f"cannot reach a scheduler at {dask!r}: {type(err).__name__}: {err}") from None
            owned.append(client)
        elif hasattr(dask, "submit") and hasattr(dask, "gather"):
            client = dask
        else:
            raise InputError("dask", f"expected 'local', a scheduler address or a Client, found {dask!r}")
        yield client
    finally:
        for thing in owned:
            _close_quietly(thing)


#: Seconds an interrupted caller waits for a local cluster still starting, to close it (two workers: about 1-2 s)
CLUSTER_START_WAIT = 60.0


def _deaf_to_sigint(make: Any) -> Any:
    """``make()`` (a LocalCluster) built in a thread that blocks SIGINT, so that every thread and process it starts
    (the cluster's IO loop, its worker processes: the signal mask is inherited through fork and exec) blocks SIGINT
    from birth. A Ctrl-C at a terminal goes to the whole process group: workers that received it would print their
    own KeyboardInterrupt tracebacks (50-90 lines, from an import or the worker's loop) after the command's one
    line. So only this process hears it, and closes the cluster, whose nannies stop the workers. This thread
    blocks SIGINT only for the instant the builder thread starts (a signal then is held pending, not lost).

    Interrupted while the cluster starts, the caller waits for the build (at most `CLUSTER_START_WAIT`) and
    closes what it made. Where signal masks do not exist (Windows) ``make()`` runs here. O(1) plus the start."""
    if not hasattr(signal, "pthread_sigmask"):
        return make()
    # multiprocessing's resource tracker, started by the first worker's spawn, unblocks SIGINT and SIGTERM in the
    # thread that starts it (it blocks them around its own spawn, then unblocks rather than restores): started
    # here first, it leaves the builder's mask alone (measured on Python 3.11: the workers were not deaf without it)
    resource_tracker.ensure_running()
    made: dict[str, Any] = {}

    def build() -> None:
        try:
            made["cluster"] = make()
        except BaseException as err:      # noqa: BLE001 - handed to the caller
            made["error"] = err

    builder = threading.Thread(target=build, name="packetloss-cvx LocalCluster start", daemon=True)
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        builder.start()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    try:
        builder.join()           # interruptible: the signal's handler raises here
    except BaseException:
        builder.join(CLUSTER_START_WAIT)
        if "cluster" in made:
            _close_quietly(made["cluster"])
        raise
    if "error" in made:
        raise made["error"]
    return made["cluster"]


def _no_worker_clock(client: Any, since: float | None, done: int, total: int) -> float | None:
    """When the scheduler has had no worker since (None: it has one now); past `NO_WORKER_TIMEOUT`
    an InputError: a sweep whose last worker died would otherwise wait for ever. O(1) scheduler call."""
    if client.nthreads():
        return None
    now = time.monotonic()
    since = now if since is None else since
    if now - since > NO_WORKER_TIMEOUT:
        raise InputError("dask", f"the scheduler has had no worker for {NO_WORKER_TIMEOUT:g} s (the last one stopped "
                                 f"or was killed); stopped with {done} of {total} chunks done")
    return since


def _close_quietly(thing: Any) -> None:
    """Close a client or cluster within seconds; a failure to close is not the caller's error."""
    try:
        if hasattr(thing, "submit"):      # a client: its default close waits 20 s for a scheduler that is gone
            thing.close(timeout=5)
        else:
            thing.close()
    except Exception:       # noqa: BLE001 - closing after an error: the first error is the one to report
        pass
