"""Whether a sampled closed-loop cost has an error bar: the fourth moments of the loop.

A run's mean stage cost is an average of quadratics ``x_t' Q x_t``; its variance is built from the fourth moments
``E[x_t^{(4)}]`` (``x^{(4)} = x ⊗ x ⊗ x ⊗ x``). Under ``x+ = F_v x + w`` with ``F_v = A - B V K`` (independent
Bernoulli deliveries ``v``, noise with finite fourth moments), the fourth moments evolve through the operator

.. math:: \\mathcal{L}_4(X) = E[F_v^{\\otimes 4}] X,

so they stay bounded iff ``rho(L_4) < 1``. With ``rho(L_4) >= 1`` the second moments may still decay (Jensen:
``rho(L_2)^2 <= rho(L_4)``), so the mean cost is finite, but the variance of a run's cost grows like
``rho(L_4)^T``: the sample is ruled by rare long loss bursts and its standard error is not an error bar (scalar
``a = 2``, ``k = 2``, ``mu = 0.8``: ``rho(L_2) = 0.8``, ``rho(L_4) = 3.2``; a sampled 80.7 +- 4.4 against the
exact 101.8). `fourth_moment_radius` computes ``rho(L_4)``; `error_bar_reason` says why a sample
gets no error bar ("" when it does).
"""

from __future__ import annotations

import numpy as np

from ..tolerances import MEAN_SQUARE_MARGIN
from .mjls import delivery_patterns

__all__ = ["FOURTH_MOMENT_DENSE_MAX_DIM", "FOURTH_MOMENT_MAX_DIM", "FOURTH_MOMENT_MAX_N", "error_bar_reason",
           "fourth_moment_radius"]

#: L_4 is formed as a matrix of M n^4 rows up to this many (n = 6, one mode: 1296 rows, about 0.5 s), applied as an
#: operator beyond ...
FOURTH_MOMENT_DENSE_MAX_DIM = 1296
#: ... up to this many rows (n = 16, one mode: 65,536 entries a vector) and this n; beyond, the fourth moments are not
#: computed (unproved).
FOURTH_MOMENT_MAX_DIM = 65536
FOURTH_MOMENT_MAX_N = 16
#: the delivery patterns are enumerated (2^m of them) up to this m
FOURTH_MOMENT_MAX_M = 12


def _mode_law(A: np.ndarray, B: np.ndarray, K: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per mode a: the closed-loop matrices F_{a,v} of every pattern v and their probabilities P(v | a)
    ((M, 2^m, n, n) and (M, 2^m), the patterns of markov.mjls.delivery_patterns); A is (n, n) or per mode
    (M, n, n), B (n, m) or per mode (M, n, m), K is (M, m, n), h is (M, m)."""
    v, prob = delivery_patterns(h)
    BvK = (np.einsum("ij,vj,ajk->avik", B, v, K) if B.ndim == 2 else np.einsum("aij,vj,ajk->avik", B, v, K))
    F = (A[None, None] if A.ndim == 2 else A[:, None]) - BvK
    return F, prob


def _apply(X: np.ndarray, F: np.ndarray, prob: np.ndarray, T: np.ndarray, delivery: str) -> np.ndarray:
    """The coupled fourth-moment map on X of shape (M, n, n, n, n), mode by mode:
    ``X_b <- sum_a T_ab sum_v P(v | a or b) F_{a,v}^{(4)} X_a`` (``delivery``: the deliveries follow the mode a,
    "current", or the mode b the chain moves to, "next"). Time O(M^2 2^m n^5)."""
    M = X.shape[0]
    out = np.zeros_like(X)
    for a in range(M):
        for k in range(F.shape[1]):
            G = F[a, k]
            Y = np.einsum("ai,ijkl->ajkl", G, X[a])
            Y = np.einsum("bj,ajkl->abkl", G, Y)
            Y = np.einsum("ck,abkl->abcl", G, Y)
            Y = np.einsum("dl,abcl->abcd", G, Y)
            weights = T[a] * (prob[a, k] if delivery == "current" else prob[:, k])
            out += weights[:, None, None, None, None] * Y[None]
    return out


def fourth_moment_radius(A: np.ndarray, B: np.ndarray, K: np.ndarray, h: np.ndarray, T: np.ndarray | None = None,
                         delivery: str = "current") -> float:
    """rho(L_4) of the law ``u = -K_a x`` over a channel whose mode a follows the chain ``T`` (M×M) and delivers
    on channel i with probability ``h[a, i]``, independently given the mode (``A`` one n×n matrix, or one per mode:
    the actuator's loops, closedloop.actuator.JumpLoop; ``B`` one n×m matrix, or one per mode: the loop of a law on
    a filter's estimate, sensing.loop, whose modes are the sensor's arrival patterns). Independent Bernoulli(mu)
    channels are the one-mode chain: ``h = mu``, ``T`` omitted, K one m×n gain. nan where n, m or the operator's size is
    beyond its limits (unproved). Dense eigenvalues up to FOURTH_MOMENT_DENSE_MAX_DIM rows (M n^4), ARPACK on
    the operator beyond (O(M^2 2^m n^5) per product).

    Examples
    --------
    >>> one = np.array([[1.0]])
    >>> float(round(fourth_moment_radius(2 * one, one, 2 * one, np.array([0.8])), 12))   # (1 - mu) a^4
    3.2
    >>> # a Gilbert channel that delivers in its good mode only, p = r = 1/2 (memoryless): the same loop at mu = 1/2
    >>> h, T = np.array([[1.0], [0.0]]), np.full((2, 2), 0.5)
    >>> float(round(fourth_moment_radius(2 * one, one, 2 * one, h, T), 12)), 0.5 * 2.0 ** 4
    (8.0, 8.0)
    """
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    n, m = A.shape[-1], B.shape[-1]
    h = np.atleast_2d(np.asarray(h, dtype=float))
    M = h.shape[0]
    T = np.ones((1, 1)) if T is None else np.asarray(T, dtype=float)
    K = np.asarray(K, dtype=float)
    K = np.broadcast_to(K, (M, m, n)) if K.ndim == 2 else K
    if n > FOURTH_MOMENT_MAX_N or m > FOURTH_MOMENT_MAX_M or M * n ** 4 > FOURTH_MOMENT_MAX_DIM:
        return float("nan")
    F, prob = _mode_law(A, B, K, h)
    size = M * n ** 4
    with np.errstate(over="ignore", invalid="ignore"):
        if size <= FOURTH_MOMENT_DENSE_MAX_DIM:
            blocks = np.zeros((M, M, n ** 4, n ** 4))                       # [b, a]
            for a in range(M):
                for k in range(F.shape[1]):
                    F2 = np.kron(F[a, k], F[a, k])
                    weights = T[a] * (prob[a, k] if delivery == "current" else prob[:, k])
                    blocks[:, a] += weights[:, None, None] * np.kron(F2, F2)[None]
            L4 = blocks.transpose(0, 2, 1, 3).reshape(size, size)
            if not np.all(np.isfinite(L4)):
                return float("inf")
            return float(np.abs(np.linalg.eigvals(L4)).max())
        from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, LinearOperator, eigs  # optional.LAZY_IMPORTS

        shape = (M, n, n, n, n)
        op = LinearOperator((size, size), dtype=float,
                            matvec=lambda x: _apply(np.asarray(x).reshape(shape), F, prob, T, delivery).ravel())
        start = np.broadcast_to(np.einsum("ij,kl->ijkl", np.eye(n), np.eye(n)), shape).ravel()
        try:
            vals = eigs(op, k=1, which="LM", v0=start, tol=1e-10, maxiter=50 * n)[0]
        except (ArpackNoConvergence, ArpackError):
            return float("nan")
    return float(np.abs(vals).max())


def error_bar_reason(A: np.ndarray, B: np.ndarray, K: np.ndarray, h: np.ndarray, T: np.ndarray | None = None,
                     delivery: str = "current") -> str:
    """Why a sampled closed-loop cost of the law gets no error bar ("" when its fourth moments are proved bounded:
    rho(L_4) below 1 by MEAN_SQUARE_MARGIN, the margin of every stability verdict; "" also when no delivery is random,
    every ``h`` and ``T`` entry 0 or 1: no loss burst for the sample to miss, whatever rho(L_4)). Arguments as
    `fourth_moment_radius`.

    Examples
    --------
    >>> error_bar_reason(np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0.8])).split(", so")[0]
    'no error bar: the fourth moments grow (rho_4 = 3.2 >= 1)'
    >>> error_bar_reason(np.array([[0.5]]), np.array([[1.0]]), np.array([[0.5]]), np.array([0.8]))
    ''
    >>> error_bar_reason(np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0.0]))  # nothing random
    ''
    """
    h = np.asarray(h, dtype=float)
    if np.all((h == 0.0) | (h == 1.0)) and (T is None or np.all((np.asarray(T) == 0.0) | (np.asarray(T) == 1.0))):
        return ""       # no delivery is random: no loss burst to miss; a run's cost is a quadratic of the noise (or
        #                 the same in every run), whose sample spread is an error bar whatever rho_4
    rho4 = fourth_moment_radius(A, B, K, h, T, delivery)
    if np.isnan(rho4):
        return (f"no error bar: the fourth moments were not computed (n = {np.shape(A)[-1]}, m = {np.shape(B)[-1]}, "
                f"{np.atleast_2d(h).shape[0]} channel modes: beyond n = {FOURTH_MOMENT_MAX_N}, m = "
                f"{FOURTH_MOMENT_MAX_M} or {FOURTH_MOMENT_MAX_DIM} rows), so the sample's variance is unproved; "
                "use the exact value")
    if rho4 < 1.0 - MEAN_SQUARE_MARGIN:
        return ""
    return (f"no error bar: the fourth moments grow (rho_4 = {rho4:.4g} >= 1), so the variance of a run's loop cost "
            "grows with the steps and the sample is ruled by rare loss bursts; use the exact value")
