"""Small linear-algebra helpers shared by the evaluators."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from functools import cache
from typing import TypeVar

import numpy as np

from .errors import NumericalError
from .tolerances import CONTROLLABILITY_RTOL, DENSE_RESIDUAL_RTOL, PSD_FACTOR_RTOL

__all__ = ["ControllableSplit", "Dyadic", "block_diagonal", "check_finite", "controllable_split", "exact_psd",
           "frobenius", "lapack", "lapack_dgesv", "power_growth", "psd_factor", "solve_checked", "typed_linalg"]

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
def lapack(name: str) -> Callable:
    """The LAPACK routine ``name`` of ``scipy.linalg.lapack`` (``"dpotrf"``, ``"dtrtrs"``, ``"dgeqrf"``, ...), imported
    on the first call, for the same reason as `lapack_dgesv`: on matrices of a few rows the f2py wrapper costs a
    fraction of the ``np.linalg`` one. O(1) after the first call for ``name``.

    Examples
    --------
    >>> c, info = lapack("dpotrf")(np.array([[4.0]]), lower=1)
    >>> float(c[0, 0]), info
    (2.0, 0)
    """
    from scipy.linalg import lapack as routines  # optional.LAZY_IMPORTS

    return getattr(routines, name)


@cache
def lapack_dgesv() -> Callable:
    """LAPACK's ``dgesv`` (``scipy.linalg.lapack``), imported on the first call: one small solve costs a quarter of
    what ``np.linalg.solve``'s stacked wrapper costs, but importing SciPy costs more than a short command's work,
    which the closed-form paths that never solve one small system alone do not pay (optional.LAZY_IMPORTS).
    O(1) after the first call.

    Examples
    --------
    >>> lu, piv, x, info = lapack_dgesv()(np.array([[2.0]]), np.array([[1.0]]))
    >>> float(x[0, 0]), info
    (0.5, 0)
    """
    from scipy.linalg.lapack import dgesv  # optional.LAZY_IMPORTS

    return dgesv


def psd_factor(W: np.ndarray) -> np.ndarray:
    """L with L'L = W for a symmetric PSD W (eigen-decomposition; zero rows dropped): a row factor, so that
    ``x'Wx = ||L x||^2`` (``cp.sum_squares(L @ x)``) and ``L'z`` draws N(0, W) for z ~ N(0, I). (The stability
    region's column factor of a PSD part, ``P+ = L L'``, is ``simulation.region.psd_part_factor``.)

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


#: ``np.linalg.norm``'s Frobenius norm squares the entries: below about 1e-154 the squares underflow (a matrix of
#: 1e-200 entries has norm 0.0), above about 1e154 they overflow (inf). Between these it is used as it is.
_SQUARES_SAFE = (1e-150, 1e150)


def frobenius(X: np.ndarray) -> float:
    """The Frobenius norm of ``X`` at every scale: ``np.linalg.norm(X)`` where its squares neither underflow nor
    overflow (the same float), else ``s ||X / s||`` with ``s = max|X|`` (as LAPACK's dnrm2 scales). 0 for a zero
    or empty array; inf or nan where X holds them. O(X.size).

    Examples
    --------
    >>> X = np.array([[3e-200, 0.0], [0.0, 4e-200]])
    >>> float(np.linalg.norm(X)), frobenius(X)          # the squares underflow: 0.0 against 5e-200
    (0.0, 5e-200)
    >>> frobenius(1e200 * np.ones((2, 2))), frobenius(np.array([[3.0, 4.0]]))
    (2e+200, 5.0)
    """
    X = np.asarray(X, dtype=float)
    with np.errstate(over="ignore", under="ignore"):
        value = float(np.linalg.norm(X))
    if _SQUARES_SAFE[0] <= value <= _SQUARES_SAFE[1]:
        return value
    s = float(np.abs(X).max(initial=0.0))
    if s == 0.0 or not np.isfinite(s):
        return s                        # 0, inf, or nan (max propagates nan)
    return s * float(np.linalg.norm(X / s))


def check_finite(name: str, arr: np.ndarray | float,
                 why: str = "the dense prediction of an unstable plant over a long horizon",
                 advice: str = "use method='recursion'") -> np.ndarray | float:
    """Return ``arr``, or raise [`NumericalError`][packetloss_cvx.errors.NumericalError] saying that ``name``
    overflowed, ``why``, and the ``advice``.

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
    that did not converge, a singular solve) raised as [`NumericalError`][packetloss_cvx.errors.NumericalError] naming
    ``what``, never untyped and never taken for an answer. O(1).

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

    Time O(k^3) for a k×k ``G``. Raises [`NumericalError`][packetloss_cvx.errors.NumericalError] naming ``name`` and
    ``instead``.

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

    Examples
    --------
    >>> split = controllable_split(np.diag([0.5, 2.0]), np.array([[1.0], [0.0]]))   # the second mode is not reached
    >>> split.nc, split.A_cc.tolist(), split.A_uu.tolist(), split.B_c.tolist()
    (1, [[0.5]], [[2.0]], [[1.0]])
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


@dataclass(frozen=True)
class Dyadic:
    """A matrix of dyadic rationals held exactly: ``ints * 2**exp`` with Python integers (an object array).

    Every finite double is a dyadic rational, so the arrays a computation starts from (A, B, mu, a certificate)
    convert without error, and sums and products of dyadics are dyadics: a certificate's inequality can be
    re-checked in exact arithmetic on the very numbers it was computed from. Time: a product of n×n matrices is
    O(n^3) integer operations on numbers of O(n (53 + exponent spread)) bits.

    Examples
    --------
    >>> x = Dyadic.of(np.array([[0.1, 3.0]]))          # 0.1 is not 1/10 but the double nearest it, exactly
    >>> (x @ x.T).fraction(0, 0) == Fraction(0.1) ** 2 + 9
    True
    """

    ints: np.ndarray
    exp: int

    @classmethod
    def of(cls, x: np.ndarray | float) -> Dyadic:
        """The exact value of a finite float array (NumericalError on inf or nan). O(size)."""
        x = np.asarray(x, dtype=float)
        if not np.all(np.isfinite(x)):
            raise NumericalError("exact arithmetic: an entry is not finite")
        flat = x.reshape(-1)
        mant, e = np.frexp(flat)
        ints = (mant * 2.0 ** 53).astype(np.int64)
        e = e.astype(np.int64) - 53
        nonzero = ints != 0
        low = int(e[nonzero].min()) if np.any(nonzero) else 0
        out = np.empty(flat.size, dtype=object)
        out[:] = [int(v) << int(k - low) if v else 0 for v, k in zip(ints.tolist(), e.tolist(), strict=True)]
        return cls(out.reshape(x.shape), low)

    def _aligned(self, other: Dyadic) -> tuple[np.ndarray, np.ndarray, int]:
        low = min(self.exp, other.exp)
        return self.ints * (1 << (self.exp - low)), other.ints * (1 << (other.exp - low)), low

    def __add__(self, other: Dyadic) -> Dyadic:
        a, b, low = self._aligned(other)
        return Dyadic(a + b, low)

    def __sub__(self, other: Dyadic) -> Dyadic:
        a, b, low = self._aligned(other)
        return Dyadic(a - b, low)

    def __neg__(self) -> Dyadic:
        return Dyadic(-self.ints, self.exp)

    def __mul__(self, other: Dyadic) -> Dyadic:
        """Elementwise, with NumPy's broadcasting."""
        return Dyadic(self.ints * other.ints, self.exp + other.exp)

    def __matmul__(self, other: Dyadic) -> Dyadic:
        return Dyadic(self.ints @ other.ints, self.exp + other.exp)

    @property
    def T(self) -> Dyadic:
        return Dyadic(self.ints.T, self.exp)

    def diag(self) -> Dyadic:
        """The diagonal of a square matrix as a vector, or the diagonal matrix of a vector."""
        if self.ints.ndim == 1:
            out = np.zeros((self.ints.size, self.ints.size), dtype=object)
            out[np.arange(self.ints.size), np.arange(self.ints.size)] = self.ints
            return Dyadic(out, self.exp)
        return Dyadic(np.array(np.diagonal(self.ints)), self.exp)

    def outer(self, other: Dyadic) -> Dyadic:
        """The outer product of two vectors."""
        return Dyadic(np.multiply.outer(self.ints, other.ints), self.exp + other.exp)

    def fraction(self, *index: int) -> Fraction:
        """One entry as a Fraction."""
        return Fraction(int(self.ints[index])) * Fraction(2) ** self.exp

    @staticmethod
    def block(rows: list[list[Dyadic]]) -> Dyadic:
        """The block matrix of dyadic blocks (np.block on their aligned integers)."""
        low = min(b.exp for row in rows for b in row)
        return Dyadic(np.block([[b.ints * (1 << (b.exp - low)) for b in row] for row in rows]), low)


def exact_psd(M: Dyadic, strict: bool = False) -> bool:
    """Is the symmetric matrix M positive semidefinite (``strict``: definite), decided exactly?

    Symmetric elimination in integers (Bareiss: every division exact, each entry after k steps the determinant of
    a (k+1)×(k+1) submatrix, over the product of nothing but positive pivots), pivoting on a positive diagonal entry:
    M is PSD iff no diagonal entry of a Schur complement is negative and the complement left when none is positive
    is zero (PD: n positive pivots). A matrix that is not exactly symmetric is not PSD here. Time O(n^3) integer
    operations.

    Examples
    --------
    >>> exact_psd(Dyadic.of(np.array([[1.0, 1.0], [1.0, 1.0]]))), exact_psd(Dyadic.of(np.ones((2, 2))), strict=True)
    (True, False)
    >>> exact_psd(Dyadic.of(np.array([[1.0, 0.5], [0.5, 0.25 - 2.0 ** -50]])))   # determinant -2^-50
    False
    """
    a = [[int(v) for v in row] for row in np.asarray(M.ints)]
    n = len(a)
    if any(a[i][j] != a[j][i] for i in range(n) for j in range(i)):
        return False
    active = list(range(n))
    previous = 1
    while active:
        diagonal = [a[i][i] for i in active]
        if min(diagonal) < 0:
            return False
        p = max(active, key=lambda i: a[i][i])
        pivot = a[p][p]
        if pivot == 0:                               # a PSD matrix with a zero diagonal is zero
            return not strict and all(a[i][j] == 0 for i in active for j in active)
        active.remove(p)
        row = a[p]                                   # row and column p are no longer updated
        for i in active:
            ai, aip = a[i], a[i][p]
            for j in active:
                ai[j] = (pivot * ai[j] - aip * row[j]) // previous
        previous = pivot
    return True
