"""Small linear-algebra helpers shared by the evaluators."""

from __future__ import annotations

import numpy as np

from .errors import NumericalError
from .tolerances import DENSE_RESIDUAL_RTOL, PSD_FACTOR_RTOL

__all__ = ["check_finite", "power_growth", "psd_factor", "solve_checked"]


def psd_factor(W: np.ndarray) -> np.ndarray:
    """L with L'L = W for a symmetric PSD W (eigen-decomposition; zero rows dropped)."""
    vals, vecs = np.linalg.eigh(W)
    keep = vals > PSD_FACTOR_RTOL * max(0.0, float(vals.max(initial=0.0)))   # relative: tiny weights are kept
    return np.sqrt(vals[keep])[:, None] * vecs[:, keep].T


def check_finite(name: str, arr: np.ndarray | float,
                 why: str = "the dense prediction of an unstable plant over a long horizon",
                 advice: str = "use method='recursion'") -> np.ndarray | float:
    """Return ``arr``, or raise :class:`NumericalError` saying that ``name`` overflowed, ``why``,
    and the ``advice``."""
    if not np.all(np.isfinite(arr)):
        raise NumericalError(f"{name} overflowed ({why}); {advice}")
    return arr


def solve_checked(G: np.ndarray, rhs: np.ndarray, name: str, instead: str = "method='recursion'") -> np.ndarray:
    """``G^{-1} rhs`` by LU, kept only if finite and its relative residual
    ``||G X - rhs|| / (||G|| ||X|| + ||rhs||)`` is at most ``DENSE_RESIDUAL_RTOL``.

    Time O(k^3) for a k×k ``G``. Raises :class:`NumericalError` naming ``name`` and ``instead``.
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
    """max over t = 0..N of ||A^t||_2 (stops early once it exceeds ``cap``). Time O(N n^3)."""
    P = np.eye(A.shape[0])
    worst = 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(N):
            P = P @ A
            worst = max(worst, float(np.linalg.norm(P, 2)))
            if not worst <= cap:
                return worst if np.isfinite(worst) else float("inf")
    return worst
