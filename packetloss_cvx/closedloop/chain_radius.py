"""The least mean-square radius behind Gilbert–Elliott channels and its certificates: ``lambda = inf_K rho(L_K)`` over
mode-dependent laws ``u = -K_a x``, computed without gains that diverge (`homogeneous_coupled_riccati`), and
the bound a certificate P proves on every law's radius (`chain_certificate_margin`). simulation.markov_region
decides the stabilisable set from them. The map's algebra is simulation.riccati_map's (as simulation.region's, whose
Bernoulli losses are its one-mode chain).

With ``E_a = sum_b T_ab P_b`` (T the mode chain, h_a the per-mode delivery probabilities) the adjoint of the
coupled second-moment map of gains K is the quadratic ``L_K^*(P)_a = A'E_aA - 2 A'F_a K_a + K_a' H_a K_a``
(``F_a = sum_b T_ab P_b B D_ab``, ``H_a = sum_b T_ab (D_ab B'P_bB D_ab + diag(d_ab (1 - d_ab)) ∘ B'P_bB)``, the
deliveries ``d_ab`` following the next mode b, h_b, "next", or the current one, h_a, "current": markov.mjls's two
conventions). The homogeneous coupled Riccati map ``R(P)_a = min_K L_K^*(P)_a`` is monotone, concave and
positively homogeneous on the PSD cone; its eigenvalue ``R(P) = lambda P`` is the least radius.

**The part no input reaches** is decided structurally, never by gains. With the controllability split
(linalg.controllable_split, of A and the channels that ever deliver: one with h = 0 in every mode never acts)
``T'AT = [[A_cc, A_cu], [0, A_uu]]``, ``T'B = [[B_c], [0]]`` (T orthogonal), every law
and every delivery pattern leaves ``x_u+ = A_uu x_u``, so the loop's second moment ``E[x x']`` is block triangular
in time: ``E[x_u x_u']`` grows as ``A_uu^t (.) A_uu'^t`` (rate ``rho(A_uu)^2`` exactly, whatever K), the reachable
block ``E[x_c x_c']`` at the coupled radius of ``(A_cc, B_c)`` under the chain (``x_u`` enters it only as an input
that decays at ``rho(A_uu)``), and the cross block ``E[x_c x_u']`` at most at the geometric mean of the two (Cauchy–
Schwarz). So ``min_K rho(L_K) = max(rho(A_uu)^2, lambda_c)``, lambda_c the least radius of ``(A_cc, B_c)``, and the
gains ``K_a = [K_c,a, 0] T'`` attain it. Its certificates are exact: ``P_a = T [[0, 0], [0, W]] T'`` with ``W =
Re(w w^H)``, w a left eigenvector of ``A_uu`` for its largest ``|nu|``, gives ``L_K^*(P) = |nu|^2 P`` for every K;
where lambda_c is the larger, ``P_a = T [[P_c,a, 0], [0, 0]] T'`` proves ``rho(L_K) >= c`` on the reachable
subspace, which every closed loop ``A - B V K`` maps into itself (`chain_certificate_margin`); the eigenvector P
returned is the whole map's, iterated from it (the regularised power iteration): a certificate on all of the space,
which an exact check of the plant as stored can confirm. A mode no input touches is split exactly (the split's
``dropped`` is 0); a mode hidden by a change of coordinates is split to the rounding of the staircase (``dropped <=
CONTROLLABILITY_RTOL ||[A, B]||``): lambda is then the least radius of the plant with those couplings set to zero,
and a verdict needs a certificate that survives the exact check of the plant as stored (markov_region).
"""

from __future__ import annotations

import functools

import numpy as np

from ..errors import InputError, NumericalError
from ..linalg import typed_linalg
from ..model.channel import GilbertElliott, MarkovChannel  # noqa: F401 (GilbertElliott: the doctests' constructor)
from ..tolerances import (
    CERTIFICATE_RTOL,
    COUPLED_BRACKET_RTOL,
    COUPLED_POLICY_REGULARISATION,
    COUPLED_ZERO_RTOL,
    HOMOGENEOUS_RICCATI_MAX_ITER,
    RICCATI_RTOL,
)
from .mjls import DENSE_MAX_DIM, mode_chain, second_moment_operator
from .riccati_map import (
    GRADED,
    POLICY_STEPS,
    SHIFT,
    certificate_bound,
    chain_rates,
    grading_scale,
    perron_adjoint,
    psd_size,
    reach_split,
    riccati_squares,
)

__all__ = ["chain_certificate_margin", "check_delivery", "homogeneous_coupled_riccati", "symmetric_perron"]

#: the power steps after which the policy iteration is tried (M n^2 <= DENSE_MAX_DIM; :func:`_reachable_eigenpair`;
#: its step cap riccati_map.POLICY_STEPS, the power iteration's shift riccati_map.SHIFT)
_CHECKPOINTS = (30, 90, 270, 810, 2430, HOMOGENEOUS_RICCATI_MAX_ITER)
#: the unregularised policy steps that finish the regularised ones (:func:`_refine`), the cut of the eigenvector's
#: directions they take the gains from, and the cut of the eigenvector returned (rounding of the eigenvalue routine)
_REFINE_STEPS, _REFINE_CUT, _EIGENVECTOR_CUT = 3, 1e-9, 1e-13


def _apply(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str, eps: float
           ) -> tuple[np.ndarray, float, bool]:
    """``(R_eps(P), lambda, zero)``: ``R_eps(P) = R(P) + eps Pi(P)``, ``Pi(P)_a = (sum_b tr P_b) I / (M n)`` (rho(Pi) =
    1), R as a sum of squares ``F_a'F_a`` (riccati_map.riccati_squares, its cutoff scaled to all of P; never
    negative; its error does not grow with the minimising gain, unlike ``A'E_aA - A'F_a K_a``); ``lambda = sum_a tr
    R(P)_a / sum_a tr P+_a`` (R's, P+ the PSD part of P) and whether R(P) is zero to rounding, ``sum_a tr R(P)_a <=
    COUPLED_ZERO_RTOL^2 ||A||^2 sum_a tr P+_a``: its factors are below the rounding of ``L'A``, on a scale set by
    the plant and all of P (not by what R would give without inputs at P: where the inputs cancel one mode in a
    step, the next step's P weighs the others by rounding only, and so would that). O(M^2 (n + m)(m + n)^2 + M
    n^3)."""
    M, n = P.shape[0], P.shape[1]
    factors, squares, weight = riccati_squares(P, A, B, *chain_rates(T, h, delivery), scaled=True)
    weight, squares = float(weight), float(squares)
    R = np.stack([F.T @ F for F in factors]) + (eps * weight / (M * n)) * np.eye(n)
    lam = squares / weight if weight > 0 else float("nan")
    zero = weight > 0 and squares <= COUPLED_ZERO_RTOL ** 2 * float(np.linalg.norm(A, 2)) ** 2 * weight
    return R, lam, bool(zero)


def _power(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str, first: int,
           steps: int) -> tuple[np.ndarray, float, str, float]:
    """Steps ``first .. steps - 1`` of the shifted power iteration from P: ``(P, lambda, how it ended, its last move
    ||P_next - P||)``, "zero" (R is nilpotent, below), "stopped" (``||P_next - P|| <= RICCATI_RTOL``, or lambda not
    positive and finite) or "steps".

    Steps ``0 .. M n`` run R itself, unshifted, from ``I / (M n)`` with the zero test of `_apply`: where
    ``R^j(I) = 0`` to rounding, ``R^j(P) = 0`` for every PSD P (monotone) and the least radius is 0 (every chain
    path can be driven to zero in j steps); the kernels of ``R^j(I)_a`` grow with j and stay once they stop growing,
    so M n + 1 steps decide it. Later steps run the regularised map ``R_eps`` (`_apply`, ``eps =
    COUPLED_POLICY_REGULARISATION lambda``, lambda R's at the step before): it maps every nonzero PSD tuple to a
    positive definite one, so its eigenvector is unique and positive definite and its power iteration converges from
    any start (nonlinear Perron–Frobenius). It has no other fixed point to stall at, and its gains are defined
    everywhere: on a direction R's eigenvector vanishes on (a transient mode, a block the inputs cancel) as eps times
    that part's discounted cost-to-go chooses them. Its eigenvalue is R's to O(eps).
    O((steps - first) M^2 (n + m)(m + n)^2)."""
    plain = P.shape[0] * P.shape[1] + 1
    lam, moved = float("nan"), float("inf")
    for step in range(first, steps):
        eps = COUPLED_POLICY_REGULARISATION * lam if step >= plain and np.isfinite(lam) and lam > 0 else 0.0
        R, lam, zero = _apply(P, A, B, T, h, delivery, eps)
        if zero and step < plain:
            return P, 0.0, "zero", moved
        total = float(np.trace(R, axis1=-2, axis2=-1).sum())
        if not (np.isfinite(lam) and lam > 0 and np.isfinite(total)):
            return P, lam, "stopped", moved
        shift = SHIFT if step >= plain else 0.0        # a shifted step keeps some of P: R^j(I) = 0 unseen
        P_next = (R / total + shift * P) / (1.0 + shift)
        moved = float(np.linalg.norm(P_next - P))
        P = P_next
        if moved <= RICCATI_RTOL and step >= plain:
            return P, lam, "stopped", moved
    return P, lam, "steps", moved


def _hessians(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str
              ) -> tuple[np.ndarray, np.ndarray]:
    """``(H, G)`` per mode with ``L_K^*(P)_a = A'E_aA - G_a'K_a - K_a'G_a + K_a' H_a K_a``: ``H_a = sum_b T_ab (D B'P_bB
    D + diag(d (1 - d)) ∘ B'P_bB)``, ``G_a = sum_b T_ab D B'P_b A`` (D = diag(d), d the step's delivery rates,
    riccati_map.chain_rates); the minimisers solve ``H_a K_a = G_a``. O(M^2 m (m + n) + M n^2 (n + m))."""
    m = B.shape[1]
    d = chain_rates(T, h, delivery)[1]
    BPB = np.einsum("ki,bkl,lj->bij", B, P, B)
    BPA = np.einsum("ki,bkl,lj->bij", B, P, A)
    H = np.einsum("ab,abi,abj,bij->aij", T, d, d, BPB)
    H += np.einsum("ab,abi,bii->ai", T, d * (1.0 - d), BPB)[:, :, None] * np.eye(m)
    G = np.einsum("ab,abi,bij->aij", T, d, BPA)
    return 0.5 * (H + H.transpose(0, 2, 1)), G


def _gains(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str,
           K: np.ndarray) -> np.ndarray:
    """The minimiser of ``L_K^*(P)`` nearest the gains K: ``K_a + H_a^+ (G_a - H_a K_a)`` (`_hessians`), H_a's
    pseudo-inverse cut at ``m eps ||B||^2 max_b ||P_b||``, the size a Hessian would have if the inputs reached what P
    weighs (not the Hessians' own largest: where P weighs what the inputs reach only at rounding level, every Hessian
    is rounding, and its inverse gave gains of 3e15 on a plant whose second channel never delivers). Where H_a is
    singular (a channel that cannot deliver from mode a, or a direction P does not weigh) the minimisers form an
    affine set; keeping K there is what lets the policy iteration improve one part of the gains without undoing
    another. O(M (m^3 + m^2 n))."""
    H, G = _hessians(P, A, B, T, h, delivery)
    w, V = np.linalg.eigh(H)
    scale = float(np.linalg.norm(B, 2)) ** 2 * max(float(np.linalg.norm(p, 2)) for p in P)
    keep = w > B.shape[1] * np.finfo(float).eps * scale
    inverse = np.where(keep, 1.0 / np.where(keep, w, 1.0), 0.0)
    step = np.einsum("aij,aj,akj,akl->ail", V, inverse, V, G - H @ K)
    return K + step


@functools.cache
def _duplication(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(D, E)``: ``vec(S) = D vech(S)`` for symmetric n×n S (row-major vec, vech the entries i <= j) and ``E =
    D^+`` (``vech(S) = E vec(S)``, the off-diagonal pairs averaged). O(n^4)."""
    pairs = [(i, j) for i in range(n) for j in range(i, n)]
    D = np.zeros((n * n, len(pairs)))
    for k, (i, j) in enumerate(pairs):
        D[i * n + j, k] = D[j * n + i, k] = 1.0
    return D, np.linalg.pinv(D)


def symmetric_perron(operator: np.ndarray, M: int, n: int) -> tuple[float, np.ndarray, float, float] | None:
    """``(root, V, radius, error)`` of the (M n^2)^2 matrix ``operator`` (a cone-preserving map on stacked
    ``vec(P_a)``, rows a first) restricted to symmetric tuples: its eigenvalue of largest real part, its eigenvector
    as (M, n, n) with ``sum_a tr V_a = 1``, the spectral radius (the Perron root, attained on the PSD cone: the same on
    all matrices), and a bound on the eigenvector's error relative to its largest eigenvalue (over the modes); None
    where they are not finite or the eigenvector has trace 0.

    Restricted, because a complex pair mu, conj(mu) of a mode's closed loop gives ``|mu|^2`` twice on all matrices
    (a symmetric and an antisymmetric eigenvector), once on symmetric ones. The eigenvector is the right singular
    vector v of ``restricted - root I`` for its least singular value s_N, not LAPACK's eigenvector: on deadbeat gains
    (many structural zeros) numpy.linalg.eig's balancing returned a vector of mixed signs, trace 0.04, for a simple
    root 1.71 whose null vector is well conditioned (next singular value 0.41; a decoupled plant behind two
    channels, every kernel). v is the exact null vector of a matrix within ``s_N + N eps s_1`` of ``restricted - root
    I`` (the root's own error included), so it is off by at most that over the next singular value s_(N-1) (a
    perturbation bound): ``error``, which decides what in it is rounding. O((M n^2)^3)."""
    D, E = _duplication(n)
    blocks = operator.reshape(M, n * n, M, n * n)
    restricted = np.einsum("pi,aibj,jq->apbq", E, blocks, D).reshape(M * D.shape[1], M * D.shape[1])
    vals = np.linalg.eigvals(restricted)
    if not np.all(np.isfinite(vals)):
        return None
    root, radius = float(np.max(vals.real)), float(np.max(np.abs(vals)))
    N = restricted.shape[0]
    _, s, vt = np.linalg.svd(restricted - root * np.eye(N))
    V = (vt[-1].reshape(M, -1) @ D.T).reshape(M, n, n)
    trace = float(np.trace(V, axis1=-2, axis2=-1).sum())
    top = float(np.max(np.abs(np.linalg.eigvalsh(V))))
    if not (np.isfinite(trace) and trace != 0.0 and top > 0.0):
        return None
    gap = float(s[-2]) if N > 1 else np.inf
    error = (float(s[-1]) + N * np.finfo(float).eps * float(s[0])) / gap / top if gap > 0 else np.inf
    return root, V / trace, radius, error


def _policy(P: np.ndarray, lam: float, A: np.ndarray, B: np.ndarray, channel: MarkovChannel, T: np.ndarray,
            h: np.ndarray, delivery: str) -> tuple[np.ndarray, np.ndarray]:
    """``(K, P_eps)``: from the power iteration's P (`_power`, positive definite), a policy iteration on the
    regularised map ``L_K^* + eps Pi`` (``eps = COUPLED_POLICY_REGULARISATION lambda``): K <- the minimiser at P_eps
    nearest K (`_gains`), P_eps the Perron eigenvector of the regularised map at K, while its root falls by
    more than RICCATI_RTOL, at most riccati_map.POLICY_STEPS steps; the gains of the least root and their eigenvector.

    P_eps is positive definite, so each step can only lower the root (``L_{K+}^*(P_eps) <= L_K^*(P_eps)``, a
    Collatz–Wielandt bound) and a fixed point is R_eps's eigenvector, unique. Near it the steps converge
    quadratically (Newton's method on ``R_eps(P) = lambda P``); far from it they can crawl by O(eps) a step: on
    pendulum_bursty at mean rate 1 (good absorbing, deliveries sure), started four power steps in, they settled the
    good state's gains at radius 0.923 where 0.901 is the least (the Perron eigenvector of a single mode's loop has
    rank two, and only its eps part says how to do better); hence the power steps first. O(steps (M n^2)^3)."""
    M, n = len(h), A.shape[0]
    eps = COUPLED_POLICY_REGULARISATION * lam
    ones = np.tile(np.eye(n).ravel(), M)
    lift = (eps / (M * n)) * np.outer(ones, ones)

    def regularised(K: np.ndarray) -> tuple[float, np.ndarray, float, float] | None:
        return symmetric_perron(second_moment_operator(A, B, channel, K, delivery).T + lift, M, n)

    K = _gains(P, A, B, T, h, delivery, np.zeros((M, B.shape[1], n)))
    found = regularised(K) if np.all(np.isfinite(K)) else None
    if found is None:
        raise NumericalError("the coupled Riccati policy iteration: the gains of the power iteration's eigenvector "
                             "or their operator are not finite")
    root, P_eps = found[:2]
    for _ in range(POLICY_STEPS):
        K_next = _gains(P_eps, A, B, T, h, delivery, K)
        found = regularised(K_next) if np.all(np.isfinite(K_next)) else None
        if found is None or not found[0] < root * (1.0 - RICCATI_RTOL):
            break
        K, (root, P_eps) = K_next, found[:2]
    return K, P_eps


def _reachable_eigenpair(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, T: np.ndarray, h: np.ndarray,
                         delivery: str) -> tuple[float, np.ndarray, np.ndarray]:
    """``(lambda, P, K)`` of a pair whose inputs reach every state (the split's reachable part, or the whole plant).

    For ``M n^2 <= DENSE_MAX_DIM``: the power iteration of the regularised map (`_power`) to the checkpoints
    _CHECKPOINTS, at each the policy iteration (`_policy`) and its unregularised finish (`_refine`): K
    the gains, their exact coupled radius (the dense operator's eigenvalues; an upper bound on the least radius) and
    P the Perron eigenvector of ``L_K^*``, whose Collatz–Wielandt bound (R's, `_bound`) is a lower one. It stops
    at the first checkpoint where the two meet within COUPLED_BRACKET_RTOL, or where the power iteration stopped,
    and returns lambda = the least radius of the gains found, P of the best bound. Where the power iteration finds
    ``R^j(I) = 0`` to rounding (every part deadbeat), lambda is 0.0 and K gains of small radius (a nilpotent loop in
    floating point is not of radius 0). Beyond the dense operator: the power iteration alone
    (HOMOGENEOUS_RICCATI_MAX_ITER steps), lambda R's sum of squares at its P (positive definite, with its eps part),
    K the gains there.
    Time as `homogeneous_coupled_riccati`."""
    M, n, m = len(h), A.shape[0], B.shape[1]
    P = np.repeat(np.eye(n)[None] / (n * M), M, axis=0)
    if M * n * n > DENSE_MAX_DIM:
        P, lam, ended, _ = _power(P, A, B, T, h, delivery, 0, HOMOGENEOUS_RICCATI_MAX_ITER)
        if ended == "zero":        # gains from the regularised map, as where R is not nilpotent
            P, lam, _, _ = _power(P, A, B, T, h, delivery, M * n + 1, HOMOGENEOUS_RICCATI_MAX_ITER)
            lam = 0.0
        return lam, P, _gains(P, A, B, T, h, delivery, np.zeros((M, m, n)))
    radius, K, lower, V, done, last, zero = np.inf, None, -np.inf, None, 0, np.inf, False
    for checkpoint in _CHECKPOINTS:
        P, lam, ended, moved = _power(P, A, B, T, h, delivery, done, checkpoint)
        if ended == "zero":        # gains from the regularised map, as where R is not nilpotent
            zero, checkpoint = True, max(checkpoint, M * n + 1 + _CHECKPOINTS[0])
            P, lam, ended, moved = _power(P, A, B, T, h, delivery, M * n + 1, checkpoint)
        done = checkpoint
        scale = lam if np.isfinite(lam) and lam > 0 else float(np.linalg.norm(A, 2)) ** 2
        gains, P_eps = _policy(P, scale, A, B, channel, T, h, delivery)
        gains, vector, upper = _refine(gains, P_eps, A, B, channel, T, h, delivery)
        if zero:
            return 0.0, vector, gains
        bound = _bound(vector, A, B, T, h, delivery)
        bound = bound if np.isfinite(bound) else -np.inf          # inf: the vector weighs nothing, proves nothing
        if upper < radius:
            radius, K = upper, gains
        if V is None or bound > lower:
            lower, V = bound, vector
        if radius <= lower * (1.0 + COUPLED_BRACKET_RTOL) or ended == "stopped" or not moved < last:
            break
        last = moved
    return radius, V, K


def _balanced_eigenpair(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, T: np.ndarray, h: np.ndarray,
                        delivery: str) -> tuple[float, np.ndarray, np.ndarray]:
    """`_reachable_eigenpair`, and where its P is graded (riccati_map.grading_scale: its diagonal, summed over the
    modes, spans more than riccati_map.GRADED) again on the plant scaled by ``D`` (``D^-1 A D``, ``D^-1 B``: exact
    in floating point, the same operators up to similarity), mapped back (``P = D^-1 P~ D^-1``, ``K = K~ D^-1``),
    kept where its lambda is smaller: for ``M n^2 <= DENSE_MAX_DIM`` each lambda is the exact coupled radius of its
    own gains, an upper bound on the least radius. On a chain of four integrators behind a one-mode chain the
    unscaled lambda was 5.6e-3 above Elia's value (1.0023 for 0.99689 at mu = 0.0124); scaled it agrees to 1e-13
    (region's iteration balances the same way). Time the eigenpair's, twice for a graded P."""
    lam, P, K = _reachable_eigenpair(A, B, channel, T, h, delivery)
    D = grading_scale(P, GRADED) if len(h) * A.shape[0] ** 2 <= DENSE_MAX_DIM and lam > 0 else None
    if D is None:
        return lam, P, K
    lam_, P_, K_ = _reachable_eigenpair(A * D[None, :] / D[:, None], B / D[:, None], channel, T, h, delivery)
    if not lam_ < lam:
        return lam, P, K
    return lam_, P_ / D[None, :, None] / D[None, None, :], K_ / D[None, None, :]


def _clean(P: np.ndarray, cut: float) -> np.ndarray:
    """P (M, n, n) with its eigenvalues at or below ``cut`` times the largest over all modes set to 0 (negative ones
    too): its PSD part without the directions it weighs at that level. O(M n^3)."""
    w, U = np.linalg.eigh(0.5 * (P + P.transpose(0, 2, 1)))
    w = np.where(w > cut * max(float(np.max(w)), 0.0), w, 0.0)
    return np.einsum("aij,aj,akj->aik", U, w, U)


def _refine(K: np.ndarray, P_eps: np.ndarray, A: np.ndarray, B: np.ndarray, channel: MarkovChannel,
            T: np.ndarray, h: np.ndarray, delivery: str) -> tuple[np.ndarray, np.ndarray, float]:
    """``(K, P, radius)``: from the regularised policy iteration's gains, unregularised policy steps (at most
    _REFINE_STEPS): P the Perron eigenvector of ``L_K^*`` (exact for K, to the eigenvalue routine's rounding), then
    K <- the minimiser at P (its directions below _REFINE_CUT of the largest cut off, K kept on the rest,
    `_gains`), taken while the radius does not grow beyond RICCATI_RTOL. Returns the last gains, their radius
    and their Perron eigenvector without the directions it weighs below its own error bound (`symmetric_perron`; at
    least _EIGENVECTOR_CUT): they are rounding, and a Collatz–Wielandt bound counts every direction it weighs (a
    mode left at trace 1e-12 where R's eigenvector vanishes bounds the radius by 0).

    Why: K minimises the regularised map, so where R's eigenvector is degenerate (rank one on a mode, zero on a
    mode whose inputs cancel it) the Perron eigenvector of ``L_K^*`` weighs directions R's does not (at 1e-10 ..
    1e-14) and its leading directions are tilted off R's by about 1e-9; a Collatz–Wielandt bound of a degenerate P
    does not survive a tilt (``R(P) = a v v' >= c u u'`` only for ``u || v``; 0.0 for 1.13 on pendulum_bursty at mean
    rate 0, before). A policy step from the cleaned eigenvector is exact on its support, and squares the tilt.
    Where the eigenvector is not PSD beyond its error bound (a double root) the regularised one is taken.
    O(steps (M n^2)^3)."""
    M, n = len(h), A.shape[0]

    def perron(gains: np.ndarray) -> tuple[float, np.ndarray] | None:
        found = symmetric_perron(second_moment_operator(A, B, channel, gains, delivery).T, M, n)
        if found is None:
            return None
        _, V, radius, error = found
        cut = max(error, _EIGENVECTOR_CUT)
        size = max(float(np.linalg.norm(v, 2)) for v in V)
        if min(float(np.linalg.eigvalsh(v)[0]) for v in V) < -cut * size:
            return radius, P_eps
        return radius, _clean(V, cut)

    found = perron(K)
    if found is None:
        raise NumericalError("the coupled Riccati eigenpair: the operator of the policy iteration's gains is not "
                             "finite")
    radius, V = found
    for _ in range(_REFINE_STEPS):
        K_next = _gains(_clean(V, _REFINE_CUT), A, B, T, h, delivery, K)
        found = perron(K_next) if np.all(np.isfinite(K_next)) else None
        if found is None or found[0] > radius * (1.0 + RICCATI_RTOL):
            break
        K, (radius, V) = K_next, found
    return K, V, radius


@typed_linalg("the coupled Riccati eigenpair")
def homogeneous_coupled_riccati(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, delivery: str = "next"
                                ) -> tuple[float, np.ndarray, np.ndarray]:
    """``(lambda, P, K)``: lambda the least mean-square radius ``min_K rho(L_K)`` over mode-dependent laws, P
    (M, n, n, ``sum_a tr P_a = 1``) the eigenvector ``R(P) = lambda P`` of the homogeneous coupled Riccati map (on the
    reachable subspace; module docstring), K (M, m, n) mode gains of radius lambda.

    The part no input reaches is split off first (linalg.controllable_split): ``lambda = max(rho(A_uu)^2,
    lambda_c)`` with lambda_c the reachable pair's (module docstring, "The part no input reaches"); no gain acts on
    it, none is computed for it. On the reachable pair (`_reachable_eigenpair`): a shifted power iteration of R
    in sum-of-squares form, then, for ``M n^2 <= DENSE_MAX_DIM``, a policy iteration on the regularised Perron
    eigenvector, whose gains stay bounded where the eigenvector vanishes; lambda is then their exact coupled radius,
    and P the Perron eigenvector of ``L_K^*``, whose Collatz–Wielandt bound `chain_certificate_margin` meets
    lambda from below. Where every part is deadbeat (``R^j(I) = 0`` to rounding) lambda is 0.0. A candidate:
    markov_region.chain_membership checks it. Time O(iterations M^2 (n + m)^3 + policy steps (M n^2)^3 + n^4).

    Raises
    ------
    NumericalError
        A linear-algebra routine failed, or the policy iteration's operator is not finite.

    Examples
    --------
    >>> lam, P, K = homogeneous_coupled_riccati(np.array([[2.0]]), np.array([[1.0]]), GilbertElliott(p=[0.3], r=[0.6]))
    >>> round(lam, 9), round(float(K[0, 0, 0]), 9)   # deadbeat when good (h = 1); a^2 (1 - r) = 1.6
    (1.6, 2.0)
    >>> A = np.diag([2.0, 1.5])                        # x2 is reached by no input: lambda = max(1.5^2, 1.6)
    >>> lam, P, K = homogeneous_coupled_riccati(A, np.array([[1.0], [0.0]]), GilbertElliott(p=[0.3], r=[0.6]))
    >>> round(lam, 12), np.round(P[:, 1, 1], 12).tolist(), K[:, 0, 1].tolist()
    (2.25, [0.5, 0.5], [0.0, 0.0])
    """
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    check_delivery(delivery)
    _, T, h = mode_chain(channel)
    M, n, m = len(h), A.shape[0], B.shape[1]
    with np.errstate(over="ignore", invalid="ignore"):
        split, Bt = reach_split(A, B, np.any(h > 0, axis=0))
        if split.nc == n:
            return _balanced_eigenpair(A, B, channel, T, h, delivery)
        nc = split.nc
        reach, rest = split.T[:, :nc], split.T[:, nc:]
        lam_u = split.uncontrollable_radius ** 2
        lam_c, K = 0.0, np.zeros((M, m, n))
        if nc:
            lam_c, P_c, K_c = _balanced_eigenpair(split.A_cc, Bt[:nc], channel, T, h, delivery)
            K = np.einsum("aij,kj->aik", K_c, reach)                      # u = -K_c x_c, x_c = T_c' x
        if nc == 0 or not lam_c > lam_u:
            P = np.repeat((rest @ perron_adjoint(split.A_uu) @ rest.T)[None] / M, M, axis=0)
        else:       # the whole map's eigenvector, iterated from the reached part's (a certificate on all of the space)
            P = np.einsum("ij,ajk,lk->ail", reach, P_c, reach)
            whole = _power(P, A, B, T, h, delivery, M * n + 1, M * n + 1 + HOMOGENEOUS_RICCATI_MAX_ITER)[0]
            P = whole if np.all(np.isfinite(whole)) else P
    return max(lam_u, lam_c), 0.5 * (P + P.transpose(0, 2, 1)), K


def _bound(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str) -> float:
    """The largest c with ``R(P)_a >= c P_a`` over the modes P weighs (riccati_map.certificate_bound, its cutoff
    scaled to all of P; inf where P weighs none). O(M^2 (n + m)(m + n)^2 + M n^3)."""
    return certificate_bound(P, A, B, *chain_rates(T, h, delivery), scaled=True)


@typed_linalg("the chain certificate's margin")
def chain_certificate_margin(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, P: np.ndarray,
                             delivery: str = "next") -> float:
    """``c - 1``, c the bound every mode-dependent law's coupled radius meets by the certificate P (M, n, n): the
    largest c with ``R(P)_a >= c P_a`` for every mode a that P weighs, so ``L_K^*(P) >= c P`` and ``rho(L_K) >= c``
    for every K (Collatz–Wielandt), i.e. ``[[A'E_aA - cP_a, -A'F_a], [-F_a'A, H_a]] >= 0`` for every mode.
    ``R(P)_a = F_a'F_a`` is the least-squares residual of the factors of ``L_K^*(P)_a``, stacked over the next mode
    b with weights ``sqrt(T_ab)`` (riccati_map.riccati_factors at P_b with h_b, "next", or h_a, "current"); each
    mode's bound is riccati_map.radius_bound.

    Where some part of the plant no input reaches (linalg.controllable_split), the bound is taken in the split's
    coordinates, the couplings it dropped set to zero, and also over the reachable subspace alone where P weighs it
    above rounding: every closed loop ``A - B V K`` maps that subspace into itself, so the same Collatz–Wielandt
    argument on PSD matrices supported there gives ``rho(L_K) >= c`` with the reachable block of ``T'P_aT`` and
    ``(A_cc, B_c)`` (the bound over the whole space is 0 there: ``x_u`` can cancel ``A_cc x_c``). c is the larger.

    ``>= -CERTIFICATE_RTOL`` proves (to rounding) that no mode-dependent law stabilises: a band on the radius, as
    for Bernoulli losses. ``-inf`` when P is not PSD or is zero. Time O(M (M (n + m) (m + n)^2 + n^3) + n^4).

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.3], r=[0.2])          # one state a = 2: stabilisable iff r > 3/4
    >>> lam, P, K = homogeneous_coupled_riccati(np.array([[2.0]]), np.array([[1.0]]), ch)
    >>> chain_certificate_margin(np.array([[2.0]]), np.array([[1.0]]), ch, P) >= -1e-12   # CERTIFICATE_RTOL
    True
    """
    check_delivery(delivery)
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    _, T, h = mode_chain(channel)
    P = np.asarray(P, dtype=float)
    P = 0.5 * (P + P.transpose(0, 2, 1))
    size = psd_size(P)
    if not size > 0:
        return float("-inf")
    split, Bt = reach_split(A, B, np.any(h > 0, axis=0))
    nc, n = split.nc, A.shape[0]
    if nc == n:
        return _bound(P, A, B, T, h, delivery) - 1.0
    Q = np.einsum("ji,ajk,kl->ail", split.T, P, split.T)                # T'P_aT
    bound = _bound(Q, split.A, Bt, T, h, delivery)
    reached = Q[:, :nc, :nc]
    if nc and max(float(np.linalg.norm(q, 2)) for q in reached) > n * np.finfo(float).eps * size:
        top = max(float(np.linalg.norm(q, 2)) for q in reached)
        if min(float(np.linalg.eigvalsh(q)[0]) for q in reached) >= -CERTIFICATE_RTOL * top:
            bound = max(bound, _bound(reached, split.A_cc, Bt[:nc], T, h, delivery))
    return bound - 1.0


def check_delivery(delivery: str) -> None:
    """Refuse a delivery convention other than "current" or "next" (InputError naming ``delivery``). O(1)."""
    if delivery not in ("current", "next"):
        raise InputError("delivery", f"expected current or next, found {delivery!r}")
