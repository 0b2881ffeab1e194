"""Small linear-algebra helpers shared by the evaluators."""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import numpy as np

from .errors import NumericalError
from .tolerances import DENSE_RESIDUAL_RTOL, PSD_FACTOR_RTOL

__all__ = ["block_diagonal", "check_finite", "lapack_dgesv", "power_growth", "psd_factor", "solve_checked"]


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
