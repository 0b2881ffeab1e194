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

from collections.abc import Callable, Iterable

import numpy as np
import numpy.typing as npt

from ..errors import DimensionError, InputError, NumericalError
from ..model.system import numeric_array
from ..tolerances import ARPACK_TOL, KRONECKER_MAX_N, MEAN_SQUARE_MARGIN

#: above this entry size, A and K are scaled down before the radius is computed (exactly: L is quadratic)
RADIUS_RESCALE = 1e100

__all__ = [
    "check_law", "is_mean_square_stable", "law_radius", "mean_square_radius", "random_matrix_moment",
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
    (:func:`second_moment_step` applied once).

    Time O(n^3 + n^2 m). Arrays as returned by :func:`check_law`.

    >>> A, B, K = np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]])
    >>> float(second_moment_map(np.eye(1), A, B, K, np.array([0.5]))[0, 0])   # (2 - 1)^2 + 0.25 * 4
    2.0
    """
    return second_moment_step(A, B, K, mu)(S)


def second_moment_step(A: np.ndarray, B: np.ndarray, K: np.ndarray,
                       mu: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``S -> L(S)`` (:func:`second_moment_map`) for one law, its parts that do not depend on S (``Abar`` and
    ``mu (1 - mu)``) formed once: a caller applying one law many times (a finite horizon, a fixed-point or power
    iteration) pays O(n^2 m) once instead of every step; the same floats as :func:`second_moment_map`. Time
    O(n^2 m) to build, O(n^3 + n^2 m) per application.

    >>> step = second_moment_step(np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0.5]))
    >>> float(step(np.eye(1))[0, 0]), float(step(2 * np.eye(1))[0, 0])      # L is linear: 2, then 4
    (2.0, 4.0)
    """
    Abar = A - (B * mu) @ K
    variance = mu * (1.0 - mu)

    def apply(S: np.ndarray) -> np.ndarray:
        c = variance * np.einsum("ij,jk,ik->i", K, S, K)
        return Abar @ S @ Abar.T + (B * c) @ B.T

    return apply


def second_moment_adjoint(P: np.ndarray, A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """The adjoint ``L*(P) = Abar' P Abar + K' diag(mu (1 - mu) diag(B' P B)) K`` (tr(P L(S)) = tr(L*(P) S)).

    It propagates cost-to-go matrices backwards. Time O(n^3 + n^2 m).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> A, B, K, mu = rng.normal(size=(2, 2)), rng.normal(size=(2, 1)), rng.normal(size=(1, 2)), np.array([0.3])
    >>> P, S = np.diag([1.0, 2.0]), np.array([[2.0, 0.5], [0.5, 1.0]])
    >>> lhs = np.trace(P @ second_moment_map(S, A, B, K, mu))
    >>> bool(np.isclose(lhs, np.trace(second_moment_adjoint(P, A, B, K, mu) @ S)))
    True
    """
    Abar = A - (B * mu) @ K
    c = mu * (1.0 - mu) * np.einsum("ji,jk,ki->i", B, P, B)
    return Abar.T @ P @ Abar + (K.T * c) @ K


def second_moment_matrix(A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """The n^2 x n^2 matrix of ``L`` on row-major ``vec(S)``: ``Abar ⊗ Abar + sum_i c_i F_i ⊗ F_i``,
    ``F_i = b_i k_i``, ``c_i = mu_i (1 - mu_i)`` (:func:`random_matrix_moment`). A stack of laws: K (..., m, n)
    with mu (..., m) gives (..., n^2, n^2). Time O(n^4 m) per law, memory 8 n^4 bytes: small n only.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> A, B, K, mu = rng.normal(size=(2, 2)), rng.normal(size=(2, 2)), rng.normal(size=(2, 2)), np.array([0.3, 0.8])
    >>> S = np.array([[2.0, 0.5], [0.5, 1.0]])
    >>> bool(np.allclose(second_moment_matrix(A, B, K, mu) @ S.ravel(), second_moment_map(S, A, B, K, mu).ravel()))
    True
    """
    Abar = A - (B * mu[..., None, :]) @ K
    return random_matrix_moment(Abar, (B[:, i, None] * K[..., i, None, :] for i in range(B.shape[1])), mu * (1.0 - mu))


def random_matrix_moment(mean: np.ndarray, directions: Iterable[np.ndarray], variances: np.ndarray) -> np.ndarray:
    """The d^2 x d^2 matrix of ``S -> E[F S F']`` on row-major ``vec(S)`` for the random matrix
    ``F = mean + sum_i (z_i - E z_i) D_i`` with independent scalars ``z_i`` of variances ``c_i``:
    ``mean ⊗ mean + sum_i c_i D_i ⊗ D_i`` (the cross terms vanish). The operator of :func:`second_moment_map`
    is the case ``D_i = b_i k_i``; the loop with an estimated state (``sensing.loop``) averages it over the
    sensor's arrival patterns. A stack: ``mean`` and each ``D_i`` (..., d, d), ``variances`` (..., k). Time O(d^4)
    per direction, memory 8 d^4 bytes.

    >>> M = random_matrix_moment(np.array([[1.0]]), [np.array([[2.0]])], np.array([0.25]))
    >>> float(M[0, 0])          # 1 + 0.25 * 4
    2.0
    """
    out = _kron(mean, mean)
    for D, c in zip(directions, np.moveaxis(np.asarray(variances), -1, 0), strict=True):
        if np.any(c):
            out += np.asarray(c)[..., None, None] * _kron(D, D)
    return out


def _kron(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.kron`` of the last two axes, over a stack (the same products: 2-D inputs give np.kron's bits)."""
    a, b = np.asarray(a), np.asarray(b)
    outer = a[..., :, None, :, None] * b[..., None, :, None, :]
    return outer.reshape(*outer.shape[:-4], a.shape[-2] * b.shape[-2], a.shape[-1] * b.shape[-1])


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
    """:func:`mean_square_radius` of a law already checked (the arrays :func:`check_law` returns): a caller that
    checked it once (simulation.moments.closed_loop) does not check it again, and ``matrix`` gives the law's
    :func:`second_moment_matrix` when the caller keeps it for its moment solves too (built once). Time as
    :func:`mean_square_radius`.

    >>> A, B, K, mu = check_law([[2.0]], [[1.0]], [[2.0]], [0.5])
    >>> round(law_radius(A, B, K, mu), 12)                      # (a - mu k)^2 + mu (1 - mu) k^2
    2.0
    """
    n = A_.shape[0]
    if method not in ("auto", "kronecker", "krylov"):
        raise InputError("method", f"expected auto, kronecker or krylov, found {method!r}")
    if not (np.all(np.isfinite(K_)) and np.all(np.isfinite(A_ - (B_ * mu_) @ K_))):
        raise NumericalError("mean-square radius: the closed-loop matrix A - B M K is not finite")
    scale = max(float(np.abs(A_).max()), float(np.abs(B_).max() * np.abs(K_).max()))
    if scale > RADIUS_RESCALE:   # L is quadratic in (A, K): radius(A, K) = c^2 radius(A / c, K / c), no overflow
        with np.errstate(over="ignore"):
            return scale * scale * mean_square_radius(A_ / scale, B_, K_ / scale, mu_, method=method)
    if method == "kronecker" or (method == "auto" and n <= KRONECKER_MAX_N) or n * n < 8:
        with np.errstate(over="ignore", invalid="ignore"):
            matrix = second_moment_matrix(A_, B_, K_, mu_) if matrix is None else matrix()
            try:
                vals = np.linalg.eigvals(matrix) if np.all(np.isfinite(matrix)) else np.array([np.inf])
            except np.linalg.LinAlgError:
                raise NumericalError("mean-square radius: the eigenvalues of the second-moment operator did not "
                                     "converge") from None
        if not np.all(np.isfinite(vals)):
            raise NumericalError("mean-square radius: the second-moment operator overflows")
        return float(np.max(np.abs(vals)))

    from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, LinearOperator, eigs  # optional.LAZY_IMPORTS

    upper = _power_bound(A_, B_, K_, mu_, int(min(20 * n, 400, max(40, 4e10 // n ** 3))))
    if upper == 0.0:
        return 0.0   # L^k(I) = 0: L vanishes on the PSD cone, hence on every symmetric matrix

    step = second_moment_step(A_, B_, K_, mu_)

    def apply(v: np.ndarray) -> np.ndarray:
        S = v.reshape(n, n)
        return step(0.5 * (S + S.T)).ravel()

    # L is applied to the symmetric part: the Perron eigenvector is symmetric (PSD), and the skew
    # part's eigenvalues are dominated by it (a completely positive map attains its radius on the cone).
    op = LinearOperator((n * n, n * n), matvec=apply, dtype=float)
    k = min(6, n * n - 2)
    try:
        vals, vecs = eigs(op, k=k, which="LM", tol=ARPACK_TOL, v0=np.eye(n).ravel(),
                          ncv=min(n * n, max(2 * k + 1, 20)), maxiter=max(300, 10 * n))
    except (ArpackNoConvergence, ArpackError) as err:
        failure = f"ARPACK did not converge ({err})"
    else:
        top = int(np.argmax(np.abs(vals)))
        radius = float(abs(vals[top]))
        lower, bound = _cone_bounds(vecs[:, top], A_, B_, K_, mu_)
        upper = min(upper, bound)
        if lower * (1.0 - 1e-9) <= radius <= upper * (1.0 + 1e-9):
            return radius
        failure = f"ARPACK's {radius:.6g} lies outside the proven bounds [{lower:.6g}, {upper:.6g}]"
    # a defective (Jordan) Perron root, which Arnoldi resolves only to about eps^(1/size), or a slow
    # convergence: the Kronecker matrix is exact where it fits
    if n <= 2 * KRONECKER_MAX_N:
        return mean_square_radius(A_, B_, K_, mu_, method="kronecker")
    raise NumericalError(f"mean-square radius: {failure}; the radius is at most {upper:.6g}")


def _cone_bounds(vec: np.ndarray, A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray) -> tuple[float, float]:
    """Collatz–Wielandt bounds from a positive definite X near the Perron eigenvector: with
    ``R = X^(-1/2) L(X) X^(-1/2)``, ``L(X) >= lambda_min(R) X`` and ``L(X) <= lambda_max(R) X``, so the radius
    lies in ``[lambda_min(R), lambda_max(R)]`` (a positive map; X > 0 makes both proofs hold). Time O(n^3)."""
    n = A.shape[0]
    v = vec * np.exp(-1j * np.angle(vec[np.argmax(np.abs(vec))]))
    X = v.real.reshape(n, n)
    X = 0.5 * (X + X.T)
    X = X if np.trace(X) >= 0 else -X
    w, U = np.linalg.eigh(X)
    w = np.maximum(w, 1e-10 * max(float(w.max()), np.finfo(float).tiny))   # PSD part, made definite
    root_inv = (U / np.sqrt(w)) @ U.T
    Y = second_moment_map((U * w) @ U.T, A, B, K, mu)
    r = np.linalg.eigvalsh(0.5 * (root_inv @ Y @ root_inv + (root_inv @ Y @ root_inv).T))
    return max(float(r[0]), 0.0), float(r[-1])


def _power_bound(A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray, steps: int) -> float:
    """``min_k ||L^k(I)||_2^(1/k)`` over k = 1..steps: an upper bound on the radius (for a positive map the
    induced norm is attained at I, Russo–Dye, and rho <= ||L^k||^(1/k)). Time O(steps (n^3 + n^2 m))."""
    X, log_scale, best = np.eye(A.shape[0]), 0.0, np.inf
    step = second_moment_step(A, B, K, mu)
    for k in range(1, steps + 1):
        X = step(X)
        size = float(np.linalg.norm(X, 2))
        if size == 0.0:
            return 0.0
        log_scale += np.log(size)
        X /= size
        best = min(best, float(np.exp(log_scale / k)))
    return best


def is_mean_square_stable(radius: float) -> bool:
    """True only when ``radius < 1 - MEAN_SQUARE_MARGIN``: a radius within the margin of one is not
    proved stable (the eigenvalue solvers agree to about 1e-12 relative).

    Examples
    --------
    >>> is_mean_square_stable(0.5), is_mean_square_stable(1.0 - 1e-15), is_mean_square_stable(np.nan)
    (True, False, False)
    """
    return bool(np.isfinite(radius) and radius < 1.0 - MEAN_SQUARE_MARGIN)
