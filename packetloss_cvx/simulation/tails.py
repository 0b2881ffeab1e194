"""Whether a sampled closed-loop cost has an error bar: the fourth moments of the loop.

A run's mean stage cost is an average of quadratics ``x_t' Q x_t``; its variance is built from the fourth moments
``E[x_t^{(4)}]`` (``x^{(4)} = x ⊗ x ⊗ x ⊗ x``). Under ``x+ = F_v x + w`` with ``F_v = A - B V K`` (independent
Bernoulli deliveries ``v``, noise with finite fourth moments), the fourth moments evolve through the operator

.. math:: \\mathcal{L}_4(X) = E[F_v^{\\otimes 4}] X,

so they stay bounded iff ``rho(L_4) < 1``. With ``rho(L_4) >= 1`` the second moments may still decay (Jensen:
``rho(L_2)^2 <= rho(L_4)``), so the mean cost is finite, but the variance of a run's cost grows like
``rho(L_4)^T``: the sample is ruled by rare long loss bursts and its standard error is not an error bar (scalar
``a = 2``, ``k = 2``, ``mu = 0.8``: ``rho(L_2) = 0.8``, ``rho(L_4) = 3.2``; a sampled 80.7 +- 4.4 against the
exact 101.8). :func:`fourth_moment_radius` computes ``rho(L_4)``; :func:`error_bar_reason` says why a sample
gets no error bar ("" when it does).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..tolerances import MEAN_SQUARE_MARGIN

__all__ = ["FOURTH_MOMENT_DENSE_MAX_N", "FOURTH_MOMENT_MAX_N", "error_bar_reason", "fourth_moment_radius"]

#: L_4 is formed as an n^4 x n^4 matrix up to this n (1296 x 1296, about 0.5 s), applied as an operator beyond ...
FOURTH_MOMENT_DENSE_MAX_N = 6
#: ... up to this n (n^4 = 65,536 entries a vector); beyond it the fourth moments are not computed (unproved).
FOURTH_MOMENT_MAX_N = 16
#: the delivery patterns are enumerated (2^m of them) up to this m
FOURTH_MOMENT_MAX_M = 12


def _patterns(B: np.ndarray, K: np.ndarray, A: np.ndarray, mu: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """The closed-loop matrices F_v of every delivery pattern v with positive probability, and the probabilities."""
    m = B.shape[1]
    mats, probs = [], []
    for v in itertools.product((0.0, 1.0), repeat=m):
        p = float(np.prod([mu[i] if v[i] else 1.0 - mu[i] for i in range(m)]))
        if p > 0.0:
            mats.append(A - (B * np.array(v)) @ K)
            probs.append(p)
    return mats, np.array(probs)


def _apply(X: np.ndarray, mats: list[np.ndarray], probs: np.ndarray) -> np.ndarray:
    """L_4(X) = sum_v p_v F_v^{⊗4} X for X of shape (n, n, n, n), mode by mode. Time O(2^m n^5)."""
    out = np.zeros_like(X)
    for F, p in zip(mats, probs, strict=True):
        Y = np.einsum("ai,ijkl->ajkl", F, X)
        Y = np.einsum("bj,ajkl->abkl", F, Y)
        Y = np.einsum("ck,abkl->abcl", F, Y)
        out += p * np.einsum("dl,abcl->abcd", F, Y)
    return out


def fourth_moment_radius(A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray) -> float:
    """rho(L_4) of the law ``u = -K x`` over independent Bernoulli(mu) channels (nan where n or m is beyond
    FOURTH_MOMENT_MAX_N or FOURTH_MOMENT_MAX_M). Dense eigenvalues up to FOURTH_MOMENT_DENSE_MAX_N (time
    O(n^12)), ARPACK on the operator beyond (O(2^m n^5) per product).

    Examples
    --------
    >>> float(round(fourth_moment_radius(np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0.8])), 12))
    3.2
    """
    A, B, K, mu = (np.asarray(x, dtype=float) for x in (A, B, K, mu))
    n, m = A.shape[0], B.shape[1]
    if n > FOURTH_MOMENT_MAX_N or m > FOURTH_MOMENT_MAX_M:
        return float("nan")
    mats, probs = _patterns(B, K, A, mu)
    with np.errstate(over="ignore", invalid="ignore"):
        if n <= FOURTH_MOMENT_DENSE_MAX_N:
            L4 = np.zeros((n ** 4, n ** 4))
            for F, p in zip(mats, probs, strict=True):
                F2 = np.kron(F, F)
                L4 += p * np.kron(F2, F2)
            if not np.all(np.isfinite(L4)):
                return float("inf")
            return float(np.abs(np.linalg.eigvals(L4)).max())
        from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, LinearOperator, eigs  # optional.LAZY_IMPORTS

        size = n ** 4
        op = LinearOperator((size, size), dtype=float,
                            matvec=lambda v: _apply(np.asarray(v).reshape(n, n, n, n), mats, probs).ravel())
        start = np.einsum("ij,kl->ijkl", np.eye(n), np.eye(n)).ravel()
        try:
            vals = eigs(op, k=1, which="LM", v0=start, tol=1e-10, maxiter=50 * n)[0]
        except (ArpackNoConvergence, ArpackError):
            return float("nan")
    return float(np.abs(vals).max())


def error_bar_reason(A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray) -> str:
    """Why a sampled closed-loop cost of the law gets no error bar ("" when its fourth moments are proved bounded:
    rho(L_4) below 1 by MEAN_SQUARE_MARGIN, the margin of every stability verdict).

    Examples
    --------
    >>> error_bar_reason(np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0.8])).split(", so")[0]
    'no error bar: the fourth moments grow (rho_4 = 3.2 >= 1)'
    >>> error_bar_reason(np.array([[0.5]]), np.array([[1.0]]), np.array([[0.5]]), np.array([0.8]))
    ''
    """
    rho4 = fourth_moment_radius(A, B, K, mu)
    if np.isnan(rho4):
        return (f"no error bar: the fourth moments were not computed (n = {A.shape[0]} > {FOURTH_MOMENT_MAX_N} or "
                f"m = {B.shape[1]} > {FOURTH_MOMENT_MAX_M}), so the sample's variance is unproved; use the exact value")
    if rho4 < 1.0 - MEAN_SQUARE_MARGIN:
        return ""
    return (f"no error bar: the fourth moments grow (rho_4 = {rho4:.4g} >= 1), so the run cost's variance grows "
            f"with the steps and the sample is ruled by rare loss bursts; use the exact value")
