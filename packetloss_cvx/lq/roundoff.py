"""Running error bounds of a rolled-out plan: how far the computed mean states of a fixed plan, and the quadratic
cost of those states, can be from the exact ones.

A plan U rolled forward in floating point, ``x_{t+1} = A x_t + B (mu_t u_t)``, commits a rounding error
``delta_t`` at every step, and the exact error ``e_t = xhat_t - x_t`` obeys ``e_{t+1} = A e_t + delta_t``: an
unstable A amplifies it like A^t, while the states themselves may stay small (a plan that steers the state
to zero cancels the open-loop growth ``A^t x0`` against its inputs' contributions). Nothing in the forward
pass notices: its sum has no cancellation, but its states are not the plan's states. The bound here is
a posteriori, in three parts:

* the residuals ``delta_t = xhat_{t+1} - A xhat_t - B (mu_t u_t)`` of the computed states, evaluated in twice
  the working precision by error-free transformations (`two_product`, `two_sum`; Ogita, Rump and
  Oishi's Dot2), so that they are known to about u^2, not merely bounded by gamma_n |A||xhat| (Higham,
  *Accuracy and Stability of Numerical Algorithms*, 2nd ed., §3.1);
* the state error itself, ``ehat = sum_s A^{t-s} delta_s`` rolled out in double (`linear_scan`), whose own
  rounding is bounded componentwise through its residuals and propagated by nonnegative matrices
  (`propagation_bound`): by |A|, or, where |A| grows faster than A (a rotation), in a complex Schur basis
  ``A = Z T Z^H``, where |T| has A's spectral radius;
* the cost: ``J(xhat) - J(x) = sum_t (2 xhat_t - e_t)' Q_t e_t``, evaluated at ``ehat`` plus what the remaining
  error ``|e - ehat| <= eta`` can add.

The result is close to the true error where the plan's cost is resolved (it is mostly the computed error
estimate itself) and refuses only where the rounding really moves the cost. Time O(points N n (n + m) + points N L n^2)
with a block of L = 32 steps; no Python loop over the steps.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["SCAN_BLOCK", "UNIT_ROUNDOFF", "gamma", "linear_scan", "propagation_bound", "rollout_cost_error",
           "step_residuals", "two_product", "two_sum"]

#: u = 2^-53, the unit roundoff of IEEE double precision (round to nearest)
UNIT_ROUNDOFF = float(np.finfo(float).eps) / 2.0
#: the smallest subnormal number, 2^-1074: the absolute error of one operation whose result underflows
_SUBNORMAL = float(np.finfo(float).smallest_subnormal)
#: Veltkamp's splitting constant 2^27 + 1 for double precision
_SPLITTER = 134217729.0
#: the steps of one block of :func:`linear_scan` (a (L n)×(L n) Toeplitz product per block; the blocks' ends
#: carried by a scan)
SCAN_BLOCK = 32


def gamma(k: float) -> float:
    """Higham's ``gamma_k = k u / (1 - k u)``: the relative error bound of k roundings (inf from k u >= 1/2). O(1).

    Examples
    --------
    >>> gamma(0), gamma(1) > UNIT_ROUNDOFF, gamma(2**52)
    (0.0, True, inf)
    """
    ku = k * UNIT_ROUNDOFF
    return ku / (1.0 - ku) if ku < 0.5 else math.inf


def two_sum(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Knuth's error-free sum: ``s = fl(a + b)`` and ``e`` with ``a + b = s + e`` exactly (no overflow). Each
    NumPy operation is one correctly rounded IEEE operation, whatever the SIMD width. O(size).

    Examples
    --------
    >>> s, e = two_sum(np.array([1.0]), np.array([2.0**-60]))
    >>> s.tolist(), e.tolist() == [2.0**-60]
    ([1.0], True)
    """
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _split(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Veltkamp's split ``a = hi + lo`` into halves of at most 26 significant bits each. O(size)."""
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


def two_product(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Dekker's error-free product: ``p = fl(a b)`` and ``e`` with ``a b = p + e`` exactly (no FMA needed; exact
    unless the product underflows or |a|, |b| exceed about 1e299, where the split overflows to inf or NaN). O(size).

    Examples
    --------
    >>> p, e = two_product(np.array([1.0 + 2.0**-30]), np.array([1.0 + 2.0**-30]))
    >>> p.tolist() == [1.0 + 2.0**-29], e.tolist() == [2.0**-60]
    (True, True)
    """
    p = a * b
    ah, al = _split(a)
    bh, bl = _split(b)
    return p, al * bl - (((p - ah * bh) - al * bh) - ah * bl)


def step_residuals(A: np.ndarray, B: np.ndarray, prev: np.ndarray, nxt: np.ndarray, mu: np.ndarray,
                   U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The residuals ``delta_t = nxt_t - A prev_t - B (mu_t u_t)`` of computed states (mu u the exact product),
    in twice the working precision (Dot2 of Ogita, Rump and Oishi, 2005: every product split exactly, the sum
    compensated), and a bound on their own error: ``|delta - delta_hat| <= 2u |delta_hat| + gamma_{2K}^2 (|nxt|
    + |A||prev| + |B||mu u|) + 8 K 2^-1074`` with K = 1 + n + 2m terms a row (the last term for underflow).
    prev, nxt (points, N, n); mu (points or 1, N, m); U (points, N, m). Non-finite where a state is beyond about 1e299.
    O(points N n (n + m)).

    Examples
    --------
    >>> A, B = np.array([[0.1]]), np.array([[1.0]])
    >>> prev, nxt = np.array([[[1.0]]]), np.array([[[0.1 + 0.3]]])     # 0.1 * 1.0 + 0.3 in double
    >>> delta, err = step_residuals(A, B, prev, nxt, np.ones((1, 1, 1)), np.full((1, 1, 1), 0.3))
    >>> from fractions import Fraction as F
    >>> exact = F(0.1 + 0.3) - F(0.1) - F(0.3)                     # the rounding of that one step
    >>> abs(F(float(delta[0, 0, 0])) - exact) <= F(float(err[0, 0, 0])), float(delta[0, 0, 0]) != 0.0
    (True, True)
    """
    n, m = B.shape
    with np.errstate(all="ignore"):
        z, ze = two_product(mu, U)                                   # mu u = z + ze exactly
        s = nxt.copy()
        c = np.zeros_like(s)
        size = np.abs(nxt) + np.abs(prev) @ np.abs(A).T + np.abs(z) @ np.abs(B).T
        for j in range(n):
            p, pe = two_product(-A[:, j], prev[..., j, None])
            s, se = two_sum(s, p)
            c += se + pe
        for k in range(m):
            p, pe = two_product(-B[:, k], z[..., k, None])
            s, se = two_sum(s, p)
            c += se + pe - B[:, k] * ze[..., k, None]
        delta = s + c
        K = 1 + n + 2 * m
        err = 2.0 * UNIT_ROUNDOFF * np.abs(delta) + gamma(2 * K) ** 2 * size + 8 * K * _SUBNORMAL
    return delta, err


def linear_scan(M: np.ndarray, S: np.ndarray, block: int = SCAN_BLOCK) -> np.ndarray:
    """``y_t = M y_{t-1} + S_t`` from ``y_{-1} = 0`` for every t, S (points, N, n): in blocks of ``block`` steps, each
    one product with the block's Toeplitz matrix of the powers M^0..M^{L-1}, the blocks' ends carried by the same
    scan of M^L over the N / L blocks (recursively: O(log N) NumPy calls, no Python loop over the steps). The
    rounding differs from the step-by-step recursion's: callers bound what they use through its residuals, or (M
    and S nonnegative) by the relative error of nonnegative sums. O(points N L n^2).

    Examples
    --------
    >>> linear_scan(np.array([[0.5]]), np.ones((1, 5, 1)), block=2).ravel().tolist()   # 1, 1.5, 1.75, ...
    [1.0, 1.5, 1.75, 1.875, 1.9375]
    """
    points, N, n = S.shape
    L = max(1, min(block, N))
    nb = -(-N // L)
    with np.errstate(all="ignore"):
        powers = _powers(M, L)
        lag = np.arange(L)[:, None] - np.arange(L)[None, :]          # j - i
        toeplitz = np.where((lag >= 0)[:, :, None, None], powers[np.clip(lag, 0, L)], 0.0)   # (L, L, n, n)
        big = toeplitz.transpose(0, 2, 1, 3).reshape(L * n, L * n)   # row (j, a), column (i, b)
        padded = np.zeros((points, nb * L, n))
        padded[:, :N] = S
        Y = (padded.reshape(points * nb, L * n) @ big.T).reshape(points, nb, L, n)
        if nb > 1:                    # y at the end of block k - 1 obeys the same recursion, with M^L, over blocks
            carry = np.zeros((points, nb, n))
            carry[:, 1:] = linear_scan(powers[L], np.ascontiguousarray(Y[:, :-1, L - 1]), block)
            Y += np.einsum("jab,pkb->pkja", powers[1:], carry)
    return Y.reshape(points, nb * L, n)[:, :N]


def _powers(M: np.ndarray, L: int) -> np.ndarray:
    """M^0..M^L (L + 1, n, n) by doubling: M^{j + k} = M^j M^k for j = 1..k, log2(L) stacked products. O(L n^3)."""
    n = M.shape[0]
    powers = np.empty((L + 1, n, n))
    powers[0] = np.eye(n)
    powers[1:2] = M
    k = 1
    while k < L:
        j = min(k, L - k)
        np.matmul(powers[1:j + 1], powers[k], out=powers[k + 1:k + j + 1])
        k += j
    return powers


def _abs_basis(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """|A| as the propagator of |e_{t+1}| <= |A| |e_t| + r_t, with identity injection and read-out. O(n^2)."""
    eye = np.eye(A.shape[0])
    return np.abs(A), eye, eye


def _schur_basis(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(|T| + phi, |Z^H| + zeta, |Z|)`` from the complex Schur form ``A = Z T Z^H`` (LAPACK through SciPy,
    imported here: optional.LAZY_IMPORTS): with Y = Z^{-1} exact, ``|Y A Z| <= |T| + phi`` and ``|Y| <= |Z^H| +
    zeta`` entrywise, phi and zeta bounding the factors' departure from an exact unitary similarity (computed
    residuals plus their own rounding). None where Z is too far from unitary to bound (never seen). O(n^3)."""
    from scipy.linalg import schur  # optional.LAZY_IMPORTS

    n = A.shape[0]
    T, Z = schur(A, output="complex")
    ZH = Z.conj().T
    aZ, aZH = np.abs(Z), np.abs(ZH)
    g = float(np.linalg.norm(ZH @ Z - np.eye(n))) + gamma(2 * n + 4) * float(np.linalg.norm(aZH @ aZ))
    if not g < 0.5:
        return None
    zeta = g * math.sqrt(1.0 + g) / (1.0 - g)                          # ||Z^{-1} - Z^H||_2
    phi = (zeta * float(np.linalg.norm(A)) * math.sqrt(1.0 + g) + float(np.abs(ZH @ A @ Z - T).max())
           + gamma(4 * n + 8) * float((aZH @ np.abs(A) @ aZ).max()))
    return np.abs(T) + phi, aZH + zeta, aZ


def propagation_bound(A: np.ndarray, r: np.ndarray, schur: bool = False) -> np.ndarray:
    """A componentwise bound ``eta_t >= |sum_{s<=t} A^{t-s} rho_s|`` for every rho with ``|rho_s| <= r_s`` (r
    (points, N, n) nonnegative): the recursion ``b_t = M b_{t-1} + J r_t`` of nonnegative matrices, read out as
    ``eta = O b``, with ``(M, J, O) = (|A|, I, I)``, or (``schur``) the complex Schur basis of A, where the growth
    of M is A's own (|A| grows faster than A wherever A rotates). Inflated by ``1 + gamma_{4 (N + 2L)(n + 2)}``
    for the rounding of its own nonnegative sums; inf where it overflows. O(points N L n^2) (`linear_scan`).

    Examples
    --------
    >>> r = np.full((1, 3, 1), 1e-16)                          # |rho_s| <= 1e-16 propagated by A = -2
    >>> [round(v / 1e-16, 9) for v in propagation_bound(np.array([[-2.0]]), r).ravel().tolist()]     # 1, 3, 7
    [1.0, 3.0, 7.0]
    """
    points, N, n = r.shape
    basis = _schur_basis(A) if schur else None
    M, inject, read = basis if basis is not None else _abs_basis(A)
    with np.errstate(all="ignore"):
        b = linear_scan(M, r @ inject.T)
        eta = (b @ read.T) * (1.0 + gamma(4 * (N + 2 * SCAN_BLOCK) * (n + 2)))
    return np.where(np.isnan(eta), np.inf, eta)


def _weighted(a: np.ndarray, Q: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``sum_t a_t' Q_t b_t`` per point: a, b (points, N, n); Q (n, n) for every step or (N, n, n). O(points N n^2)."""
    if Q.ndim == 2:
        return np.einsum("ptj,ptj->p", a @ Q, b)
    return np.einsum("pti,tij,ptj->p", a, Q, b)


def rollout_cost_error(A: np.ndarray, B: np.ndarray, mu: np.ndarray, U: np.ndarray, x0: np.ndarray,
                       X: np.ndarray, Q: np.ndarray, enough: np.ndarray | float = 0.0) -> np.ndarray:
    """A bound on ``|sum_t xhat_t' Q_t xhat_t - sum_t x_t' Q_t x_t|`` per plan: xhat_1..xhat_N the states X
    (points, N, n) computed from x0 (points, n) under the plans U (points, N, m) and channels mu (points or 1, N, m),
    x_t the exact states of those floats; Q (n, n) or (N, n, n) positive semidefinite. The estimate ehat of the state
    error (its residuals in twice the precision, `step_residuals`, rolled out by `linear_scan`) gives
    ``sum (2 xhat - ehat)' Q ehat``; to it is added what the remaining error ``|e - ehat| <= eta``
    (`propagation_bound` of ehat's residuals) can change, bounded in the |A| basis, and where that
    exceeds ``enough`` (points,) in the Schur basis too (the smaller bound is kept). inf where nothing is finite.
    O(points N n (n + m) + points N L n^2).

    Examples
    --------
    >>> from fractions import Fraction as F
    >>> A, B, x0, U = np.array([[3.0]]), np.array([[1.0]]), np.array([[0.1]]), np.full((1, 20, 1), -0.2)
    >>> X = np.empty((1, 20, 1)); x = x0[0]
    >>> for t in range(20):
    ...     x = X[0, t] = x @ A.T + U[0, t] @ B.T
    >>> xs, exact = F(0.1), F(0)                 # x_t = 0.1 exactly; the rolled-out xhat_t drift by 3^t
    >>> for t in range(20):
    ...     xs = 3 * xs + F(-0.2)
    ...     exact += xs * xs
    >>> rolled = sum(F(v) ** 2 for v in X.ravel())          # sum xhat_t^2, exactly
    >>> bound = rollout_cost_error(A, B, np.ones((1, 20, 1)), U, x0, X, np.eye(1))[0]
    >>> f"{float(abs(rolled - exact)):.3g}"                  # the rounding, amplified up to 3^20 = 3.5e9 times
    '9.68e-09'
    >>> abs(rolled - exact) <= F(float(bound)) <= 2 * abs(rolled - exact)       # holds, and is tight
    True
    """
    points, N, n = X.shape
    aQ = np.abs(Q)
    with np.errstate(all="ignore"):
        prev = np.concatenate([x0[:, None, :], X[:, :-1]], axis=1)
        delta, c = step_residuals(A, B, prev, X, mu, U)
        E = linear_scan(A, delta)                                   # ehat_t estimates e_{t+1} = xhat - x
        Eprev = np.concatenate([np.zeros((points, 1, n)), E[:, :-1]], axis=1)
        rho = (np.abs(E - (Eprev @ A.T + delta)) + gamma(n + 3) * (np.abs(E) + np.abs(Eprev) @ np.abs(A).T
               + np.abs(delta)) + c + (n + 3) * _SUBNORMAL)
        aX, aE = np.abs(X), np.abs(E)
        estimate = np.abs(_weighted(2.0 * X - E, Q, E))
        estimate += gamma(N * n + 2 * n + 6) * _weighted(2.0 * aX + aE, aQ, aE)

        def total(eta: np.ndarray) -> np.ndarray:
            bound = estimate + _weighted(2.0 * (aX + aE) + eta, aQ, eta)
            bound = bound * (1.0 + gamma(N * n + 2 * n + 6))
            return np.where(np.isnan(bound), np.inf, bound)

        bound = total(propagation_bound(A, rho))
        if not np.all(bound <= enough):
            bound = np.minimum(bound, total(propagation_bound(A, rho, schur=True)))
    return bound
