"""The closed-loop mode engine: second moments of linear laws behind channels with M modes.

A channel with M modes (the joint state of Markov channels, transition matrix T) delivers actuator i's packet
in mode a with probability h_{a,i}, the actuators independent given the mode. Under ``u = -K_a x`` the moments
``Q_a = E[x x' 1{mode = a}]`` follow, without noise,

.. math:: Q_b^+ = \\sum_a T_{ab}\\, E_{v|a}[(A - B V K_a) Q_a (A - B V K_a)'], \\qquad
   E_{v|a}[G Q G'] = \\bar A_a Q \\bar A_a' + B\\, \\mathrm{diag}(h_a (1 - h_a) \\circ \\mathrm{diag}(K_a Q K_a'))\\, B'

with ``Abar_a = A - B H_a K_a`` (``delivery="current"``: the gain and the deliveries follow the mode a). With
``delivery="next"`` the deliveries follow the mode b the chain moves to (``E_{v|b}``; the TCP-like law of a
Gilbert channel, whose acknowledgement reveals the last state). The loop is mean-square stable iff the
spectral radius of this map is below one (Costa, Fragoso, Marques 2005, Thm 3.9).

A Bernoulli channel is the one-mode chain: every function here takes ``T=None`` for it, with no mode axis
(K (m, n), h = mu (m,), Q (n, n)), and is then the operator of `packetloss_cvx.closedloop.stability`.

The plant may differ per mode (A (M, n, n), CFM05's ``A_a``; ``delivery="current"``): a loop whose mode also
carries what the actuator does on a loss (`packetloss_cvx.closedloop.actuator`: the held input, the age of a
buffered plan) is this engine over an augmented state, its applied input ``F_a x - V K_a x`` (``F`` the input
applied whatever the delivery, `mode_stage_costs`'s ``held``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np

from ..budgets import BUDGETS, check, gib_text, krylov_bytes, limit
from ..errors import InputError, NumericalError
from ..tolerances import ARPACK_TOL, KRONECKER_MAX_N

__all__ = [
    "DENSE_MAX_DIM", "MAX_OPERATOR_DIM", "RADIUS_RESCALE", "delivery_moments", "mode_adjoint_step", "mode_matrix",
    "mode_radius", "mode_stage_costs", "mode_step", "random_matrix_moment",
]

#: Rows M n^2 of the dense operator beyond which the dense route is not taken as a fallback (and the chains' dense
#: operator is refused, closedloop.mjls.check_operator_size): its eigenvalues take O((M n^2)^3) time and
#: 16 (M n^2)^2 bytes (2048 rows: 64 MiB, a few seconds). The default of the ``operator_rows`` budget
#: (budgets.py; ``PACKETLOSS_CVX_BUDGET_OPERATOR_ROWS`` raises it).
MAX_OPERATOR_DIM = int(BUDGETS["operator_rows"].default)
#: Rows up to which :func:`mode_radius` takes the dense eigenvalues by default (above: matrix-free Krylov): 400, for
#: one mode n <= tolerances.KRONECKER_MAX_N.
DENSE_MAX_DIM = KRONECKER_MAX_N ** 2
#: above this entry size, A and K are scaled down before the radius is computed (exactly: the map is quadratic)
RADIUS_RESCALE = 1e100

Step = Callable[[np.ndarray], np.ndarray]


def delivery_moments(h: np.ndarray) -> np.ndarray:
    """``E[v v' | mode] = h h' + diag(h (1 - h))`` per mode (independent channels), (M, m, m). O(M m^2).

    Examples
    --------
    >>> delivery_moments(np.array([[0.5, 1.0]])).tolist()     # h h' + diag(h (1 - h))
    [[[0.5, 0.5], [0.5, 1.0]]]
    """
    return h[:, :, None] * h[:, None, :] + np.einsum("ai,ij->aij", h * (1 - h), np.eye(h.shape[1]))


def mode_step(A: np.ndarray, B: np.ndarray, K: np.ndarray, h: np.ndarray, T: np.ndarray | None = None,
              delivery: str = "current") -> Step:
    """``Q -> Q+``: one noise-free step of the module docstring's map for one law, its parts that do not depend on
    Q formed once. Linear in Q (a non-symmetric Q too, so that rounding's skew part decays with the loop).

    ``T=None``: one mode (Bernoulli, ``h = mu``), K (m, n), Q (n, n). With T (a, M): K (a, m, n) per information
    mode a (the gain's mode), Q (a, n, n); ``"current"``: h (a, m), ``Q+_b = sum_a T_ab E_{v|a}[..]``; ``"next"``:
    h (M, m), ``Q+_b = sum_a T_ab E_{v|b}[..]``. Time O(a (n^3 + n^2 m) + a M n^2) per application.

    Examples
    --------
    >>> step = mode_step(np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0.5]))
    >>> step(np.eye(1)).tolist()                       # (2 - 1)^2 + 0.25 * 4
    [[2.0]]
    >>> one = np.ones((1, 1))                          # one mode of a chain: the same map
    >>> mode_step(2 * one, one, 2 * one[None], np.array([[0.5]]), one)(one[None]).tolist()
    [[[2.0]]]
    """
    if delivery == "next":
        return _next_step(A, B, K, h, T)
    if delivery != "current":
        raise InputError("delivery", f"expected current or next, found {delivery!r}")
    Abar = A - (B * (h if h.ndim == 1 else h[..., None, :])) @ K
    Abar_t = Abar.mT
    variance = h * (1.0 - h)

    one = K.ndim == 2                                      # one law without a mode axis (Bernoulli)
    spec = "ij,jk,ik->i" if one else "aij,ajk,aik->ai"

    def apply(Q: np.ndarray) -> np.ndarray:
        c = variance * np.einsum(spec, K, Q, K)
        Y = Abar @ Q @ Abar_t + (B * (c if one else c[:, None, :])) @ B.T
        return Y if T is None else np.tensordot(T, Y, axes=(0, 0))

    return apply


def mode_adjoint_step(A: np.ndarray, B: np.ndarray, K: np.ndarray, h: np.ndarray,
                      T: np.ndarray | None = None) -> Step:
    """``P -> L*(P)``: the adjoint of `mode_step`'s map (``delivery="current"``) for one law, its parts that do
    not depend on P formed once; it propagates cost-to-go matrices backwards (``sum_b tr(P_b L(Q)_b) =
    sum_a tr(L*(P)_a Q_a)``). With ``E_a = sum_b T_ab P_b``,

    .. math:: L^*(P)_a = \\bar A_a' E_a \\bar A_a + K_a' \\mathrm{diag}(h_a (1 - h_a) \\circ
       \\mathrm{diag}(B' E_a B)) K_a,

    ``Abar_a = A - B H_a K_a``. ``T=None``: one mode (Bernoulli, ``h = mu``, ``E = P``), K (m, n), P (n, n); with T
    (M, M): K (M, m, n), h (M, m), P (M, n, n). Its matrix on row-major vec is `mode_matrix`'s transpose.
    Time O(M (n^3 + n^2 m) + M^2 n^2) per application.

    Examples
    --------
    >>> step = mode_adjoint_step(np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0.5]))
    >>> step(np.eye(1)).tolist()                       # (2 - 1)^2 + 0.25 * 4: the scalar map is its own adjoint
    [[2.0]]
    >>> rng = np.random.default_rng(1)                 # a chain: tr(P L(Q)) = tr(L*(P) Q) summed over the modes
    >>> A, B, K = rng.normal(size=(2, 2)), rng.normal(size=(2, 2)), rng.normal(size=(3, 2, 2))
    >>> h, T = rng.uniform(size=(3, 2)), np.full((3, 3), 1 / 3)
    >>> P, Q = rng.normal(size=(3, 2, 2)), rng.normal(size=(3, 2, 2))
    >>> lhs = np.sum(P * mode_step(A, B, K, h, T)(Q))
    >>> bool(np.isclose(lhs, np.sum(mode_adjoint_step(A, B, K, h, T)(P) * Q), rtol=1e-12))
    True
    """
    if T is None:
        Abar = A - (B * h) @ K
        variance = h * (1.0 - h)

        def one(P: np.ndarray) -> np.ndarray:
            c = variance * np.einsum("ji,jk,ki->i", B, P, B)
            return Abar.T @ P @ Abar + (K.T * c) @ K

        return one
    Abar = A - (B * h[:, None, :]) @ K
    Abar_t, K_t, variance = Abar.mT, K.mT, h * (1.0 - h)

    def apply(P: np.ndarray) -> np.ndarray:
        E = np.tensordot(T, P, axes=(1, 0))                                                  # E_a = sum_b T_ab P_b
        c = variance * np.einsum("ji,ajk,ki->ai", B, E, B)
        return Abar_t @ E @ Abar + (K_t * c[:, None, :]) @ K

    return apply


def _next_step(A: np.ndarray, B: np.ndarray, K: np.ndarray, h: np.ndarray, T: np.ndarray | None) -> Step:
    """`mode_step` with the deliveries following the next mode: ``Q+_b = sum_a T_ab E_{v|b}[G_a Q_a G_a']``.
    With ``Z_a = [A; K_a] Q_a [A; K_a]'`` summed first (``Zbar_b = sum_a T_ab Z_a``: O(a M n^2) instead of one
    product per pair), ``E_{v|b}[..] = W_b Zbar_b W_b' + B diag(h_b (1 - h_b) ∘ diag(Zbar_b's K Q K' block)) B'``
    with ``W_b = [I, -B H_b]`` (``E[v v'] = h h' + diag(h (1 - h))``)."""
    if T is None:
        raise InputError("delivery", "the deliveries follow the next mode only behind a chain (T)")
    if A.ndim != 2:
        raise InputError("A", "a plant per mode is taken with delivery='current' only")
    n = A.shape[0]
    stacked = np.concatenate([np.broadcast_to(A, (K.shape[0], n, n)), K], axis=1)          # [A; K_a]
    stacked_t = stacked.mT
    W = np.concatenate([np.broadcast_to(np.eye(n), (h.shape[0], n, n)), -(B * h[:, None, :])], axis=2)
    W_t, variance = W.mT, h * (1.0 - h)

    def apply(Q: np.ndarray) -> np.ndarray:
        Z = np.tensordot(T, stacked @ Q @ stacked_t, axes=(0, 0))                            # sum_a T_ab Z_a
        c = variance * np.einsum("bii->bi", Z[:, n:, n:])
        return W @ Z @ W_t + (B * c[:, None, :]) @ B.T

    return apply


def _stage_weight(Omega: np.ndarray, psi: np.ndarray, K: np.ndarray, g: np.ndarray,
                  held: np.ndarray | None = None) -> np.ndarray:
    """``Omega + K' diag(psi g) K`` per mode: with g the delivery probabilities of the inputs' mode, ``tr(W Q)`` is the
    expected stage cost (``v_i^2 = v_i``: ``E[(V u)' Psi (V u)] = u' diag(psi g) u``).

    ``held`` F (per mode, as K): the applied input is ``F x - V K x`` (F x applied whatever the delivery: a held
    input, a buffered plan's entry), and ``E[.' Psi .] = x'((F - G K)' Psi (F - G K) + K' diag(psi g (1 - g)) K) x``
    (G = diag(g); E[v_i v_j] = g_i g_j + [i = j] g_i (1 - g_i)). F = 0 is the weight above."""
    if held is not None:
        mean = held - (g[..., :, None] * K)                                   # E[applied input] = (F - G K) x
        spread = g * (1.0 - g) * psi
        return (Omega + (mean.mT * psi) @ mean
                + (K.mT * (spread if spread.ndim == 1 else spread[..., None, :])) @ K)
    weights = g * psi
    return Omega + (K.mT * (weights if weights.ndim == 1 else weights[..., None, :])) @ K


def mode_matrix(A: np.ndarray, B: np.ndarray, K: np.ndarray, h: np.ndarray, T: np.ndarray | None = None,
                delivery: str = "current") -> np.ndarray:
    """The matrix of `mode_step`'s map on row-major vec(Q), modes stacked: (M n^2)×(M n^2), rows b, columns a.

    Per pair of modes the block is ``T_ab (Abar ⊗ Abar + sum_i c_i F_i ⊗ F_i)`` with ``F_i = b_i k_i`` and
    ``c = h (1 - h)`` (`random_matrix_moment`), the gain of mode a and the deliveries of a ("current") or b
    ("next"). ``T=None``: one mode, ``Abar ⊗ Abar + sum_i c_i F_i ⊗ F_i`` with ``Abar = A - B diag(mu) K``; a stack
    of laws K (..., m, n) with h (..., m) gives (..., n^2, n^2). Time O(M m n^4) ("next": O(M^2 m n^4)), memory
    8 (M n^2)^2 bytes: small sizes only.

    Examples
    --------
    >>> one = np.ones((1, 1))
    >>> op = mode_matrix(2 * one, one, one[None].repeat(2, 0), np.array([[1.0], [0.0]]), np.full((2, 2), 0.5))
    >>> op.tolist(), round(float(max(abs(np.linalg.eigvals(op)))), 12)    # x+ = (2 - v) x: E[(2 - v)^2] = 5/2
    ([[0.5, 2.0], [0.5, 2.0]], 2.5)
    """
    if T is None:
        Abar = A - (B * h[..., None, :]) @ K
        return random_matrix_moment(Abar, (B[:, i, None] * K[..., i, None, :] for i in range(B.shape[1])),
                                    h * (1.0 - h))
    if delivery not in ("current", "next"):
        raise InputError("delivery", f"expected current or next, found {delivery!r}")
    M, n = T.shape[0], A.shape[-1]
    if delivery == "current":
        blocks = mode_matrix(A, B, K, h)[:, None] * T[:, :, None, None]                    # [a, b]
    else:
        blocks = mode_matrix(A, B, K[:, None], h[None]) * T[:, :, None, None]             # gain a, deliveries b
    return blocks.transpose(1, 2, 0, 3).reshape(M * n * n, M * n * n)


def random_matrix_moment(mean: np.ndarray, directions: Iterable[np.ndarray], variances: np.ndarray) -> np.ndarray:
    """The d^2 x d^2 matrix of ``S -> E[F S F']`` on row-major ``vec(S)`` for the random matrix
    ``F = mean + sum_i (z_i - E z_i) D_i`` with independent scalars ``z_i`` of variances ``c_i``:
    ``mean ⊗ mean + sum_i c_i D_i ⊗ D_i`` (the cross terms vanish). The operator of `mode_matrix`
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


def mode_radius(A: np.ndarray, B: np.ndarray, K: np.ndarray, h: np.ndarray, T: np.ndarray | None = None,
                delivery: str = "current", method: str = "auto", matrix: Callable[[], np.ndarray] | None = None,
                label: str = "mean-square radius") -> float:
    """Spectral radius of `mode_step`'s map (< 1 iff the loop is mean-square stable); arrays as it takes them.

    ``method``: "dense", the eigenvalues of `mode_matrix` (or of ``matrix()``, a caller's builder that keeps
    the matrix or refuses its size), time O((M n^2)^3); "krylov", ARPACK on the map applied matrix-free, its value
    checked against Collatz–Wielandt bounds proven from its eigenvector and against ``min_k ||L^k(I)||^(1/k)``,
    falling back to the dense eigenvalues within `MAX_OPERATOR_DIM` rows where the check fails (a defective
    Perron root, which Arnoldi resolves only to about eps^(1/size)); "auto": dense up to `DENSE_MAX_DIM` rows,
    else Krylov. Entries beyond `RADIUS_RESCALE` are scaled out first (the map is quadratic in (A, K)). With the
    deliveries of the current mode, a gain row on a channel that never delivers (h = 0) never acts, and is dropped
    first (at mu = 0 a law's gain may be any size, e.g. the TCP-like plan's limit, without changing the loop).

    Raises
    ------
    NumericalError
        The map is not finite, an eigenvalue routine fails, or ARPACK's value is not proved beyond the dense limit.
        Its text starts with ``label``.
    BudgetError
        The Krylov vectors exceed the ``memory_bytes`` budget (a ValueError: refused before any work).

    Examples
    --------
    >>> one = np.ones((1, 1))        # x+ = (2 - v) x, v ~ Bernoulli(1/2): as one mode, and as a memoryless chain
    >>> mode_radius(2 * one, one, one, np.array([0.5])), mode_radius(2 * one, one, one[None], np.array([[0.5]]), one)
    (2.5, 2.5)
    """
    if method not in ("auto", "dense", "krylov"):
        raise InputError("method", f"expected auto, dense or krylov, found {method!r}")
    M, n = (1 if T is None else T.shape[0]), A.shape[-1]
    if T is None or delivery == "current":
        K = np.where(np.asarray(h)[..., :, None] == 0.0, 0.0, K)     # B diag(v) K with v = 0 always: no action
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(A - (B * h[..., None, :]) @ K))):
        raise NumericalError(f"{label}: the closed-loop matrix A - B M K is not finite")
    scale = max(float(np.abs(A).max()), float(np.abs(B).max() * np.abs(K).max()))
    if scale > RADIUS_RESCALE:      # radius(A, K) = c^2 radius(A / c, K / c): no overflow
        with np.errstate(over="ignore", under="ignore"):   # scale (scale r), not scale^2 r: inf * 0 would be nan
            return scale * (scale * mode_radius(A / scale, B, K / scale, h, T, delivery, method, label=label))
    dim = M * n * n
    failure = None
    if method == "krylov" or (method == "auto" and dim > DENSE_MAX_DIM):
        if dim >= 8:
            with np.errstate(over="ignore", invalid="ignore"):
                radius, failure, upper = _krylov_radius(mode_step(A, B, K, h, T, delivery), M if T is not None
                                                        else None, n)
            if failure is None:
                return radius
            if dim > limit("operator_rows"):
                raise NumericalError(f"{label}: {failure}; the radius is at most {upper:.6g}")
    with np.errstate(over="ignore", invalid="ignore"):
        op = mode_matrix(A, B, K, h, T, delivery) if matrix is None else matrix()
        try:
            vals = np.linalg.eigvals(op) if np.all(np.isfinite(op)) else np.array([np.inf])
        except np.linalg.LinAlgError as err:
            raise NumericalError(f"{label}: the eigenvalue routine failed ({err})") from None
    if not np.all(np.isfinite(vals)):
        raise NumericalError(f"{label}: the second-moment operator overflows")
    return float(np.max(np.abs(vals)))


def _krylov_radius(step: Step, M: int | None, n: int) -> tuple[float, str | None, float]:
    """``(radius, failure, upper)``: ARPACK on the map (never formed), its value checked against the proven
    bounds; ``failure`` None where it passed, else why not. ``M`` None: one mode without a mode axis.
    Time O(iterations (M^2 n^2 + M n^2 (n + m))) plus the power bound's steps."""
    from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, LinearOperator, eigs  # optional.LAZY_IMPORTS

    shape = (n, n) if M is None else (M, n, n)
    D = int(np.prod(shape))
    k = min(6, D - 2)
    ncv = min(D, max(2 * k + 1, 20))
    needed = krylov_bytes(D, ncv + 4)
    check("memory_bytes", needed, "channel" if M else "A", f"the mean-square radius's {ncv + 4} Krylov vectors of "
                                                          f"M n^2 = {D} entries (about {gib_text(needed)})",
          instead="use fewer chain states or channels" if M else "use a smaller plant")
    # the bound's steps: 20 n at one mode, at most 400 and about 4e10 flops; behind a chain divided by the modes, so
    # that it costs about what it costs at one mode (each step applies the M-mode map)
    upper = _power_bound(step, shape, int(min(20 * n, 400, max(40, 4e10 // (D * n)))) // (M or 1))
    if upper == 0.0:
        return 0.0, None, 0.0   # L^k(I) = 0: L vanishes on the PSD cone, hence on every symmetric matrix

    def apply(v: np.ndarray) -> np.ndarray:
        Q = v.reshape(shape)
        return step(0.5 * (Q + np.swapaxes(Q, -1, -2))).ravel()

    # L is applied to the symmetric part: the Perron eigenvector is symmetric (PSD), and the skew
    # part's eigenvalues are dominated by it (a completely positive map attains its radius on the cone).
    op = LinearOperator((D, D), matvec=apply, dtype=float)
    try:
        vals, vecs = eigs(op, k=k, which="LM", tol=ARPACK_TOL, v0=np.broadcast_to(np.eye(n), shape).ravel(),
                          ncv=ncv, maxiter=max(300, 10 * n))
    except (ArpackNoConvergence, ArpackError) as err:
        return np.nan, f"ARPACK did not converge ({err})", upper
    top = int(np.argmax(np.abs(vals)))
    radius = float(abs(vals[top]))
    try:
        lower, bound = _cone_bounds(vecs[:, top], step, shape)
    except np.linalg.LinAlgError as err:
        return np.nan, f"the Collatz-Wielandt check failed ({err})", upper
    upper = min(upper, bound)
    if np.isfinite(radius) and lower * (1.0 - 1e-9) <= radius <= upper * (1.0 + 1e-9):
        return radius, None, upper
    return radius, f"ARPACK's {radius:.6g} lies outside the proven bounds [{lower:.6g}, {upper:.6g}]", upper


def _cone_bounds(vec: np.ndarray, step: Step, shape: tuple[int, ...]) -> tuple[float, float]:
    """Collatz–Wielandt bounds from a positive definite X (a tuple of them) near the Perron eigenvector: with
    ``R_b = X_b^(-1/2) L(X)_b X_b^(-1/2)``, ``L(X) >= min_b lambda_min(R_b) X`` and ``L(X) <= max_b lambda_max(R_b) X``
    (blockwise Loewner order), so the radius lies between them (a positive map; X > 0 makes both proofs hold).
    Time O(M n^3) plus one application."""
    v = vec * np.exp(-1j * np.angle(vec[np.argmax(np.abs(vec))]))
    X = v.real.reshape(shape)
    X = 0.5 * (X + np.swapaxes(X, -1, -2))
    X = X if np.trace(X, axis1=-2, axis2=-1).sum() >= 0 else -X
    w, U = np.linalg.eigh(X)
    w = np.maximum(w, 1e-10 * max(float(w.max()), np.finfo(float).tiny))   # PSD part, made definite
    U_t = np.swapaxes(U, -1, -2)
    root_inv = (U / np.sqrt(w)[..., None, :]) @ U_t
    Y = step((U * w[..., None, :]) @ U_t)
    Z = root_inv @ Y @ root_inv
    r = np.linalg.eigvalsh(0.5 * (Z + np.swapaxes(Z, -1, -2)))
    return max(float(r[..., 0].min()), 0.0), float(r[..., -1].max())


def _power_bound(step: Step, shape: tuple[int, ...], steps: int) -> float:
    """``min_k max_b ||L^k(I)_b||_2^(1/k)`` over k = 1..steps: an upper bound on the radius (a positive map's
    induced norm, the largest block's spectral norm, is attained at I: Russo–Dye; and rho <= ||L^k||^(1/k)).
    Time O(steps (M n^3 + M^2 n^2))."""
    X, log_scale, best = np.broadcast_to(np.eye(shape[-1]), shape), 0.0, np.inf
    for k in range(1, steps + 1):
        X = step(X)
        size = float(np.linalg.norm(X, 2)) if X.ndim == 2 else float(np.linalg.norm(X, 2, axis=(-2, -1)).max())
        if size == 0.0:
            return 0.0
        log_scale += np.log(size)
        X /= size
        best = min(best, float(np.exp(log_scale / k)))
    return best


def mode_stage_costs(A: np.ndarray, B: np.ndarray, Omega: np.ndarray, psi: np.ndarray, Sigma: np.ndarray,
                     x0: np.ndarray, K_all: np.ndarray, h_all: np.ndarray, T: np.ndarray | None = None,
                     start: np.ndarray | None = None, delivery: str = "current",
                     first_gain: np.ndarray | None = None,
                     held: np.ndarray | None = None, per_step: bool = False) -> tuple[np.ndarray, float]:
    """Exact ``E[x_t' Omega x_t + (V_t u_t)' Psi (V_t u_t)]``, t = 0..steps-1, and ``E[x_T' Omega x_T]`` of
    ``u_t = -K_{t,a} x_t`` from x0 (noise Sigma enters every step with P(mode)), from the recursion on
    ``Q_{a,t} = E[x_t x_t' 1{mode = a}]`` (CFM05, ch. 3) of `mode_step`, the stage cost ``sum_a tr(W_a Q_a)``
    with ``W_a = Omega + K_a' diag(psi g_a) K_a`` (``v_i^2 = v_i``; g_a = h_a, or ``sum_b T_ab h_b`` with "next").

    ``T=None``: one mode (Bernoulli), ``K_all`` (steps, m, n), ``h_all`` (steps, m) the delivery probabilities per
    step. With T: ``K_all`` (steps, M, m, n), ``h_all`` (M, m), ``start`` P(mode at 0); "current": the gain of the
    mode at t; "next": of the mode at t - 1, ``first_gain`` (m, n) at t = 0. ``K_all`` and ``h_all`` broadcast over
    the steps (stride 0) are one law: its map is formed once. Entries stay inf past an overflow.
    ``held`` (M, m, n), or (m, n) at one mode, with one law and "current" only: the applied input is
    ``F_a x - V K_a x`` instead of ``-V K_a x`` (`_stage_weight`); A may then carry a mode axis.
    ``per_step`` (one mode): a weight per step, ``Omega`` (steps + 1, n, n) with ``Omega[t]`` on x_t (the terminal one
    last) and ``psi`` (steps, m), as the paper's cost has them (allocation.attainable).
    Time O(steps M (M n^2 + n^3 + n^2 m)).

    Examples
    --------
    >>> one = np.ones((1, 1))       # x+ = (2 - v) x, u = -x, v ~ Bernoulli(1/2): E[x^2] = 1, 5/2; inputs 1/2, 5/4
    >>> stage, terminal = mode_stage_costs(2 * one, one, one, np.ones(1), 0 * one, np.ones(1),
    ...                                    np.ones((2, 1, 1)), np.full((2, 1), 0.5))
    >>> stage.tolist(), terminal
    ([1.5, 3.75], 6.25)
    """
    steps = K_all.shape[0]
    one_law = K_all.strides[0] == 0 and (T is not None or h_all.strides[0] == 0)
    if held is not None and not (one_law and delivery == "current"):
        raise InputError("held", "an input held on a loss is taken for one law with delivery='current'")
    if per_step and (T is not None or held is not None):
        raise InputError("per_step", "a weight per step is taken at one mode without a held input")
    if T is None:
        Q, pi, R = np.outer(x0, x0), None, None
    elif delivery == "next":
        Q, R, pi = np.outer(x0, x0)[None], start[None], start
    else:
        Q, R, pi = start[:, None, None] * np.outer(x0, x0), T, start
    stage = np.empty(steps)
    each_step = not one_law or delivery == "next"             # "next": t = 0 has its own law, t = 1 the gains'
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(steps):
            if per_step:
                K, h = K_all[t], h_all[t]
                step, weight = mode_step(A, B, K, h), _stage_weight(Omega[t], psi[t], K, h)
            elif t == 0 or (each_step and (not one_law or t == 1)):
                if T is None:
                    K, h = K_all[t], h_all[t]
                    step, weight = mode_step(A, B, K, h), _stage_weight(Omega, psi, K, h, held)
                else:
                    K = np.asarray(first_gain, dtype=float)[None] if delivery == "next" and t == 0 else K_all[t]
                    R = R if delivery == "next" and t == 0 else T
                    step = mode_step(A, B, K, h_all, R, delivery)
                    weight = _stage_weight(Omega, psi, K, h_all if delivery == "current" else R @ h_all, held)
            stage[t] = float(np.sum(weight * Q))
            if T is None:
                Q = step(Q) + Sigma
            else:
                pi = pi @ T if delivery == "current" or t > 0 else pi                      # P(mode at t + 1)
                Q = step(Q) + pi[:, None, None] * Sigma
        terminal = float(np.sum((Omega[steps] if per_step else Omega) * Q))
    stage[~np.isfinite(stage)] = np.inf
    return stage, terminal if np.isfinite(terminal) else float("inf")
