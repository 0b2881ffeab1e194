"""The homogeneous Riccati map over M-mode channels: the algebra every stabilisable-set form shares.

A channel is a mode chain ``T`` (M, M) with delivery rates ``d`` (M, M, m): a step from mode a into mode b
delivers input i with probability ``d_ab,i``, independently. Gilbert–Elliott and k-state chains are
``(T, h_b)`` (the deliveries follow the next mode, "next") or ``(T, h_a)`` ("current"): `chain_rates`;
independent Bernoulli(mu) losses are the one-mode chain ``T = [[1]]``, ``d = mu``: `bernoulli_rates`. For
a PSD tuple ``P_a = L_a L_a'`` the adjoint of the second-moment map of mode gains K is

.. math:: L_K^*(P)_a = \\sum_b T_{ab}\\, E\\big[(A - B V K_a)' P_b (A - B V K_a)\\big],\\quad V \\sim d_{ab},

and the homogeneous Riccati map ``R(P)_a = min_K L_K^*(P)_a`` is monotone, concave and positively homogeneous on
the PSD cone; its eigenvalue ``R(P) = lambda P`` is the least mean-square radius ``min_K rho(L_K)``, and a P with
``R(P) >= c P`` proves ``rho(L_K) >= c`` for every K (Collatz–Wielandt). Here R is a sum of squares,
``R(P)_a = F_a'F_a`` (`riccati_factors`): the least-squares residual of the factors of ``L_K^*(P)_a``
stacked over the next mode b with weights ``sqrt(T_ab)``, never negative, and its error does not grow with the
minimising gain. simulation.region (Bernoulli, M = 1, batched over channels) and simulation.chain_radius (mode
chains) iterate it; simulation.region and simulation.markov_region check the certificates it gives.
"""

from __future__ import annotations

import numpy as np

from ..linalg import ControllableSplit, controllable_split
from ..tolerances import CERTIFICATE_KERNEL_RTOL, CERTIFICATE_RTOL, RICCATI_RTOL

__all__ = ["BALANCE_EXP", "CUTS", "GRADED", "POLICY_STEPS", "SHIFT", "bernoulli_rates", "certificate_bound",
           "chain_rates", "converges_within", "cut_candidates", "grading_scale", "least_squares_residual",
           "moment_factor", "perron_adjoint", "psd_part_factor", "psd_size", "radius_bound", "reach_split",
           "riccati_factors", "riccati_squares", "unreached_stein"]

#: the power iterations run on ``R + SHIFT lambda I`` (the same eigenvector): a shift removes a peripheral spectrum
#: (e.g. rotations, eigenvalues -lambda); 0.1 costs little speed where the second eigenvalue is small (0.5 had taken
#: 280 steps a point on the two_actuator grid)
SHIFT = 0.1
#: the policy iterations' step cap
POLICY_STEPS = 50
#: relative eigenvalue cuts under which a certificate P is tried again without those directions (:func:`cut_candidates`)
CUTS = (1e-12, 1e-9, 1e-6)

_ONE = np.ones((1, 1))


def bernoulli_rates(mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(T, d)`` of independent Bernoulli(mu) losses, the one-mode chain: ``T = [[1]]``, d (..., 1, 1, m) for mu
    (..., m). O(m).

    >>> T, d = bernoulli_rates(np.array([0.5, 0.9]))
    >>> T.tolist(), d.shape
    ([[1.0]], (1, 1, 2))
    """
    mu = np.asarray(mu, dtype=float)
    return _ONE, mu[..., None, None, :]


def chain_rates(T: np.ndarray, h: np.ndarray, delivery: str) -> tuple[np.ndarray, np.ndarray]:
    """``(T, d)`` of a mode chain with per-mode delivery probabilities h (M, m): d (M, M, m) the rates of a step from
    mode a into mode b, h_b ("next") or h_a ("current"). O(M^2 m)."""
    M = len(h)
    return T, np.broadcast_to(h[None] if delivery == "next" else h[:, None], (M, M, h.shape[1]))


def psd_part_factor(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(L, w)``: ``P+ = L L'`` the PSD part of a symmetric stack P (..., n, n), its eigenvalues w (ascending) at or
    below ``n eps max(w)`` taken as zero (so P+ has an exact kernel there), and those eigenvalues ``w`` (..., n) with
    the dropped ones set to 0; ``L = U diag(sqrt(w))``, its columns the eigenvectors (``L L'``, unlike
    linalg.psd_factor's ``F'F``). Time O(n^3) a point."""
    w, U = np.linalg.eigh(0.5 * (P + np.swapaxes(P, -1, -2)))
    top = np.max(w, axis=-1, keepdims=True)
    w = np.where(w > P.shape[-1] * np.finfo(float).eps * np.maximum(top, 0.0), w, 0.0)
    return U * np.sqrt(w)[..., None, :], w


def moment_factor(L: np.ndarray, A: np.ndarray, B: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(Phi_x, Phi_u)`` with ``E[(Ax - BVu)' P (Ax - BVu)] = ||Phi_x x + Phi_u u||^2`` for ``P = L L'`` (stacks:
    L (..., n, r), mu (..., m); the factors (..., r + m, n) and (..., r + m, m)): the mean and the loss variance of
    the delivered input, ``c_i = mu_i (1 - mu_i)``,

    .. math:: \\Phi_x = \\begin{bmatrix} L'A \\\\ 0 \\end{bmatrix},\\quad \\Phi_u = \\begin{bmatrix} -L'BM \\\\
       \\mathrm{diag}(\\sqrt{c_i \\|L'b_i\\|^2}) \\end{bmatrix}.

    Time O(r n (n + m)) a point."""
    m = B.shape[1]
    LA, LB = np.swapaxes(L, -1, -2) @ A, np.swapaxes(L, -1, -2) @ B
    spread = np.sqrt(mu * (1.0 - mu) * np.sum(LB * LB, axis=-2))
    phi_u = np.concatenate([-LB * mu[..., None, :], spread[..., :, None] * np.eye(m)], axis=-2)
    phi_x = np.concatenate([LA, np.zeros((*spread.shape, A.shape[0]))], axis=-2)
    return phi_x, phi_u


def least_squares_residual(phi_x: np.ndarray, phi_u: np.ndarray, scale: float = 0.0) -> np.ndarray:
    """``F = (I - U U') Phi_x``, U the left singular vectors of ``Phi_u`` above lstsq's cutoff (``eps max(k, m)
    max(s_max, scale)``, the minimum-norm minimiser's; ``scale`` makes columns at rounding level of a larger
    problem count as zero): ``min_u ||Phi_x x + Phi_u u||^2 = ||F x||^2``, an orthogonal projection, whose error
    does not grow with the minimising gain as a difference ``A'PA - A'PBM K`` does. Stacks on the leading axes.
    Time O(k (m + n)^2) a point."""
    U, sv, _ = np.linalg.svd(phi_u, full_matrices=False)
    cutoff = np.finfo(float).eps * max(phi_u.shape[-2:]) * np.maximum(sv[..., :1], scale)
    U = U * (sv > cutoff)[..., None, :]
    return phi_x - U @ (np.swapaxes(U, -1, -2) @ phi_x)


def riccati_factors(L: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, d: np.ndarray, scale: float = 0.0
                    ) -> np.ndarray:
    """``F`` (..., M, M (r + m), n) with ``R(P)_a = F_a'F_a`` for ``P_b = L_b L_b'`` (L (..., M, n, r), d
    (..., M, M, m)): `moment_factor` of ``L_b`` at the rates ``d_ab``, weighted by ``sqrt(T_ab)`` and stacked
    over b, minimised over u (`least_squares_residual` with ``scale``). One mode (Bernoulli): F (..., 1,
    r + m, n), the residual of moment_factor itself. Time O(M^2 (r + m)(m + n)^2) a point.

    >>> T, d = bernoulli_rates(np.array([0.5]))
    >>> F = riccati_factors(np.eye(1)[None], np.array([[2.0]]), np.array([[1.0]]), T, d)
    >>> round(float(np.sum(F * F)), 12)             # scalar: R(1) = a^2 (1 - mu)
    2.0
    """
    M, n, m = T.shape[0], A.shape[0], B.shape[1]
    if M == 1:                       # no stacking: the weight is 1, the factors moment_factor's own
        phi_x, phi_u = moment_factor(L[..., 0, :, :], A, B, d[..., 0, 0, :])
        return least_squares_residual(phi_x, phi_u, scale)[..., None, :, :]
    lead = L.shape[:-3]
    phi_x, phi_u = moment_factor(np.broadcast_to(L[..., None, :, :, :], (*lead, M, *L.shape[-3:])), A, B, d)  # [a, b]
    weight = np.sqrt(T)[..., :, :, None, None]
    return least_squares_residual((weight * phi_x).reshape(*lead, M, -1, n), (weight * phi_u).reshape(*lead, M, -1, m),
                                  scale)


def riccati_squares(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, d: np.ndarray, scaled: bool = False
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(F, squares, weight)`` at a PSD tuple P (..., M, n, n): the factors of ``R(P+)`` (`riccati_factors` at
    the PSD part P+, `psd_part_factor`), ``sum_a tr R(P+)_a`` (a sum of squares) and ``sum_a tr P+_a`` (a sum
    of nonnegative eigenvalues); their ratio is the least radius at an eigenvector. ``scaled``: the residual drops
    input directions below lstsq's cutoff of ``max_a ||L_a|| ||B||`` (one point only), the size the columns have
    before cancellation, not the columns' own largest: where P weighs only directions no input reaches, ``L'B`` is
    rounding and its own largest column would count as an input. O(M^2 (n + m)(m + n)^2 + M n^3) a point."""
    L, w = psd_part_factor(P)
    scale = 0.0
    if scaled and L.size:
        scale = float(np.max(np.linalg.norm(L, 2, axis=(-2, -1)))) * float(np.linalg.norm(B, 2))
    F = riccati_factors(L, A, B, T, d, scale)
    return F, np.sum(np.sum(F * F, axis=(-2, -1)), axis=-1), np.sum(w, axis=(-2, -1))


def radius_bound(F: np.ndarray, P: np.ndarray) -> float:
    """The largest c with ``F'F >= c P`` (P PSD, one point): ``min ||F x||^2 / x'Px`` over x with ``Px != 0``. With
    ``F'F = min_K L_K^*(P)`` this is the Collatz-Wielandt bound ``rho(L_K) >= c`` for every K (``L_K^*(P) >= c P``,
    ``P >= 0``, ``P != 0``). Eigenvalues of P at or below ``n eps max`` count as its kernel, whose directions are
    minimised out first (a projection; a kernel direction F maps below ``CERTIFICATE_KERNEL_RTOL ||F||`` is
    rounding, no direction at all); 0.0 where the support is wider than F's rank. Time O(n^3 + k n^2)."""
    w, U = np.linalg.eigh(0.5 * (P + P.T))
    keep = w > P.shape[0] * np.finfo(float).eps * max(float(w[-1]), 0.0)
    if not np.any(keep):
        return float("-inf")
    Y = F @ U
    support = Y[:, keep]
    if not np.all(keep):
        support = least_squares_residual(support, Y[:, ~keep],
                                         CERTIFICATE_KERNEL_RTOL / np.finfo(float).eps * float(np.linalg.norm(F, 2)))
    G = support / np.sqrt(w[keep])
    if G.shape[0] < G.shape[1]:
        return 0.0
    return float(np.linalg.svd(G, compute_uv=False)[-1] ** 2)


def certificate_bound(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, d: np.ndarray, scaled: bool = False
                      ) -> float:
    """The largest c with ``R(P)_a >= c P_a`` for every mode a that P (M, n, n) weighs (`radius_bound` of
    `riccati_factors`, ``scaled`` as `riccati_squares`), so ``rho(L_K) >= c`` for every K; inf where P
    weighs no mode. P is taken as given (symmetric PSD: the callers check). O(M^2 (n + m)(m + n)^2 + M n^3).

    >>> c = certificate_bound(np.eye(1)[None], np.array([[2.0]]), np.array([[1.0]]), *bernoulli_rates(np.array([0.6])))
    >>> round(c, 12)                                # scalar: R(1) = a^2 (1 - mu)
    1.6
    """
    F = riccati_squares(P, A, B, T, d, scaled)[0] if scaled else riccati_factors(psd_part_factor(P)[0], A, B, T, d)
    if len(P) == 1:
        return radius_bound(F[0], P[0]) if np.any(P) else np.inf
    return min((radius_bound(F[a], P[a]) for a in np.flatnonzero(np.any(P != 0, axis=(-2, -1)))), default=np.inf)


def cut_candidates(P: np.ndarray, cuts: tuple[float, ...] = CUTS):
    """P (M, n, n, symmetric) with its eigenvalues at or below each of ``cuts`` times the largest (over all modes)
    set to 0, each normalised to ``sum_a tr = 1``, the cuts that change P and leave some direction: the power and
    policy iterations leave weight ~1e-13 on a block (or a mode) whose own radius is below the top one, which spoils
    a Collatz–Wielandt bound; each cut P is a certificate in its own right, checked as any other. O(M n^3)."""
    w, U = np.linalg.eigh(P)
    top = float(np.max(w))
    for cut in cuts:
        kept = w > cut * top
        if np.all(kept) or not np.any(kept):
            continue
        Q = np.stack([(U[a][:, kept[a]] * w[a][kept[a]]) @ U[a][:, kept[a]].T for a in range(len(P))])
        Q = 0.5 * (Q + np.swapaxes(Q, -1, -2))
        yield Q / float(np.sum(np.trace(Q, axis1=-2, axis2=-1)))


#: a P whose diagonal spans more than this (least over largest, zeros aside) is refined on the plant scaled by
#: diagonal powers of two (`grading_scale`; region's and chain_radius's eigenpairs)
GRADED = 1e-6
#: the balancing exponents of `grading_scale` are clipped to +-BALANCE_EXP (no scaled entry overflows for a plant
#: below 1e150)
BALANCE_EXP = 100


def grading_scale(P: np.ndarray, graded: float) -> np.ndarray | None:
    """``D = diag(2^round(-log2(d_i) / 2))`` (exponents clipped to +-BALANCE_EXP; 1 where ``d_i <= 0``) for the
    diagonal d of P (n, n), or of a tuple's sum over its modes (M, n, n), where its positive entries span more than
    ``graded`` (least over largest); None where they do not, or P is not finite or has no positive diagonal entry.
    The plant scaled by it, ``D^-1 A D``, ``D^-1 B``, is the same up to an exact similarity (powers of two) and has
    the eigenvector ``D P D``, balanced: the power and policy iterations on a chain of integrators (diagonal 4e-14
    .. 1) stop 1e-2 off unscaled and agree with the exact single-input value scaled (region, chain_radius). O(M n^2).

    >>> grading_scale(np.diag([1.0, 1e-8]), 1e-6).tolist(), grading_scale(np.eye(2), 1e-6)
    ([1.0, 8192.0], None)
    """
    d = np.diagonal(P.sum(axis=0) if P.ndim == 3 else P)
    positive = d > 0
    if not (np.all(np.isfinite(P)) and np.any(positive)) or \
            float(d[positive].min()) >= graded * float(d[positive].max()):
        return None
    return np.where(positive, np.exp2(np.clip(np.round(-0.5 * np.log2(np.where(positive, d, 1.0))),
                                              -BALANCE_EXP, BALANCE_EXP)), 1.0)


def perron_adjoint(A: np.ndarray) -> np.ndarray:
    """The Perron eigenvector of ``X -> A'XA`` (PSD, trace 1): ``Re(w w^H)`` for a left eigenvector w of A's
    eigenvalue nu of largest modulus (``A'XA = |nu|^2 X``): the certificate of a part no input reaches. O(n^3).

    >>> A = np.array([[2.0, 1.0], [0.0, 0.5]])                 # A' w = 2 w for w = (3, 2) / sqrt(13)
    >>> X = perron_adjoint(A)
    >>> X.round(12).tolist(), bool(np.allclose(A.T @ X @ A, 4 * X))
    ([[0.692307692308, 0.461538461538], [0.461538461538, 0.307692307692]], True)
    """
    vals, vecs = np.linalg.eig(A.T)
    w = vecs[:, int(np.argmax(np.abs(vals)))]
    X = np.outer(w.real, w.real) + np.outer(w.imag, w.imag)
    return X / float(np.trace(X))


def reach_split(A: np.ndarray, B: np.ndarray, live: np.ndarray) -> tuple[ControllableSplit, np.ndarray]:
    """``(split, T'B)``: the controllability split of A by the channels that can deliver (``live`` (m,) bool: a
    channel that never delivers never acts), and every channel's input map in its coordinates with the rows of the
    part they do not reach set to exact zeros (the live channels' are the staircase's dropped couplings). Every law
    leaves ``x_u+ = A_uu x_u``: the least radius is ``max(rho(A_uu)^2, the reached part's)``. O(n^4 + n^2 m)."""
    split = controllable_split(A, B[:, live])
    Bt = split.T.T @ B
    Bt[split.nc:] = 0.0
    return split, Bt


def unreached_stein(A: np.ndarray, B: np.ndarray, live: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """``[(c, P), ...]``: candidate certificates that every law's radius is at least c, from the part the channels
    ``live`` (m,) bool do not reach (`reach_split`) where ``rho(A_uu)^2 >= 1 - CERTIFICATE_RTOL``: ``P = T_u S T_u'``
    (trace 1, or norm 1) with ``A_uu' S A_uu - cS = cI`` (S has a positive direction iff ``rho(A_uu)^2 > c``;
    ``T_c(P) = 0 + cI + 0`` where the split is exact, e.g. a mode no column of B touches: a definite inequality the
    rounding cannot undo), at ``c = rho(A_uu)^2 (1 - 1e-9)`` and at ``1 - CERTIFICATE_RTOL``. Empty where there is no
    such part. One P for every mode of a chain too (``E_a = sum_b T_ab P = P``). Candidates only: an exact check
    decides (a split resting on a rank decision, its coupling rounded away, fails it). Time O(n^4 + n_u^6).

    >>> [(round(c, 6), P.round(12).tolist()) for c, P in unreached_stein(np.array([[0.5, 1.0], [0.0, 1.2]]),
    ...                                                                    np.array([[1.0], [0.0]]), np.array([True]))]
    [(1.44, [[0.0, 0.0], [0.0, 1.0]]), (1.0, [[0.0, 0.0], [0.0, 1.0]])]
    """
    split = reach_split(A, B, live)[0]
    if split.nc == A.shape[0]:
        return []
    top = split.uncontrollable_radius ** 2
    Au, Tu = split.A_uu, split.T[:, split.nc:]
    k = Au.shape[0]
    out = []
    for c in (top * (1.0 - 1e-9), 1.0 - CERTIFICATE_RTOL):
        if not 1.0 - CERTIFICATE_RTOL <= c <= top:
            continue
        with np.errstate(all="ignore"):
            try:
                S = np.linalg.solve(np.kron(Au.T, Au.T) - c * np.eye(k * k), c * np.eye(k).ravel()).reshape(k, k)
            except np.linalg.LinAlgError:
                continue
        P = Tu @ (0.5 * (S + S.T)) @ Tu.T
        if not np.all(np.isfinite(P)):
            continue
        scale = float(np.trace(P)) if np.trace(P) > 0 else float(np.linalg.norm(P, 2))
        out.append((c, P / scale))
    return out


def converges_within(moved: np.ndarray, last: np.ndarray, steps_left: int) -> np.ndarray:
    """Does a power iteration whose last two steps moved ``last`` then ``moved`` (``||P_next - P||``, above
    RICCATI_RTOL) reach RICCATI_RTOL within ``steps_left`` more steps at that rate r = moved / last: r < 1 and
    ``log(RTOL / moved) / log r <= steps_left``? The power iterations' hand-off test. Elementwise; O(1) a point.

    >>> converges_within(np.array([1e-6, 1e-2]), np.array([1e-3, 2e-2]), 10).tolist()   # rates 1e-3 and 0.5
    [True, False]
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.asarray(moved, dtype=float) / last
        to_go = np.where(rate < 1.0, np.log(RICCATI_RTOL / moved) / np.log(rate), np.inf)
    return to_go <= steps_left


def psd_size(P: np.ndarray) -> float:
    """The largest ``||P_a||_2`` of a symmetric tuple P (M, n, n) that is PSD to ``CERTIFICATE_RTOL`` of it, else nan
    (not finite, zero, or an eigenvalue below ``-CERTIFICATE_RTOL size``): the check before any certificate bound.
    O(M n^3)."""
    if not np.all(np.isfinite(P)):
        return float("nan")
    w = np.linalg.eigvalsh(P)                       # symmetric: ||P_a||_2 is its largest |eigenvalue|
    least = float(np.min(w[:, 0]))
    size = max(-least, float(np.max(w[:, -1])))
    if not size > 0 or least < -CERTIFICATE_RTOL * size:
        return float("nan")
    return size
