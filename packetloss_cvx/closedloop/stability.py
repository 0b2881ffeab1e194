"""Mean-square stability of a stationary law ``u = -K x`` over independent Bernoulli channels.

With full state and ``x+ = (A - B V K) x + w`` (eq:plant, ``V = diag(v)``, ``v_i ~ Bernoulli(mu_i)``
independent across channels and steps), the second moment ``S = E[x x']`` obeys

.. math:: S^+ = \\mathcal{L}(S) + \\Sigma_W, \\qquad
   \\mathcal{L}(S) = \\bar A S \\bar A' + \\sum_i \\mu_i (1 - \\mu_i) (b_i k_i) S (b_i k_i)',

with ``Abar = A - B M K``, ``M = diag(mu)``, ``b_i`` the i-th column of B and ``k_i`` the i-th row of K
(the cross terms vanish: ``E[(v_i - mu_i)(v_j - mu_j)] = 0`` for i != j). The loop is mean-square
stable iff the spectral radius of ``L`` is below one. ``L`` maps PSD matrices to PSD matrices (it is
completely positive), so its spectral radius is itself an eigenvalue, with a PSD eigenvector.

The radius is computed without forming the n^2 x n^2 matrix for large n (ARPACK on the operator,
O(n^3 + n^2 m) per product), or from the Kronecker matrix for small n (the test reference). The operator, its
matrix and its radius are those of the mode engine (`packetloss_cvx.closedloop.modes`) at one mode: a
Bernoulli channel is the one-state chain.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ..errors import DimensionError, InputError
from ..model.system import numeric_array
from ..tolerances import MEAN_SQUARE_MARGIN
from .modes import RADIUS_RESCALE, mode_adjoint_step, mode_matrix, mode_radius, mode_step, random_matrix_moment

__all__ = [
    "RADIUS_RESCALE", "check_law", "is_mean_square_stable", "law_radius", "mean_square_radius", "random_matrix_moment",
    "second_moment_adjoint", "second_moment_map", "second_moment_matrix", "second_moment_step",
]


def check_law(A: npt.ArrayLike, B: npt.ArrayLike, K: npt.ArrayLike,
              mu: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validated float arrays ``(A, B, K, mu)``: A n×n, B n×m, K m×n, mu of length m in [0, 1].

    Raises
    ------
    DimensionError, InputError
        Naming the array and the expected shape.

    Examples
    --------
    >>> A, B, K, mu = check_law([[1]], [[1, 2]], [[1], [0]], 0.5)   # ints to floats, scalar mu not of length 2
    Traceback (most recent call last):
    ...
    packetloss_cvx.errors.DimensionError: mu: expected (2,), found (1,)
    >>> A, B, K, mu = check_law([[1]], [[1, 2]], [[1], [0]], [0.5, 1])
    >>> A.dtype, B.shape, K.shape, mu.tolist()
    (dtype('float64'), (1, 2), (2, 1), [0.5, 1.0])
    """
    A_, B_ = numeric_array(A, "A"), numeric_array(B, "B")
    K_, mu_ = numeric_array(K, "gain"), numeric_array(mu, "mu").reshape(-1)
    if A_.ndim != 2 or A_.shape[0] != A_.shape[1]:
        raise DimensionError("A", f"expected (n, n), found {A_.shape}")
    n = A_.shape[0]
    if B_.ndim != 2 or B_.shape[0] != n:
        raise DimensionError("B", f"expected ({n}, m), found {B_.shape}")
    m = B_.shape[1]
    if K_.shape != (m, n):
        raise DimensionError("gain", f"expected ({m}, {n}), found {K_.shape}")
    if mu_.shape != (m,):
        raise DimensionError("mu", f"expected ({m},), found {mu_.shape}")
    if np.any(mu_ < 0) or np.any(mu_ > 1):
        raise InputError("mu", "expected probabilities in [0, 1]")
    return A_, B_, K_, mu_


def second_moment_map(S: np.ndarray, A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """``L(S) = Abar S Abar' + B diag(mu (1 - mu) diag(K S K')) B'``: the module docstring's operator
    (`second_moment_step` applied once).

    Time O(n^3 + n^2 m). Arrays as returned by `check_law`.

    >>> A, B, K = np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]])
    >>> float(second_moment_map(np.eye(1), A, B, K, np.array([0.5]))[0, 0])   # (2 - 1)^2 + 0.25 * 4
    2.0
    """
    return second_moment_step(A, B, K, mu)(S)


def second_moment_step(A: np.ndarray, B: np.ndarray, K: np.ndarray,
                       mu: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``S -> L(S)`` ([`second_moment_map`][packetloss_cvx.closedloop.stability.second_moment_map]) for one law, its
    parts that do not depend on S (``Abar`` and ``mu (1 - mu)``) formed once: a caller applying one law many times (a
    finite horizon, a fixed-point or power iteration) pays O(n^2 m) once instead of every step; the same floats as
    [`second_moment_map`][packetloss_cvx.closedloop.stability.second_moment_map]. Time O(n^2 m) to build, O(n^3 + n^2 m)
    per application.

    >>> step = second_moment_step(np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0.5]))
    >>> float(step(np.eye(1))[0, 0]), float(step(2 * np.eye(1))[0, 0])      # L is linear: 2, then 4
    (2.0, 4.0)
    """
    return mode_step(A, B, K, mu)


def second_moment_adjoint(P: np.ndarray, A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """The adjoint ``L*(P) = Abar' P Abar + K' diag(mu (1 - mu) diag(B' P B)) K`` (tr(P L(S)) = tr(L*(P) S)).

    It propagates cost-to-go matrices backwards: the mode engine's adjoint at one mode
    (`mode_adjoint_step`). Time O(n^3 + n^2 m).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> A, B, K, mu = rng.normal(size=(2, 2)), rng.normal(size=(2, 1)), rng.normal(size=(1, 2)), np.array([0.3])
    >>> P, S = np.diag([1.0, 2.0]), np.array([[2.0, 0.5], [0.5, 1.0]])
    >>> lhs = np.trace(P @ second_moment_map(S, A, B, K, mu))
    >>> bool(np.isclose(lhs, np.trace(second_moment_adjoint(P, A, B, K, mu) @ S)))
    True
    """
    return mode_adjoint_step(A, B, K, mu)(P)


def second_moment_matrix(A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """The n^2 x n^2 matrix of ``L`` on row-major ``vec(S)``: ``Abar ⊗ Abar + sum_i c_i F_i ⊗ F_i``,
    ``F_i = b_i k_i``, ``c_i = mu_i (1 - mu_i)`` (`random_matrix_moment`). A stack of laws: K (..., m, n)
    with mu (..., m) gives (..., n^2, n^2). Time O(n^4 m) per law, memory 8 n^4 bytes: small n only.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> A, B, K, mu = rng.normal(size=(2, 2)), rng.normal(size=(2, 2)), rng.normal(size=(2, 2)), np.array([0.3, 0.8])
    >>> S = np.array([[2.0, 0.5], [0.5, 1.0]])
    >>> bool(np.allclose(second_moment_matrix(A, B, K, mu) @ S.ravel(), second_moment_map(S, A, B, K, mu).ravel()))
    True

    `random_matrix_moment` (re-exported here) builds it.
    """
    return mode_matrix(A, B, K, mu)


def mean_square_radius(A: npt.ArrayLike, B: npt.ArrayLike, K: npt.ArrayLike, mu: npt.ArrayLike,
                       method: str = "auto") -> float:
    """Spectral radius of the second-moment operator ``L`` of ``u = -K x`` (stable iff < 1).

    Parameters
    ----------
    A, B, K, mu : array_like
        Plant (n×n, n×m), gain (m×n), delivery probabilities (m).
    method : {"auto", "kronecker", "krylov"}
        "kronecker": eigenvalues of the n^2 x n^2 matrix (time O(n^6)); "krylov": ARPACK (implicitly
        restarted Arnoldi) on the operator, O(n^3 + n^2 m) per product and O(n^2) memory per vector;
        "auto": Kronecker for n <= ``KRONECKER_MAX_N``, else Krylov.

    Returns
    -------
    float
        The spectral radius (a real eigenvalue of ``L``, since ``L`` is positive).

    Raises
    ------
    NumericalError
        ARPACK or LAPACK's eigenvalue solver did not converge, or the operator is not finite.

    Examples
    --------
    >>> round(mean_square_radius([[2.0]], [[1.0]], [[2.0]], [0.5]), 12)   # scalar: (a - mu k)^2 + mu(1-mu)k^2
    2.0
    """
    return law_radius(*check_law(A, B, K, mu), method=method)


def law_radius(A_: np.ndarray, B_: np.ndarray, K_: np.ndarray, mu_: np.ndarray, method: str = "auto",
               matrix: Callable[[], np.ndarray] | None = None) -> float:
    """[`mean_square_radius`][packetloss_cvx.closedloop.stability.mean_square_radius] of a law already checked (the
    arrays `check_law` returns): a caller that checked it once (simulation.moments.closed_loop) does not check it again,
    and ``matrix`` gives the law's [`second_moment_matrix`][packetloss_cvx.closedloop.stability.second_moment_matrix]
    when the caller keeps it for its moment solves too (built once). Time as
    [`mean_square_radius`][packetloss_cvx.closedloop.stability.mean_square_radius].

    >>> A, B, K, mu = check_law([[2.0]], [[1.0]], [[2.0]], [0.5])
    >>> round(law_radius(A, B, K, mu), 12)                      # (a - mu k)^2 + mu (1 - mu) k^2
    2.0
    """
    if method not in ("auto", "kronecker", "krylov"):
        raise InputError("method", f"expected auto, kronecker or krylov, found {method!r}")
    return mode_radius(A_, B_, K_, mu_, method="dense" if method == "kronecker" else method, matrix=matrix)


def is_mean_square_stable(radius: float) -> bool:
    """True only when ``radius < 1 - MEAN_SQUARE_MARGIN``: a radius within the margin of one is not
    proved stable (the eigenvalue solvers agree to about 1e-12 relative).

    Examples
    --------
    >>> is_mean_square_stable(0.5), is_mean_square_stable(1.0 - 1e-15), is_mean_square_stable(np.nan)
    (True, False, False)
    """
    return bool(np.isfinite(radius) and radius < 1.0 - MEAN_SQUARE_MARGIN)
