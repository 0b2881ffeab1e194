"""Small linear-algebra helpers shared by the evaluators."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import TypeVar

import numpy as np

from .errors import NumericalError
from .tolerances import CONTROLLABILITY_RTOL, DENSE_RESIDUAL_RTOL, PSD_FACTOR_RTOL

__all__ = ["ControllableSplit", "block_diagonal", "check_finite", "controllable_split", "lapack_dgesv",
           "power_growth", "psd_factor", "solve_checked", "typed_linalg"]

_F = TypeVar("_F", bound=Callable)


def block_diagonal(blocks: np.ndarray) -> np.ndarray:
    """blkdiag(blocks[0], ..., blocks[N-1]) of N square n×n blocks, as one (N n)×(N n) array (the
    entries of scipy.linalg.block_diag, in one strided assignment, without importing SciPy). O((N n)^2).

    Examples
    --------
    >>> block_diagonal(np.array([[[1.0]], [[2.0]]])).tolist()
    [[1.0, 0.0], [0.0, 2.0]]
    """
    N, n, _ = blocks.shape
    out = np.zeros((N * n, N * n))                      # owns its data (a caller may make it read-only)
    steps = np.arange(N)
    out.reshape(N, n, N, n)[steps, :, steps, :] = blocks
    return out


@cache
def lapack_dgesv() -> Callable:
    """LAPACK's ``dgesv`` (``scipy.linalg.lapack``), imported on the first call: one small solve costs 1.2 us
    through it against 4.8 us through ``np.linalg.solve``'s stacked wrapper, but importing SciPy costs about
    0.15 s, which the closed-form paths that never solve one small system alone do not pay
    (optional.LAZY_IMPORTS). O(1) after the first call.

    Examples
    --------
    >>> lu, piv, x, info = lapack_dgesv()(np.array([[2.0]]), np.array([[1.0]]))
    >>> float(x[0, 0]), info
    (0.5, 0)
    """
    from scipy.linalg.lapack import dgesv  # optional.LAZY_IMPORTS

    return dgesv


def psd_factor(W: np.ndarray) -> np.ndarray:
    """L with L'L = W for a symmetric PSD W (eigen-decomposition; zero rows dropped).

    Examples
    --------
    >>> W = np.array([[2.0, 1.0], [1.0, 2.0]])
    >>> L = psd_factor(W)
    >>> bool(np.allclose(L.T @ L, W))
    True
    >>> psd_factor(np.diag([4.0, 0.0])).round(12).tolist()      # the zero direction is dropped
    [[2.0, 0.0]]
    """
    vals, vecs = np.linalg.eigh(W)
    keep = vals > PSD_FACTOR_RTOL * max(0.0, float(vals.max(initial=0.0)))   # relative: tiny weights are kept
    return np.sqrt(vals[keep])[:, None] * vecs[:, keep].T


def check_finite(name: str, arr: np.ndarray | float,
                 why: str = "the dense prediction of an unstable plant over a long horizon",
                 advice: str = "use method='recursion'") -> np.ndarray | float:
    """Return ``arr``, or raise :class:`NumericalError` saying that ``name`` overflowed, ``why``,
    and the ``advice``.

    Examples
    --------
    >>> check_finite("Phi", np.ones(2)).tolist()
    [1.0, 1.0]
    >>> check_finite("Phi", np.array([1.0, np.inf]), why="A is unstable", advice="shorten the horizon")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.NumericalError: Phi overflowed (A is unstable); shorten the horizon
    """
    if not np.all(np.isfinite(arr)):
        raise NumericalError(f"{name} overflowed ({why}); {advice}")
    return arr


def typed_linalg(what: str) -> Callable[[_F], _F]:
    """A decorator: a LAPACK failure inside the function (numpy.linalg.LinAlgError: an SVD or eigenvalue routine
    that did not converge, a singular solve) raised as :class:`NumericalError` naming ``what``, never untyped and
    never taken for an answer. O(1).

    Examples
    --------
    >>> @typed_linalg("the example")
    ... def fails():
    ...     raise np.linalg.LinAlgError("SVD did not converge")
    >>> fails()
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.NumericalError: the example: a linear-algebra routine failed (SVD did not converge); ...
    """
    def wrap(func: _F) -> _F:
        @functools.wraps(func)
        def inner(*args, **kwargs):
            try:
                return func(*args, **kwargs)
            except np.linalg.LinAlgError as err:
                raise NumericalError(f"{what}: a linear-algebra routine failed ({err}); the plant is too badly "
                                     "scaled or conditioned for this computation") from None
        return inner  # type: ignore[return-value]
    return wrap


def solve_checked(G: np.ndarray, rhs: np.ndarray, name: str, instead: str = "method='recursion'") -> np.ndarray:
    """``G^{-1} rhs`` by LU, kept only if finite and its relative residual
    ``||G X - rhs|| / (||G|| ||X|| + ||rhs||)`` is at most ``DENSE_RESIDUAL_RTOL``.

    Time O(k^3) for a k×k ``G``. Raises :class:`NumericalError` naming ``name`` and ``instead``.

    Examples
    --------
    >>> solve_checked(np.array([[2.0, 0.0], [0.0, 4.0]]), np.array([1.0, 1.0]), "G").tolist()
    [0.5, 0.25]
    >>> solve_checked(np.zeros((2, 2)), np.ones(2), "G")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.NumericalError: G: the matrix is singular to working precision; use method='recursion'
    """
    with np.errstate(all="ignore"):
        try:
            X = np.linalg.solve(G, rhs)
        except np.linalg.LinAlgError:
            raise NumericalError(f"{name}: the matrix is singular to working precision; use {instead}") from None
        residual = np.linalg.norm(G @ X - rhs)
        scale = np.linalg.norm(G) * np.linalg.norm(X) + np.linalg.norm(rhs)
    if not np.all(np.isfinite(X)) or not np.isfinite(residual) or residual > DENSE_RESIDUAL_RTOL * scale:
        raise NumericalError(f"{name}: the dense solve lost its accuracy (relative residual "
                             f"{residual / scale if scale else np.inf:.1e}); use {instead}")
    return X


def power_growth(A: np.ndarray, N: int, cap: float = np.inf) -> float:
    """max over t = 0..N of ||A^t||_2 (stops early once it exceeds ``cap``). Time O(N n^3).

    Examples
    --------
    >>> power_growth(np.array([[0.5]]), 10)          # ||A^0|| = 1 is the largest
    1.0
    >>> power_growth(np.array([[2.0]]), 3)           # ||A^3|| = 8
    8.0
    >>> power_growth(np.array([[2.0]]), 100, cap=10.0)   # stops at 2^4 = 16 > cap
    16.0
    """
    P = np.eye(A.shape[0])
    worst = 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(N):
            P = P @ A
            worst = max(worst, float(np.linalg.norm(P, 2)))
            if not worst <= cap:
                return worst if np.isfinite(worst) else float("inf")
    return worst


@dataclass(frozen=True)
class ControllableSplit:
    """The Kalman controllability decomposition of (A, B) in orthogonal coordinates.

    ``T' A T = [[A_cc, A_cu], [0, A_uu]]`` and ``T' B = [[B_c], [0]]`` with ``T`` orthogonal and the first ``nc``
    coordinates spanning the reachable subspace. ``dropped`` is the largest singular value the staircase
    treated as zero (0.0 when every zero was exact, as for a mode no input touches) and ``kept`` the least one
    it kept (``inf`` when nothing is reached), both relative to ``||[A, B]||_2``.
    """

    T: np.ndarray
    nc: int
    A: np.ndarray
    B: np.ndarray
    dropped: float
    kept: float

    @property
    def A_cc(self) -> np.ndarray:
        return self.A[:self.nc, :self.nc]

    @property
    def A_uu(self) -> np.ndarray:
        """The part no input reaches: its modes evolve as ``x_u+ = A_uu x_u`` whatever the law."""
        return self.A[self.nc:, self.nc:]

    @property
    def B_c(self) -> np.ndarray:
        return self.B[:self.nc]

    @property
    def uncontrollable_radius(self) -> float:
        """rho(A_uu), exactly the spectral radius of the part no law changes (0.0 when all is reached)."""
        if self.nc == self.A.shape[0]:
            return 0.0
        return float(np.abs(np.linalg.eigvals(self.A_uu)).max())


def controllable_split(A: np.ndarray, B: np.ndarray, rtol: float = CONTROLLABILITY_RTOL) -> ControllableSplit:
    """The controllability staircase of (A, B) by orthogonal transforms (Varga's form, one SVD per step).

    A direction counts as reached when its singular value exceeds ``rtol * ||[A, B]||_2``
    (tolerances.CONTROLLABILITY_RTOL: about the rounding the orthogonal steps themselves make). Backward
    stable, unlike the rank of the controllability matrix [B, AB, ...], whose columns grow like ||A||^n.
    Time O(n^4) at worst (n steps of O(n^3)).

    Examples
    --------
    A mode that no input reaches, coupled into the reached one (least mean-square radius exactly 1.2^2):

    >>> split = controllable_split(np.array([[0.5, 1.0], [0.0, 1.2]]), np.array([[1.0], [0.0]]))
    >>> split.nc, split.uncontrollable_radius, split.dropped
    (1, 1.2, 0.0)
    >>> bool(np.allclose(split.T @ split.A @ split.T.T, [[0.5, 1.0], [0.0, 1.2]]))
    True
    >>> controllable_split(np.eye(3) + np.eye(3, k=1), np.eye(3)[:, 2:]).nc      # a chain of integrators
    3
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    n = A.shape[0]
    scale = float(np.linalg.norm(np.hstack([A, B]), 2)) if n else 0.0
    tau = rtol * scale
    T = np.eye(n)
    At = A.copy()
    Bt = B.copy()
    start, dropped, kept = 0, 0.0, np.inf
    block = Bt                                            # what maps into the coordinates not yet reached
    while start < n and block.size:
        U, s, _ = np.linalg.svd(block, full_matrices=True)
        r = int(np.count_nonzero(s > tau))
        if r < s.size:
            dropped = max(dropped, float(s[r]))
        if r == 0:
            break
        kept = min(kept, float(s[r - 1]))
        At[start:, :] = U.T @ At[start:, :]
        At[:, start:] = At[:, start:] @ U
        Bt[start:, :] = U.T @ Bt[start:, :]
        T[:, start:] = T[:, start:] @ U
        block = At[start + r:, start:start + r]
        start += r
    nc = start
    At[nc:, :nc] = 0.0                                    # what the staircase dropped (at most tau each)
    Bt[nc:, :] = 0.0
    rel = 1.0 / scale if scale > 0 else 0.0
    return ControllableSplit(T=T, nc=nc, A=At, B=Bt, dropped=dropped * rel, kept=kept * rel)
