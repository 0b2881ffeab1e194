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
O(n^3 + n^2 m) per product), or from the Kronecker matrix for small n (the test reference).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, LinearOperator, eigs

from ..errors import DimensionError, InputError, NumericalError
from ..model import numeric_array
from ..tolerances import ARPACK_TOL, KRONECKER_MAX_N, MEAN_SQUARE_MARGIN

__all__ = [
    "check_law", "is_mean_square_stable", "mean_square_radius", "second_moment_adjoint", "second_moment_map",
    "second_moment_matrix",
]


def check_law(A: npt.ArrayLike, B: npt.ArrayLike, K: npt.ArrayLike,
              mu: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validated float arrays ``(A, B, K, mu)``: A n×n, B n×m, K m×n, mu of length m in [0, 1].

    Raises
    ------
    DimensionError, InputError
        Naming the array and the expected shape.
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
    """``L(S) = Abar S Abar' + B diag(mu (1 - mu) diag(K S K')) B'``: the module docstring's operator.

    Time O(n^3 + n^2 m). Arrays as returned by :func:`check_law`.

    >>> A, B, K = np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]])
    >>> float(second_moment_map(np.eye(1), A, B, K, np.array([0.5]))[0, 0])   # (2 - 1)^2 + 0.25 * 4
    2.0
    """
    Abar = A - (B * mu) @ K
    c = mu * (1.0 - mu) * np.einsum("ij,jk,ik->i", K, S, K)
    return Abar @ S @ Abar.T + (B * c) @ B.T


def second_moment_adjoint(P: np.ndarray, A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """The adjoint ``L*(P) = Abar' P Abar + K' diag(mu (1 - mu) diag(B' P B)) K`` (tr(P L(S)) = tr(L*(P) S)).

    It propagates cost-to-go matrices backwards. Time O(n^3 + n^2 m).
    """
    Abar = A - (B * mu) @ K
    c = mu * (1.0 - mu) * np.einsum("ji,jk,ki->i", B, P, B)
    return Abar.T @ P @ Abar + (K.T * c) @ K


def second_moment_matrix(A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """The n^2 x n^2 matrix of ``L`` on row-major ``vec(S)``: ``Abar ⊗ Abar + sum_i c_i F_i ⊗ F_i``,
    ``F_i = b_i k_i``, ``c_i = mu_i (1 - mu_i)``. Time O(n^4 m), memory 8 n^4 bytes: small n only.
    """
    Abar = A - (B * mu) @ K
    out = np.kron(Abar, Abar)
    for i, c in enumerate(mu * (1.0 - mu)):
        if c:
            F = np.outer(B[:, i], K[i])
            out += c * np.kron(F, F)
    return out


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
        ARPACK did not converge, or the operator is not finite.

    Examples
    --------
    >>> round(mean_square_radius([[2.0]], [[1.0]], [[2.0]], [0.5]), 12)   # scalar: (a - mu k)^2 + mu(1-mu)k^2
    2.0
    """
    A_, B_, K_, mu_ = check_law(A, B, K, mu)
    n = A_.shape[0]
    if method not in ("auto", "kronecker", "krylov"):
        raise InputError("method", f"expected auto, kronecker or krylov, found {method!r}")
    if not (np.all(np.isfinite(K_)) and np.all(np.isfinite(A_ - (B_ * mu_) @ K_))):
        raise NumericalError("mean-square radius: the closed-loop matrix A - B M K is not finite")
    if method == "kronecker" or (method == "auto" and n <= KRONECKER_MAX_N) or n * n < 8:
        with np.errstate(over="ignore", invalid="ignore"):
            vals = np.linalg.eigvals(second_moment_matrix(A_, B_, K_, mu_))
        if not np.all(np.isfinite(vals)):
            raise NumericalError("mean-square radius: the second-moment operator overflows")
        return float(np.max(np.abs(vals)))

    def apply(v: np.ndarray) -> np.ndarray:
        S = v.reshape(n, n)
        return second_moment_map(0.5 * (S + S.T), A_, B_, K_, mu_).ravel()

    # L is applied to the symmetric part: the Perron eigenvector is symmetric (PSD), and the skew
    # part's eigenvalues are dominated by it (a completely positive map attains its radius on the cone).
    op = LinearOperator((n * n, n * n), matvec=apply, dtype=float)
    k = min(6, n * n - 2)
    try:
        vals = eigs(op, k=k, which="LM", tol=ARPACK_TOL, v0=np.eye(n).ravel(), ncv=min(n * n, max(2 * k + 1, 20)),
                    maxiter=50 * n * n, return_eigenvectors=False)
    except (ArpackNoConvergence, ArpackError) as err:
        raise NumericalError(f"mean-square radius: ARPACK did not converge ({err}); try method='kronecker'") from None
    return float(np.max(np.abs(vals)))


def is_mean_square_stable(radius: float) -> bool:
    """True only when ``radius < 1 - MEAN_SQUARE_MARGIN``: a radius within the margin of one is not
    proved stable (the eigenvalue solvers agree to about 1e-12 relative)."""
    return bool(np.isfinite(radius) and radius < 1.0 - MEAN_SQUARE_MARGIN)
