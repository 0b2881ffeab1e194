"""The stabilisable set behind Gilbert–Elliott channels (issue 21 item 6): can some mode-dependent linear law
``u = -K_a x`` (a the channel state the law knows: the last one, or the current one) make the loop mean-square
stable, and where, over each channel's mean rate at fixed burstiness?

With ``E_a = sum_b T_ab P_b`` (T the mode chain, h_a the per-mode delivery probabilities) the adjoint of the
coupled second-moment map of gains K is the quadratic ``L_K^*(P)_a = A'E_aA - 2 A'F_a K_a + K_a' H_a K_a``:
with the deliveries following the next mode b ("next", the default: the law knows the last state, as a TCP-like
acknowledgement of a Gilbert channel reveals it) ``F_a = sum_b T_ab P_b B H_b`` and ``H_a = sum_b T_ab (H_b B'P_bB
H_b + diag(h_b (1 - h_b)) ∘ B'P_bB)``; following the current mode a ("current": the law knows the state that
decides this step's deliveries) ``F_a = E_a B H_a``, ``H_a = H_a B'E_aB H_a + diag(h_a (1 - h_a)) ∘ B'E_aB``
(H_b = diag(h_b); markov.mjls's two conventions). As for
Bernoulli losses (simulation.region) two certificates, each checked in numpy by the operator it speaks about:

- **inside**: mode gains K whose coupled map has radius ``< 1 - MEAN_SQUARE_MARGIN`` (mjls.mean_square_radius);
- **outside**: ``P_a >= 0``, ``sum_a tr P_a = 1``, with, for every mode a,

  .. math:: T_a(P) = \\begin{bmatrix} A'E_aA - P_a & -A'F_a \\\\ -F_a'A & H_a \\end{bmatrix} \\succeq 0,

  i.e. ``L_K^*(P) >= P`` for every K (``x'(L_K^*(P)_a - P_a)x = [x; K_a x]' T_a(P) [x; K_a x]``), so
  ``<P, L_K^j(Q)> >= <P, Q> > 0`` for Q > 0 and every j: no mode-dependent law is mean-square stabilising.

Both come from the homogeneous coupled Riccati map ``R(P)_a = min_K L_K^*(P)_a`` (the coupled equations of
markov.mjls with Omega = Psi = 0: ``R(P)_a = A'E_aA - A'F_a H_a^+ F_a'A``), monotone,
concave and positively homogeneous on the PSD cone: its shifted power iteration reaches ``R(P) = lambda P``,
lambda = min_K rho(L_K); its minimiser is the inside certificate when lambda < 1, its P the outside one when
lambda >= 1. A certificate that does not check is "undecided", never "unstable".

A memoryless chain (p + r = 1) is in state good with probability r at every step, independently of the past,
so under "next" it delivers Bernoulli(r h_good + p h_bad) unknown to the law and its set is S at that mean rate
(tested; under "current" the law knows which packets will arrive, and the set is larger); one state and a
Gilbert channel (h_good = 1, h_bad = 0): the deadbeat gain in the good state leaves ``x+ = a x`` in the bad one,
radius ``a^2 (1 - r)``, so the loop is stabilisable iff ``r > 1 - 1/a^2`` whatever p (tested).

Where the Perron eigenvector vanishes on some modes (a transient state: a channel whose mean rate is h_good
has p = 0) the minimiser gives those modes gain 0, which may not stabilise them; the gains are then taken
once more from ``P + _LIFT I`` (optimal to within _LIFT on the support, sensible off it) and checked again.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..channel import GilbertElliott
from ..errors import InputError, NumericalError
from ..markov.mjls import DENSE_MAX_DIM, mode_chain, second_moment_operator
from ..markov.mjls import mean_square_radius as mjls_radius
from ..recursion import riccati_step
from ..results.region import CriticalPoint, Membership
from ..tolerances import CERTIFICATE_RTOL, CRITICAL_MU_TOL, HOMOGENEOUS_RICCATI_MAX_ITER, RICCATI_RTOL
from .critical import critical_point
from .region import converges_within, least_squares_residual, moment_factor, psd_factor, radius_bound
from .stability import is_mean_square_stable

__all__ = ["chain_at_rate", "chain_certificate_margin", "chain_critical_rate", "chain_membership", "chain_outside",
           "chain_rate_map",
           "critical_rate_unproved", "homogeneous_coupled_riccati"]

#: the power iteration's shift (as simulation.region: removes a peripheral spectrum)
_SHIFT = 0.1
#: power steps before the policy iteration takes over (M n^2 <= DENSE_MAX_DIM), the step after which a point
#: too slow to converge within them is handed over at once, and the policy iteration's step cap (as
#: simulation.region: pendulum_bursty's coupled steps shrink by about 0.93 each, some 360 power steps a point)
_POWER_STEPS, _POWER_WATCH, _POLICY_STEPS = 30, 4, 50
#: how far from a fixed point of R (``||R(P) / lambda - P||``, sum of traces 1) a policy iteration's P may be and
#: still be taken: the power iteration's own stop (its step is this residual / 1.1). On 24 random chains, both
#: conventions, the policy iteration's P came out within 1.8e-14 at 39 points and 2e-6 to 4e-3 away at 9
#: (transient or gainless modes: the Perron eigenvector of L_K^* at a K that is not R's minimiser there); more
#: policy steps then reach a fixed point (:func:`_policy_until_fixed`, session 30), else the power steps go on
_FIXED_TOL = RICCATI_RTOL
#: the lift of P on every mode when its own minimiser's gains do not check (module docstring)
_LIFT = 1e-6


def _step(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str
          ) -> tuple[np.ndarray, np.ndarray]:
    """``(K, R(P))`` per mode a: the quadratic ``L_K^*(P)_a = A'E_aA - 2 A'F_a K_a + K_a' H_a K_a`` (module
    docstring), its minimiser (least squares: H_a may be singular) and minimum. "current" is, per mode, Theorem 1's
    step with no weights at ``(E_a, h_a)`` (:func:`~packetloss_cvx.recursion.riccati_step`, least squares: the one
    kernel markov.mjls's coupled equations run, there with their weights). O(M (M (n^2 m + m^2) + n^3 + m^3))."""
    E = np.einsum("ab,bij->aij", T, P)
    E = 0.5 * (E + E.transpose(0, 2, 1))
    if delivery == "current":   # deliveries follow mode a, known to the law: per mode the Bernoulli step at (E_a, h_a)
        return riccati_step(E, A, B, h, np.zeros_like(h), variance=True, least_squares=True)
    BPB = np.einsum("ki,bkl,lj->bij", B, P, B)                     # B'P_bB per mode b
    own = (BPB * h[:, None, :]) * h[:, :, None] + np.einsum("bi,ij->bij", h * (1 - h),
                                                             np.eye(B.shape[1])) * BPB
    F = np.einsum("ab,bij,jk,bk->aik", T, P, B, h)                  # deliveries follow the next mode b
    H = np.einsum("ab,bij->aij", T, own)
    K = np.array([np.linalg.lstsq(H[a], F[a].T @ A, rcond=None)[0] for a in range(len(h))])
    R = np.einsum("ji,ajk,kl->ail", A, E, A) - np.einsum("ji,ajk,akl->ail", A, F, K)
    return K, 0.5 * (R + R.transpose(0, 2, 1))


def homogeneous_coupled_riccati(A: np.ndarray, B: np.ndarray, channel: GilbertElliott, delivery: str = "next"
                                ) -> tuple[float, np.ndarray, np.ndarray]:
    """``(lambda, P, K)``: the eigenpair ``R(P) = lambda P`` of the homogeneous coupled Riccati map
    (``sum_a tr P_a = 1``, P of shape (M, n, n)) and the mode gains (M, m, n) that attain the minimum, by the
    shifted power iteration until ``||P_next - P|| <= RICCATI_RTOL``; for ``M n^2 <= DENSE_MAX_DIM`` a policy
    iteration on the Perron eigenvector of the dense coupled operator finishes a point after 30 steps, or after 4
    when its last two steps shrink too slowly to reach RICCATI_RTOL within the 30 (as simulation.region's), else
    the iteration stops after ``HOMOGENEOUS_RICCATI_MAX_ITER`` steps. Where the policy iteration settles off a
    fixed point of R, more policy steps look for one (:func:`_policy_until_fixed`). A candidate:
    :func:`chain_membership` checks it. Time O(iterations M (M n^2 + n^3 + m^3)), plus O((M n^2)^3) a policy step.

    Examples
    --------
    >>> lam, P, K = homogeneous_coupled_riccati(np.array([[2.0]]), np.array([[1.0]]), GilbertElliott(p=[0.3], r=[0.6]))
    >>> round(lam, 9), round(float(K[0, 0, 0]), 9)   # deadbeat when good (h = 1); a^2 (1 - r) = 1.6
    (1.6, 2.0)
    """
    return _eigenpair(A, B, channel, delivery, settle=True)[:3]


def _eigenpair(A: np.ndarray, B: np.ndarray, channel: GilbertElliott, delivery: str, settle: bool
               ) -> tuple[float, np.ndarray, np.ndarray, bool]:
    """:func:`homogeneous_coupled_riccati`'s ``(lambda, P, K)`` and whether the settling policy steps gave them.
    ``settle`` False: where the policy iteration settles off a fixed point of R the power iteration goes on at
    once (no :func:`_policy_until_fixed`), which gives another P, a certificate where the settled P weighs some
    modes by 1e-26 or less (:func:`_membership`)."""
    _, T, h = mode_chain(channel)
    M, n = len(h), A.shape[0]
    P = np.repeat(np.eye(n)[None] / (n * M), M, axis=0)
    K = np.zeros((M, B.shape[1], n))
    policy = M * n * n <= DENSE_MAX_DIM
    steps = _POWER_STEPS if policy else HOMOGENEOUS_RICCATI_MAX_ITER
    gains = None
    with np.errstate(over="ignore", invalid="ignore"):
        P, ended = _power(P, A, B, T, h, delivery, 0, steps, policy)
        if policy and ended != "stopped":
            found, moved = _policy_iteration(P, A, B, channel, T, h, delivery)
            fixed = moved and _fixed(found, A, B, T, h, delivery)
            if moved and not fixed and settle:
                found, gains = _policy_until_fixed(found, A, B, channel, T, h, delivery)
                fixed = gains is not None
            if fixed:
                P = found
            else:
                # not a fixed point of R: on a transient mode (a chain state never reached again, e.g. good with
                # r = 0) every gain gives the same radius, so the Perron eigenvector of L_K^* need not be one of
                # R; the power iteration goes on as without the policy iteration
                P, _ = _power(P, A, B, T, h, delivery, _POWER_WATCH if ended == "slow" else steps,
                              HOMOGENEOUS_RICCATI_MAX_ITER, False)
        # the gains whose Perron eigenvector P is where the policy steps found it (a minimiser at P, of radius
        # lambda; the least-squares minimiser at P leaves the modes P nearly vanishes on with gain 0), else P's own
        K = gains if gains is not None else _step(P, A, B, T, h, delivery)[0]
    return _eigenvalue(P, A, B, T, h, delivery), P, K, gains is not None


def _eigenvalue(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str) -> float:
    """lambda = sum_a tr R(P+)_a / sum_a tr P+_a (P+ the PSD part of P), a sum of squares: never negative (as
    simulation.region's); nan where P is not finite or has no PSD part. O(M (M n^2 m + n^3))."""
    if not np.all(np.isfinite(P)):
        return float("nan")
    L, w = psd_factor(P)
    total = float(np.sum(w))
    squares = sum(float(np.sum(F * F)) for F in _riccati_factors(L, A, B, T, h, delivery))
    return squares / total if total > 0 else float("nan")


def _power(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str, first: int,
           steps: int, watch: bool) -> tuple[np.ndarray, str]:
    """The shifted power iteration's steps ``first .. steps - 1`` from P: ``(P, how it ended)``, "stopped"
    (``||P_next - P|| <= RICCATI_RTOL``, or lambda not positive and finite), "slow" (with ``watch``: after step
    _POWER_WATCH its last two steps shrink too slowly to reach RICCATI_RTOL by the last step; as
    simulation.region) or "steps" (all taken). O((steps - first) M (M n^2 + n^3 + m^3))."""
    last = float("inf")
    for step in range(first, steps):
        _, R = _step(P, A, B, T, h, delivery)
        lam = float(sum(np.trace(r) for r in R))
        if not (np.isfinite(lam) and lam > 0):
            return P, "stopped"
        P_next = (R / lam + _SHIFT * P) / (1.0 + _SHIFT)
        moved = float(np.linalg.norm(P_next - P))
        P = P_next
        if moved <= RICCATI_RTOL:
            return P, "stopped"
        if watch and step + 1 == _POWER_WATCH and not converges_within(moved, last, steps - step - 1):
            return P, "slow"
        last = moved
    return P, "steps"


def _fixed(P: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str) -> bool:
    """Is P (sum of traces 1) an eigenvector of R, ``||R(P) / lambda - P|| <= _FIXED_TOL``? O(M (M n^2 m + n^3))."""
    _, R = _step(P, A, B, T, h, delivery)
    lam = float(sum(np.trace(r) for r in R))
    return bool(np.isfinite(lam) and lam > 0 and float(np.linalg.norm(R / lam - P)) <= _FIXED_TOL)


def _perron(P: np.ndarray, A: np.ndarray, B: np.ndarray, channel: GilbertElliott, T: np.ndarray, h: np.ndarray,
            delivery: str) -> tuple[float, np.ndarray, np.ndarray] | None:
    """One policy step from P (M, n, n): K = argmin L_K^*(P), then ``(rho(L_K), its Perron eigenvector of L_K^*
    scaled to sum_a tr = 1, K)``; None where K or the eigenvector is not finite, or the root is degenerate
    (lambda <= 0, or the eigenvector not PSD to CERTIFICATE_RTOL). O((M n^2)^3)."""
    M, n = P.shape[0], A.shape[0]
    K, _ = _step(P, A, B, T, h, delivery)
    if not np.all(np.isfinite(K)):
        return None
    vals, vecs = np.linalg.eig(second_moment_operator(A, B, channel, K, delivery).T)
    top = int(np.argmax(vals.real))
    lam = float(vals[top].real)
    V = vecs[:, top].real.reshape(M, n, n)        # rows of the operator: vec(Q_b) row-major, b first
    V = 0.5 * (V + V.transpose(0, 2, 1))
    trace = float(np.trace(V, axis1=-2, axis2=-1).sum())
    if not (np.isfinite(lam) and trace != 0.0):
        return None
    Pn = V / trace
    # a degenerate Perron root (lambda = 0, its eigenvector not PSD): keep the last good P
    if lam <= 0.0 or min(float(np.linalg.eigvalsh(p)[0]) for p in Pn) < -CERTIFICATE_RTOL:
        return None
    return lam, Pn, K


def _policy_until_fixed(P: np.ndarray, A: np.ndarray, B: np.ndarray, channel: GilbertElliott, T: np.ndarray,
                        h: np.ndarray, delivery: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Policy steps (:func:`_perron`) from a settled policy iteration's P that is not a fixed point of R, at most
    _POLICY_STEPS, until one is (:func:`_fixed`) whose lambda (:func:`_eigenvalue`, what the caller reports) is the
    gains' Perron root to _FIXED_TOL: ``(that P, the gains K whose Perron eigenvector it is)``, else ``(P, None)``.
    Since ``L_K^*(P) = lambda P = R(P)`` there to RICCATI_RTOL, K attains R's minimum at P, and its radius is
    lambda. (Where the wandering gains reach 1e18-1e32 on a mode no channel actuates, a fixed point of R by the
    traces can have a sum-of-squares lambda far below the root: 0.82 against 1.475 = a_3^2 on a decoupled plant,
    tests/test_markov_region.py; such a P is not taken.)

    Where the eigenvector concentrates on a gainless mode (the chain state where every channel is lost, known to
    a "current" law) the other modes' P_a tend to 0 and every E_a to rank one, the Hessians H_a to singular, and
    the least-squares minimiser is free along their near-kernel: lambda settles (its error is second order in K)
    while P is still 1e-6 to 1e-3 from a fixed point, and the next step's K may throw it back. The steps wander,
    but land on a fixed point of R to rounding within a few (tests/test_markov_region.py's "current" chains: 3 to
    21), where the power iteration crawls towards one (5,000 steps, the residual still about 1e-5). A P taken
    here is checked like any other: the caller's certificates. O(_POLICY_STEPS (M n^2)^3)."""
    Q = P
    for _ in range(_POLICY_STEPS):
        found = _perron(Q, A, B, channel, T, h, delivery)
        if found is None:
            break
        root, Q, K = found
        if _fixed(Q, A, B, T, h, delivery) and abs(_eigenvalue(Q, A, B, T, h, delivery) - root) <= _FIXED_TOL * root:
            return Q, K
    return P, None


def _policy_iteration(P: np.ndarray, A: np.ndarray, B: np.ndarray, channel: GilbertElliott, T: np.ndarray,
                      h: np.ndarray, delivery: str) -> tuple[np.ndarray, bool]:
    """From power-iteration P (M, n, n): the mode gains K = argmin L_K^*(P), then P = the Perron eigenvector of
    L_K^* (the transpose of markov.mjls.second_moment_operator, dense), until lambda settles (as
    simulation.region's, for the coupled map). Each step can only lower rho (``L_{K+}^*(P) <= L_K^*(P) = lambda
    P``, a Collatz-Wielandt bound), so it converges where the power iteration crawls. A candidate like the power
    iteration's: the caller checks it. Returns the P found and whether it moved (False: P given back). Time
    O((M n^2)^3) a step."""
    best, last, moved = P.copy(), float("inf"), False
    for _ in range(_POLICY_STEPS):
        found = _perron(P, A, B, channel, T, h, delivery)
        if found is None:
            break
        lam, Pn, _ = found
        settled = lam >= last * (1.0 - RICCATI_RTOL)
        if not settled or lam <= last:
            best, moved = Pn, True
        if settled:
            break
        last, P = lam, Pn
    return best, moved


def chain_certificate_margin(A: np.ndarray, B: np.ndarray, channel: GilbertElliott, P: np.ndarray,
                             delivery: str = "next") -> float:
    """``c - 1``, c the bound every mode-dependent law's coupled radius meets by the certificate P (M, n, n): the
    largest c with ``R(P)_a >= c P_a`` for every mode a that P weighs, so ``L_K^*(P) >= c P`` and ``rho(L_K) >= c``
    for every K (Collatz-Wielandt), i.e. ``T_a(P)`` (module docstring) with ``A'E_aA - cP_a`` in its corner is PSD.
    ``R(P)_a = F_a'F_a`` is the least-squares residual (region.least_squares_residual) of the factors of
    ``L_K^*(P)_a``, stacked over the next mode b with weights ``sqrt(T_ab)`` (region.moment_factor at P_b with
    h_b, "next", or h_a, "current"); each mode's bound is region.radius_bound. ``>= -CERTIFICATE_RTOL`` proves (to
    rounding) that no mode-dependent law stabilises: a band on the radius, as for Bernoulli losses (the least
    eigenvalue of T_a over its scale, the check before, shrinks like ``1 / ||K||^2``). ``-inf`` when P is not PSD
    or is zero. Time O(M (M (n + m) (m + n)^2 + n^3)).

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.3], r=[0.2])          # one state a = 2: stabilisable iff r > 3/4
    >>> lam, P, K = homogeneous_coupled_riccati(np.array([[2.0]]), np.array([[1.0]]), ch)
    >>> chain_certificate_margin(np.array([[2.0]]), np.array([[1.0]]), ch, P) >= -1e-12   # CERTIFICATE_RTOL
    True
    """
    _check_delivery(delivery)
    _, T, h = mode_chain(channel)
    P = 0.5 * (P + P.transpose(0, 2, 1))
    size = max(float(np.linalg.norm(p, 2)) for p in P) if np.all(np.isfinite(P)) else float("nan")
    if not size > 0 or min(float(np.linalg.eigvalsh(p)[0]) for p in P) < -CERTIFICATE_RTOL * size:
        return float("-inf")
    factors = _riccati_factors(psd_factor(P)[0], A, B, T, h, delivery)
    worst = min((radius_bound(F, P[a]) for a, F in enumerate(factors) if np.any(P[a])), default=np.inf)
    return worst - 1.0                                # a mode P does not weigh asks nothing of R(P)_a


def _riccati_factors(L: np.ndarray, A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str
                     ) -> list[np.ndarray]:
    """``F_a`` with ``R(P)_a = F_a'F_a`` for ``P_b = L_b L_b'``: the factors of ``L_K^*(P)_a`` stacked over the next
    mode b (weights ``sqrt(T_ab)``; deliveries h_b, "next", or h_a, "current"), least-squares residual in u.
    O(M^2 (n + m)(m + n)^2)."""
    M, n = len(h), A.shape[0]
    out = []
    for a in range(M):
        rates = h if delivery == "next" else np.repeat(h[a][None], M, axis=0)
        phi_x, phi_u = moment_factor(L, A, B, rates)
        weight = np.sqrt(T[a])[:, None, None]
        out.append(least_squares_residual((weight * phi_x).reshape(-1, n), (weight * phi_u).reshape(-1, B.shape[1])))
    return out


def chain_outside(A: np.ndarray, B: np.ndarray, channel: GilbertElliott, P: np.ndarray, delivery: str
                  ) -> tuple[float, np.ndarray | None]:
    """``(margin, certificate)``: P (normalised to ``sum_a tr P_a = 1``) when its margin is ``>= -CERTIFICATE_RTOL``,
    else P with its eigenvalues below 1e-12, 1e-9, 1e-6 of the largest (over all modes) cut off, the first that
    checks (each a certificate in its own right: the power iteration leaves rounding weight on modes and blocks of
    smaller radius); ``(margin of P, None)`` when none does. Time O(4 chain margins)."""
    P = P / max(float(sum(np.trace(p) for p in P)), np.finfo(float).tiny)
    margin = chain_certificate_margin(A, B, channel, P, delivery)
    if margin >= -CERTIFICATE_RTOL:
        return margin, P
    w, U = np.linalg.eigh(0.5 * (P + P.transpose(0, 2, 1)))
    top = float(np.max(w))
    for cut in (1e-12, 1e-9, 1e-6):
        kept = w > cut * top
        if np.all(kept) or not np.any(kept):
            continue
        Q = np.einsum("aij,aj,akj->aik", U, np.where(kept, w, 0.0), U)
        Q = Q / float(sum(np.trace(q) for q in Q))
        cut_margin = chain_certificate_margin(A, B, channel, Q, delivery)
        if cut_margin >= -CERTIFICATE_RTOL:
            return cut_margin, Q
    return margin, None


def _check_delivery(delivery: str) -> None:
    if delivery not in ("current", "next"):
        raise InputError("delivery", f"expected current or next, found {delivery!r}")


def chain_membership(A: npt.ArrayLike, B: npt.ArrayLike, channel: GilbertElliott, delivery: str = "next"
                     ) -> Membership:
    """Can some mode-dependent linear law make the loop behind ``channel`` mean-square stable? ``delivery`` as
    markov.mjls: "next" (default; the law knows the last state, as a TCP-like acknowledgement reveals it, the
    deliveries follow the state the chain moves to) or "current" (the law knows the state that decides this
    step's deliveries). A Membership: "stable" with the mode gains (M, m, n) and their coupled radius, "unstable"
    with P (M, n, n) and its margin, or "undecided" (the certificate did not check: near the boundary). ``mu``
    holds the channel's mean rates. Time as :func:`homogeneous_coupled_riccati` plus one coupled radius
    (O((M n^2)^3) dense).

    Examples
    --------
    >>> a, b = np.array([[2.0]]), np.array([[1.0]])      # one state a = 2: iff r > 3/4, whatever p
    >>> [chain_membership(a, b, GilbertElliott(p=[0.4], r=[r])).verdict for r in (0.7, 0.8)]
    ['unstable', 'stable']
    """
    return _membership(np.asarray(A, dtype=float), np.asarray(B, dtype=float), channel, delivery)[0]


def _membership(A: np.ndarray, B: np.ndarray, channel: GilbertElliott, delivery: str) -> tuple[Membership, float]:
    """:func:`chain_membership` and the eigenvalue lambda behind it. An eigenpair whose certificates do not check
    is tried again without the settling policy steps (``_eigenpair(settle=False)``), where they gave it: their fixed
    point can weigh a mode by 1e-26 or less, where the outside certificate fails and the power iteration's P
    proves "unstable" (two decoupled plants in tests/test_markov_region.py)."""
    _check_delivery(delivery)
    if not isinstance(channel, GilbertElliott):
        raise InputError("channel", f"expected a GilbertElliott channel, found {type(channel).__name__}")
    if channel.m != B.shape[1]:
        raise InputError("channel", f"expected {B.shape[1]} channels (the columns of B), found {channel.m}")
    lam, P, K, settled = _eigenpair(A, B, channel, delivery, settle=True)
    found = _decide(A, B, channel, delivery, lam, P, K)
    if found is None and settled:        # only then does the other route give another P
        again = _eigenpair(A, B, channel, delivery, settle=False)[:3]
        found = _decide(A, B, channel, delivery, *again)
        if found is not None:
            return found, again[0]
    if found is not None:
        return found, lam
    form = f"coupled-riccati ({delivery})"
    return Membership(channel.mean_rate, "undecided", None, float("nan"), None, float("nan"), ((form, "undecided"),),
                      f"the coupled Riccati eigenpair (lambda = {lam:.12g}) gave no certificate that checks (within "
                      "about 1e-9 of the boundary)"), lam


def _decide(A: np.ndarray, B: np.ndarray, channel: GilbertElliott, delivery: str, lam: float, P: np.ndarray,
            K: np.ndarray) -> Membership | None:
    """The verdict an eigenpair ``(lam, P, K)`` proves: "stable" by a gain whose coupled radius is below 1 (K, or
    the gains at P lifted), "unstable" by P's outside certificate; None where neither checks. O(coupled radius)."""
    rates = channel.mean_rate
    form = f"coupled-riccati ({delivery})"
    if lam < 1.0 and np.all(np.isfinite(K)):
        _, T, h = mode_chain(channel)
        for gains in (K, _step(P + _LIFT * np.eye(A.shape[0]), A, B, T, h, delivery)[0]):
            try:
                radius = mjls_radius(A, B, channel, gains, delivery)
            except NumericalError:
                radius = float("nan")
            if is_mean_square_stable(radius):
                return Membership(rates, "stable", gains, radius, None, float("nan"), ((form, "stable"),))
    elif lam >= 1.0:
        margin, certificate = chain_outside(A, B, channel, P, delivery)
        if certificate is not None:
            return Membership(rates, "unstable", None, float("nan"), certificate, margin, ((form, "unstable"),))
    return None


def chain_at_rate(channel: GilbertElliott, rate: npt.ArrayLike) -> GilbertElliott:
    """The Gilbert–Elliott channel with each channel's mean delivery rate ``rate_i`` and the same burstiness
    (correlation ``lambda_i = 1 - p_i - r_i``) and state delivery probabilities. The stationary P(good) is
    ``g_i = (rate_i - h_bad_i) / (h_good_i - h_bad_i)``, so ``r_i = g_i (1 - lambda_i)``, ``p_i = (1 - g_i)
    (1 - lambda_i)``. O(m).

    Raises
    ------
    InputError
        A rate outside [h_bad_i, h_good_i], or a chain that never moves (lambda_i = 1).

    Examples
    --------
    >>> ch = chain_at_rate(GilbertElliott(p=[0.1], r=[0.3]), [0.5])      # lambda = 0.6 kept
    >>> [round(float(v), 12) for v in (ch.p[0], ch.r[0], ch.mean_rate[0], ch.correlation[0])]
    [0.2, 0.2, 0.5, 0.6]
    """
    rate = np.atleast_1d(np.asarray(rate, dtype=float))
    if rate.shape != (channel.m,):
        raise InputError("rate", f"expected {channel.m} mean rates, found shape {rate.shape}")
    lam = channel.correlation
    if np.any(lam >= 1.0):
        raise InputError("channel", "a chain that never moves (p + r = 0) has no mean rate to vary")
    span = channel.h_good - channel.h_bad
    if np.any(span <= 0) or np.any(rate < channel.h_bad - 1e-15) or np.any(rate > channel.h_good + 1e-15):
        raise InputError("rate", f"expected each mean rate within [h_bad, h_good], found {rate.tolist()}")
    g = np.clip((rate - channel.h_bad) / span, 0.0, 1.0)
    return GilbertElliott(p=(1 - g) * (1 - lam), r=g * (1 - lam), h_good=channel.h_good, h_bad=channel.h_bad)


def chain_rate_map(A: npt.ArrayLike, B: npt.ArrayLike, channel: GilbertElliott, axis: npt.ArrayLike,
                   channels: tuple[int, int] = (0, 1), delivery: str = "next") -> tuple[np.ndarray, np.ndarray]:
    """The region over the mean rates of channels I, J (the others at their own rates) at fixed burstiness:
    ``(stable, lam)`` on the grid ``axis`` × ``axis`` (rows rate_J, columns rate_I): 1.0 certified stable, 0.0
    certified not stabilisable, nan undecided; ``lam`` the homogeneous coupled Riccati eigenvalue (min over mode
    laws of the coupled radius). One channel (m = 1): one row over ``axis``. Time K^2 memberships.

    Examples
    --------
    >>> stable, lam = chain_rate_map([[2.0]], [[1.0]], GilbertElliott(p=[0.5], r=[0.5]), [0.5, 0.9])
    >>> stable.tolist()                                     # memoryless: Bernoulli, S = {mu > 3/4}
    [[0.0, 1.0]]
    """
    axis = np.asarray(axis, dtype=float)
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    base = channel.mean_rate.copy()
    rows = axis if channel.m > 1 else axis[:1]
    stable = np.full((len(rows), len(axis)), np.nan)
    lam = np.full_like(stable, np.nan)
    for r, y in enumerate(rows):
        for c, x in enumerate(axis):
            rate = base.copy()
            rate[channels[0]] = x
            if channel.m > 1:
                rate[channels[1]] = y
            ch = chain_at_rate(channel, rate)
            found, lam[r, c] = _membership(A, B, ch, delivery)
            if found.verdict != "undecided":
                stable[r, c] = 1.0 if found.verdict == "stable" else 0.0
    return stable, lam


def critical_rate_unproved(channel: GilbertElliott) -> str | None:
    """Why no critical mean rate is offered behind ``channel`` (None where the region is proved monotone in the
    mean rates at fixed burstiness: every channel with ``h_bad = 0`` and burstiness ``0 <= lambda_i < 1``, a
    chain that moves, and ``h_good_i > 0``; docs/design.md, "The critical mean rate behind a chain"). O(m).

    >>> critical_rate_unproved(GilbertElliott(p=[0.1], r=[0.3])) is None
    True
    >>> critical_rate_unproved(GilbertElliott(p=[0.6], r=[0.7]))[:40]
    'monotonicity in the mean rate is proved '
    >>> critical_rate_unproved(GilbertElliott(p=[0.0], r=[0.0], state=["good"]))[:31]   # a chain that never moves
    'channel(s) [1] never move (1 - '
    >>> critical_rate_unproved(GilbertElliott(p=[0.1], r=[0.3], h_good=[0.0]))[:28]          # never delivers
    'channel(s) [1] never deliver'
    """
    still = [i + 1 for i in range(channel.m) if channel.correlation[i] >= 1.0]
    if still:                   # p + r = 0 (a given state), or below the resolution of 1 - p - r: no ray to run
        return (f"channel(s) {still} never move (1 - p - r = 1 in floating point): at fixed burstiness the mean rate "
                "cannot be varied, so there is no critical mean rate (the membership above still answers)")
    dead = [i + 1 for i in range(channel.m) if channel.h_good[i] == 0.0 and channel.h_bad[i] == 0.0]
    if dead:                    # its mean rate is 0 whatever the chain: nothing to vary
        return (f"channel(s) {dead} never deliver (h_good = h_bad = 0): their mean rate cannot be varied, so there "
                "is no critical mean rate (the membership above still answers)")
    bad = [i + 1 for i in range(channel.m) if channel.h_bad[i] != 0.0 or channel.correlation[i] < 0.0]
    if not bad:
        return None
    return ("monotonicity in the mean rate is proved for channels with h_bad = 0 and burstiness >= 0 only (a "
            f"thinning of the chain); channel(s) {bad} are outside it, so no bisection is offered (the rate map "
            "--grid K still answers point by point)")


def chain_critical_rate(system, direction: npt.ArrayLike | None = None, tol: float = CRITICAL_MU_TOL,
                        delivery: str = "next") -> CriticalPoint:
    """The least ``t`` with mean rates ``t * direction`` (burstiness and h kept, :func:`chain_at_rate`) at which some
    mode-dependent law stabilises the loop behind the system's chain: :func:`~.critical.critical_point`'s bisection
    on decided points, the upper end with stabilising mode gains, the lower end with an infeasibility certificate,
    so the exact critical rate lies in ``[lower, t]``. Offered only where the region is proved monotone along the
    ray (:func:`critical_rate_unproved`). ``direction`` nonnegative, not all zero (default all ones); t runs to
    ``min_i h_good_i / direction_i``. Time O(log2(1 / tol)) chain memberships.

    Raises
    ------
    InputError
        No Gilbert-Elliott channel, a bad direction, or a chain outside the proof (the reason).
    NumericalError
        The ray's end or mu = 0 undecided, or no point of a bracket wider than ``tol`` decidable.

    Examples
    --------
    >>> from packetloss_cvx.model import System
    >>> s = System(A=[[1.5]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.4], r=[0.4]))     # one state, a Gilbert channel: iff r > 1 - 1/a^2
    >>> point = chain_critical_rate(s)               # burstiness 0.2 kept: r = 0.8 rate, so rate > (5/9) / 0.8
    >>> bool(point.lower <= 25 / 36 <= point.t <= point.lower + 1e-6), point.inside.verdict, point.outside.verdict
    (True, 'stable', 'unstable')
    """
    channel = system.channel
    if not isinstance(channel, GilbertElliott):
        raise InputError("channel", "expected a system with a Gilbert-Elliott channel")
    _check_delivery(delivery)
    reason = critical_rate_unproved(channel)
    if reason is not None:
        raise InputError("channel", reason)
    d = np.ones(channel.m) if direction is None else np.asarray(direction, dtype=float).reshape(-1)
    if d.shape != (channel.m,) or not np.all(np.isfinite(d)) or np.any(d < 0) or not np.any(d > 0):
        raise InputError("direction", f"expected {channel.m} nonnegative numbers, not all zero")
    A, B = np.asarray(system.A, dtype=float), np.asarray(system.B, dtype=float)
    end = float(np.min(channel.h_good[d > 0] / d[d > 0]))

    def decide(rate: np.ndarray) -> Membership:
        return chain_membership(A, B, chain_at_rate(channel, np.minimum(rate, channel.h_good)), delivery)

    return critical_point(system, "dp", d, tol, decide=decide, end=end)
