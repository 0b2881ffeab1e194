"""The condensed expected-cost QP compiled once per padded shape and shared by every system of that shape.

The problem of the condensed backend (`CondensedBackend`, which owns
its data) is, with all of a system's data as
``cp.Parameter``s (DPP),

    minimise  ||c + G z||^2 + ||r ∘ z||^2      over z in R^K,

``c = L Phi x / sqrt(s)``, ``G = (L Gamma / sqrt(s))[:, free]`` and ``r = sqrt(w)`` on the free entries,
``w = (psi + [UDP] d (1 - mu)) / (mu s)`` (eq:opt-lqg-simplest with Lemma 1 in the mean delivered input
``z = mu u``; ``s`` the common weight scale). Nothing about a system is compiled in: one problem of
shape (R, K) serves every system, both protocols, stationary channels and schedules whose data fit.
Shapes are padded to a bucket (`padded`: 8, 16, ..., 64, then 96, 128, 192, ...): zero rows of
``c`` and ``G``, and padded variables with ``r = 1`` and a zero column of ``G``, so that a padded z is 0
at the optimum and adds nothing to the objective. The 200 random systems of the audit have 102
distinct (n, m, N) and fall into 15 buckets: the audit compiles 15 condensed problems instead of
404 (docs/performance.md, "Audit: compiled QPs shared across systems").

Every solve maps all three Parameters onto the compiled cone program and runs Clarabel **cold** (a new
solver, `ClarabelProgram`: the data ``problem.solve`` would hand Clarabel,
bit for bit, without cvxpy's per-solve reduction chain, which took 3/4 of a solve): cvxpy's
default re-solve updates the cached Clarabel solver in place, which keeps the Ruiz equilibration of
the first data it saw (Clarabel's ``update_data`` "reapplies the original equilibration"), so a
shared problem would solve each system with another system's scaling and its answers would depend
on the order of the solves. Cold, a solve is a function of its own data only.

Thread-safety and processes: the cache is per process (a module-level dict behind a lock); a Dask
worker process builds its own on first use. Each compiled problem carries a lock held from the
assignment of its Parameters to the read of its solution, so threads sharing a bucket take turns.

Complexity and memory: a compile is paid once per bucket; a re-solve costs O(R K) to assign and map the
Parameters into Clarabel's data plus Clarabel's O(K^3 + R K^2) solve, skipping cvxpy's reduction chain (which
about doubles a small re-solve). cvxpy keeps, per bucket, a parameter map with about R K entries: about 72 bytes
per entry of G with its data (tracemalloc; 1.2 MB at 128 × 128). At most ``SHARED_CACHE_SIZE`` buckets of at
most ``SHARED_MAX_ENTRIES`` entries each are kept (least recently used first out; about 60 MB at worst); a larger
shape gets a private, uncached problem of its exact shape.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import cvxpy as cp
import numpy as np

from ..errors import InputError
from ..tolerances import CLARABEL_TIGHT
from .convex import ClarabelProgram

__all__ = [
    "SHARED_CACHE_SIZE", "SHARED_MAX_ENTRIES", "CondensedQP", "cached_shapes", "clear_cache", "condensed_problem",
    "objective_value", "padded",
]

#: At most this many compiled buckets are kept per process (least recently used dropped first).
SHARED_CACHE_SIZE = 48

#: A padded shape with more than R K = SHARED_MAX_ENTRIES entries of G is not cached (so that the cache
#: holds at most 48 x 1.2 MB): it gets a private problem of its exact shape (R, K), compiled per object.
SHARED_MAX_ENTRIES = 2**14

#: Clarabel settings of every solve here: the QP twin's tight tolerances; every solve is cold (a new Clarabel
#: solver per solve, :class:`~packetloss_cvx.qp.convex.ClarabelProgram`; module docstring).
COLD_SETTINGS = dict(CLARABEL_TIGHT)

_lock = threading.Lock()
_cache: OrderedDict[tuple[int, int], CondensedQP] = OrderedDict()


def padded(size: int) -> int:
    """The bucket of a dimension: the least of 8, 16, 24, ..., 64 (multiples of 8), then 96, 128, 192,
    256, ... (2^k and 3 2^(k-1)) that is >= ``size``. Beyond 64 a bucket is at most 1.5 times ``size``.
    The audit's 200 random systems (R, K <= 32) fall into 15 buckets (58 with 1, 2, 3, 4, 6, 8, 12, ...:
    more compiles than the smaller solves save; docs/performance.md). O(log size).

    Examples
    --------
    >>> [padded(k) for k in (0, 1, 8, 9, 60, 65, 97, 129, 200)]
    [8, 8, 8, 16, 64, 96, 128, 192, 256]
    """
    if size <= 64:
        return 8 * max(1, -(-int(size) // 8))
    power = 1 << (int(size) - 1).bit_length()           # least power of two >= size
    return 3 * power // 4 if 3 * power // 4 >= size else power


class CondensedQP:
    """``min ||c + G z||^2 + ||r ∘ z||^2`` of shape (R, K), compiled once, solved for any data of at most
    that shape (padded with zero rows and decoupled unit-weight variables).

    Parameters
    ----------
    rows, cols : int
        R (rows of c and G, at least 1) and K (variables, at least 1).
    shared : bool
        Whether the problem lives in the module's cache (`condensed_problem`).

    Examples
    --------
    >>> qp = CondensedQP(2, 2)       # data of 1 x 1 in a 2 x 2 problem: min (1 + z)^2 + z^2, z = -1/2, value 1/2
    >>> z, value, status = qp.solve(np.array([1.0]), np.array([[1.0]]), np.array([1.0]), "a 1x1 QP")
    >>> status, bool(abs(z[0] + 0.5) < 1e-8), bool(abs(value - 0.5) < 1e-8)
    ('optimal', True, True)
    """

    def __init__(self, rows: int, cols: int, shared: bool = False) -> None:
        self.shape = (max(int(rows), 1), max(int(cols), 1))
        self.shared = shared
        R, K = self.shape
        self.z = cp.Variable(K, name="z")
        self.c = cp.Parameter(R, name="c")
        self.G = cp.Parameter((R, K), name="G")
        self.r = cp.Parameter(K, nonneg=True, name="r")
        self.problem = cp.Problem(cp.Minimize(cp.sum_squares(self.c + self.G @ self.z)
                                              + cp.sum_squares(cp.multiply(self.r, self.z))))
        if not self.problem.is_dpp():  # pragma: no cover - construction guarantees it
            raise RuntimeError("the shared condensed QP is not DPP")
        self.program: ClarabelProgram | None = None       # compiled on the first solve
        self.lock = threading.Lock()
        self.solves = 0

    def solve(self, c: np.ndarray, G: np.ndarray, r: np.ndarray, what: str) -> tuple[np.ndarray | None, float, str]:
        """Solve for ``c`` (rows), ``G`` (rows × k) and ``r`` (k, nonnegative), rows <= R and k <= K:
        every Parameter is assigned (padding included), so nothing of an earlier solve is left; the
        solve is cold. Returns ``(z, value, status)``: z of length k (None without a solution) and the
        objective value. O(R K) to assign plus Clarabel's solve.

        Raises
        ------
        InputError
            The data do not fit the problem's shape.
        SolverError
            cvxpy or Clarabel failed outright (`solve`).
        """
        R, K = self.shape
        rows, k = G.shape
        if rows > R or k > K or c.shape != (rows,) or r.shape != (k,):
            raise InputError("G", f"data of shape c {c.shape}, G {G.shape}, r {r.shape} do not fit a problem of "
                                  f"shape {self.shape}")
        c_full, G_full, r_full = np.zeros(R), np.zeros((R, K)), np.ones(K)
        c_full[:rows], G_full[:rows, :k], r_full[:k] = c, G, r
        with self.lock:
            if self.program is None:
                self.program = ClarabelProgram(self.problem)
            status, point = self.program.solve({self.c: c_full, self.G: G_full, self.r: r_full}, what,
                                               attempts=(COLD_SETTINGS,))
            self.solves += 1
            if status not in cp.settings.SOLUTION_PRESENT:
                return None, float("nan"), status
            # the data solved and the point stay on the Parameters and the Variable, as problem.solve leaves them:
            # stored by save_value (how cvxpy stores a solution), not through the value setter, whose validation
            # of data ClarabelProgram already checked (finite, shaped) was 40 % of a solve's Python time
            at = point(self.z)
            for leaf, value in ((self.c, c_full), (self.G, G_full), (self.r, r_full), (self.z, at)):
                leaf.save_value(value)
        # the value as problem.solve reports it: the objective evaluated at the point (not Clarabel's own)
        return np.array(at[:k], dtype=float), objective_value(c_full, G_full, r_full, at), status


def objective_value(c: np.ndarray, G: np.ndarray, r: np.ndarray, z: np.ndarray) -> float:
    """``||c + G z||^2 + ||r ∘ z||^2``, `CondensedQP`'s objective at ``z`` (cvxpy's ``objective.value`` of its
    expression ``quad_over_lin(c + G z, 1) + quad_over_lin(r * z, 1)``, to rounding). O(R K).

    Examples
    --------
    >>> objective_value(np.array([1.0]), np.array([[1.0]]), np.array([1.0]), np.array([-0.5]))     # 1/4 + 1/4
    0.5
    """
    return float(np.square(c + G @ z).sum() + np.square(r * z).sum())


def condensed_problem(rows: int, cols: int) -> CondensedQP:
    """The compiled problem for data of ``rows`` × ``cols``: the cached one of its padded shape
    (built on first use, least recently used dropped beyond ``SHARED_CACHE_SIZE``), or, beyond
    ``SHARED_MAX_ENTRIES``, a new private problem of the exact shape (not cached: keep it). O(1)
    when cached.

    Examples
    --------
    >>> clear_cache()
    >>> a, b = condensed_problem(5, 7), condensed_problem(8, 1)       # both fit the bucket (8, 8)
    >>> a is b, a.shape, a.shared, cached_shapes()
    (True, (8, 8), True, [(8, 8)])
    >>> condensed_problem(200, 100).shared                             # 256 x 128 > SHARED_MAX_ENTRIES
    False
    """
    shape = (padded(rows), padded(cols))
    if shape[0] * shape[1] > SHARED_MAX_ENTRIES:
        return CondensedQP(rows, cols)
    with _lock:
        found = _cache.get(shape)
        if found is not None:
            _cache.move_to_end(shape)
            return found
        found = _cache[shape] = CondensedQP(*shape, shared=True)    # cvxpy compiles it on its first solve
        while len(_cache) > SHARED_CACHE_SIZE:
            _cache.popitem(last=False)
        return found


def cached_shapes() -> list[tuple[int, int]]:
    """The padded shapes compiled in this process, least recently used first.

    Examples
    --------
    >>> clear_cache(); _ = condensed_problem(1, 3); cached_shapes()
    [(8, 8)]
    """
    with _lock:
        return list(_cache)


def clear_cache() -> None:
    """Drop every cached problem (the next solve of each shape compiles again).

    Examples
    --------
    >>> _ = condensed_problem(2, 2); clear_cache(); cached_shapes()
    []
    """
    with _lock:
        _cache.clear()
