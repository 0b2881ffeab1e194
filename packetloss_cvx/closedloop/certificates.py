"""Certificates of mean-square (in)stability, re-checked in exact rational arithmetic.

A verdict of the stabilisable set (simulation.region) rests on one inequality between matrices computed in floating
point. On a well-conditioned plant a check to rounding is a proof; on an ill-conditioned one (a chain of
integrators at small mu: a certificate's P with eigenvalues 1, 2e-5, 2e-10, 0) the rounding of the check is larger
than the margin it reports, and a float check had proved "every law's radius >= 1.000664" where a gain of radius
0.9975 exists. So the final inequality is re-checked exactly: every double is a dyadic rational, the inequality's
matrix is formed from the very doubles of A, B, mu and the certificate without rounding (linalg.Dyadic), and its
definiteness decided by exact elimination (linalg.exact_psd). A certificate that passes is a proof about the plant
as stored; one that fails gives no verdict ("undecided").

- **outside**: a symmetric P, not negative semidefinite, with ``T_c(P) >= 0`` proves ``rho(L_K) >= c`` for every
  law K (`outside_proved`). With ``x'(L_K^*(P) - cP)x = [x; Kx]' T_c(P) [x; Kx]``, ``L_K^*(P) >= cP`` for
  every K; were ``rho(L_K) < c``, ``P = -sum_j (L_K^* / c)^j (W) / c <= 0`` for ``W = L_K^*(P) - cP >= 0``. P need
  not be PSD (a P >= 0, P != 0 is the usual case): an indefinite P proves it for a part no input reaches, where the
  Stein equation of that part gives a definite, hence robust, inequality.
- **inside**: ``X > 0`` with ``L_K(X) < c X`` proves ``rho(L_K) < c`` (`inside_proved`; L_K is a positive
  map: ``L_K^j(X) <= c'^j X`` for some ``c' < c``). X is the solution of ``X = L_K(X) / r + I`` for an r between
  the law's computed radius and c (`stability_witness`), so that ``cX - L_K(X) = (c - r) X + r I`` up to the
  solve's residual: definite by a margin the rounding cannot reach unless the solve has lost its digits.

Time: O((n + m)^3) integer operations on numbers of O((n + m) 53) bits for a check, plus
O(n^6) for the witness's dense solve (n <= MOMENT_DENSE_MAX_N).
"""

from __future__ import annotations

import numpy as np

from ..errors import NumericalError
from ..linalg import Dyadic, controllable_split, exact_psd, frobenius
from ..model.chain import mode_chain, reachable_modes
from ..model.channel import GE_MODEL, MarkovChannel
from ..tolerances import MEAN_SQUARE_MARGIN
from .modes import DENSE_MAX_DIM, mode_matrix
from .moments import solve_fixed_point
from .stability import law_radius, second_moment_matrix, second_moment_step

__all__ = ["SNAP", "TILTS", "candidates", "chain_outside_proved", "chain_proved_certificate", "exact_transition",
           "inside_proved", "law_proved_stable", "mode_outside_matrices", "no_law_proved", "outside_matrix",
           "outside_proved", "snapped", "stability_witness", "tilted", "tilted_by"]

#: entries at or below these fractions of a certificate's largest are tried as exact zeros (:func:`snapped`): the
#: rounding of an orthogonal transform (1e-17 where the split of a zero row of B is exact), and the iteration's own
#: tolerance (RICCATI_RTOL = 1e-12 on the eigenvector: 1.7e-13 off the block of a decoupled plant's mode that only
#: one input reaches)
SNAP = (1e-13, 1e-10)

#: the tilts ``P - t ||P|| S / ||S||`` tried on a certificate P that does not check exactly (:func:`tilted`)
TILTS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14)


def _exact(A: np.ndarray, B: np.ndarray, mu: np.ndarray) -> tuple[Dyadic, Dyadic, Dyadic, Dyadic]:
    """A, B, mu and mu (1 - mu) (vectors (m,)), exactly."""
    mu = np.asarray(mu, dtype=float).reshape(-1)
    mu_ = Dyadic.of(mu)
    return Dyadic.of(A), Dyadic.of(B), mu_, mu_ * (Dyadic.of(np.ones_like(mu)) - mu_)


def _symmetric(P: np.ndarray) -> Dyadic:
    """``(P + P') / 2`` exactly."""
    P_ = Dyadic.of(P)
    P_ = P_ + P_.T
    return Dyadic(P_.ints, P_.exp - 1)


def outside_matrix(A: np.ndarray, B: np.ndarray, mu: np.ndarray, P: np.ndarray, c: float) -> Dyadic:
    """``T_c(P)`` exactly, for the symmetric part of P: ``[[A'PA - cP, -A'PBM], [-MB'PA, MB'PBM + diag(mu (1 - mu)
    diag(B'PB))]]``, (n + m)×(n + m): `mode_outside_matrices` at one mode. NumericalError on a non-finite entry.
    O((n + m)^3) integer operations.

    >>> T = outside_matrix(np.array([[2.0]]), np.array([[1.0]]), np.array([0.5]), np.eye(1), 1.0)
    >>> [[float(T.fraction(i, j)) for j in range(2)] for i in range(2)]     # [[a^2 - c, -a mu], [-a mu, mu]]
    [[3.0, -1.0], [-1.0, 0.5]]
    """
    mu = np.asarray(mu, dtype=float).reshape(-1)
    return mode_outside_matrices(A, B, Dyadic(np.ones((1, 1), dtype=object), 0), mu[None, None],
                                 np.asarray(P, dtype=float)[None], c)[0]


def mode_outside_matrices(A: np.ndarray, B: np.ndarray, T: Dyadic, rates: np.ndarray, P: np.ndarray,
                          c: float) -> list[Dyadic]:
    """``T_c(P)_a`` exactly for every mode a of a chain (the symmetric part of each P_a), (n + m)×(n + m) each:
    ``[[A'E_aA - cP_a, -A'F_a], [-F_a'A, H_a]]`` with ``E_a = sum_b T_ab P_b``, ``F_a = sum_b T_ab P_b B D_ab`` and
    ``H_a = sum_b T_ab (D_ab B'P_bB D_ab + diag(d_ab (1 - d_ab) diag(B'P_bB)))``: ``x'(L_K^*(P)_a - cP_a)x`` is the
    form at ``[x; K_a x]`` (simulation.chain_radius). ``T`` the exact transition matrix (`exact_transition`),
    ``rates`` (M, M, m) the delivery probabilities d_ab of a step from a into b (h_b "next", h_a "current"). One mode
    with T = 1 and d = mu is the Bernoulli `outside_matrix`. O(M^2 (n + m)^3) integer operations.

    >>> Ts = mode_outside_matrices(np.array([[2.0]]), np.array([[1.0]]), Dyadic.of(np.ones((1, 1))),
    ...                            np.full((1, 1, 1), 0.5), np.ones((1, 1, 1)), 1.0)
    >>> [[float(Ts[0].fraction(i, j)) for j in range(2)] for i in range(2)]
    [[3.0, -1.0], [-1.0, 0.5]]
    """
    A_, B_ = Dyadic.of(A), Dyadic.of(B)
    P_ = [_symmetric(Pb) for Pb in P]
    PB = [Pb @ B_ for Pb in P_]
    BPB = [B_.T @ X for X in PB]
    c_ = Dyadic.of(float(c))
    out = []
    for a in range(len(P_)):
        E = F = H = None
        for b in range(len(P_)):
            if T.ints[a, b] == 0:
                continue
            d = Dyadic.of(np.asarray(rates[a, b], dtype=float))
            var = d * (Dyadic(np.ones(d.ints.shape, dtype=object), 0) - d)
            terms = (P_[b], PB[b] * d, BPB[b] * d.outer(d) + (var * BPB[b].diag()).diag())
            if not (T.ints[a, b] == 1 and T.exp == 0):           # a certain step (one mode) needs no product
                t = Dyadic(T.ints[a, b], T.exp)
                terms = tuple(t * X for X in terms)
            E, F, H = terms if E is None else (E + terms[0], F + terms[1], H + terms[2])
        if E is None:         # a mode the chain leaves with probability 0 everywhere: no row (T is stochastic)
            raise NumericalError("exact arithmetic: a transition row is zero")
        APBD = A_.T @ F
        out.append(Dyadic.block([[A_.T @ (E @ A_) - c_ * P_[a], -APBD], [-APBD.T, H]]))
    return out


def exact_transition(channel: MarkovChannel) -> Dyadic:
    """The mode chain's transition matrix (model.chain.mode_chain's modes and order: the joint states reachable from
    the start) exactly, from the channel's stored
    numbers: a channel given as Gilbert–Elliott's p, r (its table form), ``[[1 - p, p], [r, 1 - r]]`` with 1 - p
    taken exactly (mode_chain's floats round it), a [`MarkovChannel`][packetloss_cvx.model.channel.MarkovChannel]'s
    transitions as stored, Kronecker products of the channels' exact. O(M^2) integer operations.

    >>> from fractions import Fraction
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> T = exact_transition(GilbertElliott(p=[0.1], r=[0.4]))
    >>> T.fraction(0, 0) == 1 - Fraction(0.1), T.fraction(1, 0) == Fraction(0.4)
    (True, True)
    """
    if channel.form != GE_MODEL:
        chains = [Dyadic.of(np.asarray(Ti, dtype=float)) for Ti in channel.transition]
    else:
        one, chains = Dyadic.of(np.ones((1, 1))), []
        for p, r in zip(np.asarray(channel.p, dtype=float), np.asarray(channel.r, dtype=float), strict=True):
            p_, r_ = Dyadic.of(np.array([[p]])), Dyadic.of(np.array([[r]]))
            chains.append(Dyadic.block([[one - p_, p_], [r_, one - r_]]))
    T = Dyadic(np.ones((1, 1), dtype=object), 0)
    for Ti in chains:
        T = Dyadic(np.kron(T.ints, Ti.ints), T.exp + Ti.exp)
    live = reachable_modes(channel)
    return T if live.all() else Dyadic(T.ints[np.ix_(live, live)], T.exp)


def chain_outside_proved(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, P: np.ndarray | None,
                         c: float, delivery: str = "next") -> bool:
    """Does the tuple P (M, n, n), or one of its candidates, prove ``rho(L_K) >= c`` for every mode-dependent law K
    behind ``channel``, exactly (`chain_proved_certificate` finds one)? False for a P that is None, not finite or of
    the wrong shape. Time as `chain_proved_certificate`.

    >>> from .chain_radius import homogeneous_coupled_riccati
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> ch = GilbertElliott(p=[0.3], r=[0.2])           # x+ = 0 once delivered: the least radius a^2 (1 - r) = 3.2
    >>> lam, P, K = homogeneous_coupled_riccati(np.array([[2.0]]), np.array([[1.0]]), ch)
    >>> [chain_outside_proved(np.array([[2.0]]), np.array([[1.0]]), ch, P, c) for c in (3.2 * (1 - 1e-12), 3.3)]
    [True, False]
    """
    return chain_proved_certificate(A, B, channel, P, c, delivery) is not None


def chain_proved_certificate(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, P: np.ndarray | None,
                             c: float, delivery: str = "next", gains: np.ndarray | None = None) -> np.ndarray | None:
    """The first candidate Q of the tuple P (M, n, n) that proves ``rho(L_K) >= c`` for every mode-dependent law K
    behind ``channel`` exactly, or None: ``T_c(Q)_a >= 0`` for every mode (`mode_outside_matrices`; then
    ``L_K^*(Q) >= cQ`` blockwise for every K) and Q not blockwise negative semidefinite. (Were ``rho(L_K) < c``,
    ``Q = -sum_j (L_K^*/c)^j (W) / c <= 0`` for ``W = L_K^*(Q) - cQ >= 0``: the module docstring's argument, on
    tuples.) The candidates are Bernoulli's (`candidates`) per mode: P, P snapped, and those tilted by the
    coupled Stein solution of ``cS_a - A'(sum_b T_ab S_b)A = I`` (a singular Perron tuple proves its bound only with
    its exact kernel), over all modes, then over the modes P weighs (`_coupled_stein`), and first, given the mode
    gains that minimise at P (``gains`` (M, m, n)), by the closed-loop one (`_closed_loop_stein`), each scaled to
    Frobenius norm 1. The check of `chain_certificate_margin`'s verdict in exact arithmetic, on the plant and channel as
    stored; last, where the plant splits exactly by a permutation, P's block on the reached coordinates for the
    reached pair (`_reached_part_proved`). None for a P that is None, not finite or of the wrong shape.
    Time O(M^2 (n + m)^3) integer operations a candidate, O((M n^2)^3) for the tilts' solve.

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> ch = GilbertElliott(p=[0.3], r=[0.2])       # one state a = 2: "next", R(P) = (p a^2 p_b, (1 - r) a^2 p_b)
    >>> P = np.array([[[0.0]], [[1.0]]])            # on the bad mode: every law's radius >= (1 - r) a^2 = 3.2
    >>> [Q.ravel().tolist() for c in (3.2 * (1 - 1e-12), 3.3)
    ...  if (Q := chain_proved_certificate(np.array([[2.0]]), np.array([[1.0]]), ch, P, c)) is not None]
    [[0.0, 1.0]]
    """
    modes, T, h = mode_chain(channel)
    M, n = len(modes), np.asarray(A).shape[0]
    if P is None or np.shape(P) != (M, n, n) or not np.all(np.isfinite(P)) or not c > 0:
        return None
    rates = np.broadcast_to(h[None] if delivery == "next" else h[:, None], (M, M, h.shape[1]))
    exact_T = exact_transition(channel)
    P = 0.5 * (P + P.transpose(0, 2, 1))
    P = P / max(frobenius(P), np.finfo(float).tiny)
    found = _proved_candidate(A, B, T, exact_T, rates, P, c, _closed_loop_stein(A, B, T, h, delivery, gains, c))
    if found is not None:
        return found
    return _reached_part_proved(np.asarray(A, dtype=float), np.asarray(B, dtype=float), T, exact_T, h, rates, P, c)


def _proved_candidate(A: np.ndarray, B: np.ndarray, T: np.ndarray, exact_T: Dyadic, rates: np.ndarray,
                      P: np.ndarray, c: float, closed: np.ndarray | None = None) -> np.ndarray | None:
    """The first of P's candidates (`chain_proved_certificate`) with ``T_c(Q)_a >= 0`` exactly for every mode and Q
    not blockwise negative semidefinite, or None; ``closed``, a closed-loop Stein solution (`_closed_loop_stein`),
    tilts first."""

    def proves(Q: np.ndarray) -> bool:
        return all(exact_psd(X) for X in mode_outside_matrices(A, B, exact_T, rates, Q, c)) \
            and not all(exact_psd(-_symmetric(Qa)) for Qa in Q)

    plain = [P, *snapped(P)]                                 # snapped over the tuple: one level for every mode
    for Q in plain:
        if proves(Q):
            return Q
    M = len(P)
    weighed = np.any(P != 0.0, axis=(-2, -1))
    supports = [np.ones(M, dtype=bool)] + ([weighed] if np.any(weighed) and not np.all(weighed) else [])
    tilts = [closed] if closed is not None else []
    tilts += [_coupled_stein(np.asarray(A, dtype=float), T, c, support) for support in supports]
    for S in tilts:
        if S is None:
            continue
        for Q in plain:
            for tilted_Q in reversed(tilted_by(Q, S)):   # the least tilt first: the certificate stays nearest P
                if proves(tilted_Q):
                    return tilted_Q
    return None


def _reached_part_proved(A: np.ndarray, B: np.ndarray, T: np.ndarray, exact_T: Dyadic, h: np.ndarray,
                         rates: np.ndarray, P: np.ndarray, c: float) -> np.ndarray | None:
    """Where the plant splits exactly by a signed permutation S (``S'AS = [[A_cc, A_cu], [0, A_uu]]``, ``S'B = [[B_c],
    [0]]`` with exact zeros, the channels that ever deliver: linalg.controllable_split) and the reached block of
    ``S'P_aS`` (or a candidate of it) proves ``rho >= c`` for ``(A_cc, B_c)`` exactly (`_proved_candidate`), that
    block put back in place, zero elsewhere.
    Every closed loop ``A - B V K`` maps the reachable subspace into itself, so the Collatz–Wielandt argument on PSD
    matrices supported there bounds every law's radius by the same c (chain_radius.chain_certificate_margin): a
    proof about the plant as stored, since a permutation moves the doubles exactly; the block put back passes this
    same check. None otherwise. Time that of the reduced checks plus O(n^4) for the split."""
    split = controllable_split(A, B[:, np.any(h > 0, axis=0)])
    nc, S = split.nc, split.T
    if not 0 < nc < A.shape[0] or not np.all((S == 0.0) | (np.abs(S) == 1.0)) or \
            not np.all(np.count_nonzero(S, axis=0) == 1):
        return None
    At, Bt = S.T @ A @ S, S.T @ B                          # exact: a signed permutation
    Pt = np.einsum("ji,ajk,kl->ail", S, P, S)
    if np.any(At[nc:, :nc] != 0.0) or np.any(Bt[nc:] != 0.0):
        return None
    Q = _proved_candidate(At[:nc, :nc], Bt[:nc], T, exact_T, rates, Pt[:, :nc, :nc], c)
    if Q is None:
        return None
    out = np.zeros_like(P)
    out[:, :nc, :nc] = Q
    return np.einsum("ij,ajk,lk->ail", S, out, S)


def _closed_loop_stein(A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, delivery: str,
                       gains: np.ndarray | None, c: float) -> np.ndarray | None:
    """S (M, n, n) with ``cS - L_K^*(S) = I`` (blockwise) for the mode gains K (M, m, n), the adjoint of their coupled
    second-moment map (modes.mode_matrix, transposed); None without gains, for M n^2 beyond DENSE_MAX_DIM, or where
    it has no finite solution. The tilt for a mode whose deliveries are sure: there the minimising input acts on the
    kernel of a singular certificate P, so the open-loop Stein tilt (`_coupled_stein`, no input) can make
    ``T_c(P - tS)`` indefinite; at the minimiser K, ``[x; K_a x]' T_c(-tS)_a [x; K_a x] = t x'(cS - L_K^*(S))_a x =
    t |x|^2``, definite on that kernel. Measured: a random 3-state plant behind a Gilbert channel ("current", good
    delivering surely: its P rank one in that mode) failed every other candidate at a margin of 0.416 under one BLAS
    thread and passed under four; with this tilt it passes at every t of TILTS. O((M n^2)^3)."""
    if gains is None:
        return None
    M, n = T.shape[0], A.shape[0]
    K = np.asarray(gains, dtype=float)
    if K.shape != (M, B.shape[1], n) or not np.all(np.isfinite(K)) or M * n * n > DENSE_MAX_DIM:
        return None
    with np.errstate(all="ignore"):
        try:
            L = mode_matrix(np.asarray(A, dtype=float), np.asarray(B, dtype=float), K, h, T, delivery).T
            S = np.linalg.solve(c * np.eye(M * n * n) - L, np.tile(np.eye(n).ravel(), M)).reshape(M, n, n)
        except (np.linalg.LinAlgError, ValueError):
            return None
    S = 0.5 * (S + S.transpose(0, 2, 1))
    return S if np.isfinite(frobenius(S)) and frobenius(S) > 0 else None


def _coupled_stein(A: np.ndarray, T: np.ndarray, c: float, support: np.ndarray) -> np.ndarray | None:
    """S (M, n, n) with ``cS_a - A'(sum_b T_ab S_b)A = I`` for the modes a in ``support`` (M,) bool, the sum over
    those b, and ``S_a = 0`` elsewhere (the tilt of `chain_proved_certificate`; `tilted`'s S at one mode), None
    where it has no finite solution. On the modes a tuple weighs, not all: a mode it leaves at exactly 0 keeps
    ``T_c(Q)_a`` at 0 where the chain moves from it only into such modes (an absorbing mode whose deliveries are
    sure), which a tilt there would make indefinite. O((M n^2)^3)."""
    M, n = T.shape[0], A.shape[0]
    k = int(np.count_nonzero(support))
    Tw = T[np.ix_(support, support)]
    with np.errstate(all="ignore"):
        try:
            Sw = np.linalg.solve(c * np.eye(k * n * n) - np.kron(Tw, np.kron(A.T, A.T)),
                                 np.tile(np.eye(n).ravel(), k)).reshape(k, n, n)
        except np.linalg.LinAlgError:
            return None
    S = np.zeros((M, n, n))
    S[support] = 0.5 * (Sw + Sw.transpose(0, 2, 1))
    return S if np.isfinite(frobenius(S)) and frobenius(S) > 0 else None


def outside_proved(A: np.ndarray, B: np.ndarray, mu: np.ndarray, P: np.ndarray | None, c: float) -> bool:
    """Does P prove ``rho(L_K) >= c`` for every law K, exactly (module docstring): ``T_c(P) >= 0`` and P not
    negative semidefinite? False for a P that is None or not finite. Time O((n + m)^3) integer operations.

    >>> A, B = np.array([[2.0]]), np.array([[1.0]])          # every law's radius >= a^2 (1 - mu): 2 at mu = 1/2
    >>> [outside_proved(A, B, np.array([0.5]), np.eye(1), c) for c in (2.0, 2.0 + 2.0 ** -40)]
    [True, False]
    """
    if P is None or not np.all(np.isfinite(P)) or not c > 0:
        return False
    if not exact_psd(outside_matrix(A, B, mu, P, c)):
        return False
    return not exact_psd(-_symmetric(P))


def inside_proved(A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray, X: np.ndarray | None,
                  c: float) -> bool:
    """Does X prove ``rho(L_K) < c`` exactly: ``X > 0`` and ``cX - L_K(X) > 0`` (module docstring), X taken
    symmetric? Time O(n^3 + n^2 m) integer operations.

    >>> A, B, K = np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]])   # L_K(x) = a^2 (1 - mu) x = x / 2
    >>> [inside_proved(A, B, K, np.array([0.875]), np.eye(1), c) for c in (0.5 + 2.0 ** -50, 0.5)]
    [True, False]
    """
    if X is None or not (np.all(np.isfinite(X)) and np.all(np.isfinite(K))):
        return False
    A_, B_, mu_, var = _exact(A, B, mu)
    K_, X_ = Dyadic.of(K), _symmetric(X)
    Abar = A_ - (B_ * mu_) @ K_
    image = Abar @ X_ @ Abar.T + B_ @ (var * (K_ @ X_ @ K_.T).diag()).diag() @ B_.T
    return exact_psd(X_, strict=True) and exact_psd(Dyadic.of(float(c)) * X_ - image, strict=True)


def stability_witness(A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray, c: float,
                      radius: float | None = None) -> np.ndarray | None:
    """A candidate X for `inside_proved` at c: the solution of ``X = L_K(X) / r + I``, r the midpoint of the
    law's computed radius (``radius``, else `law_radius`) and c; None where that radius is not
    below c or the solve fails (a residual check, NumericalError). Time O(n^6) (n <= MOMENT_DENSE_MAX_N).

    >>> X = stability_witness(np.array([[2.0]]), np.array([[1.0]]), np.array([[2.0]]), np.array([0.9]), 0.5)
    >>> round(float(X[0, 0]), 12)                    # r = 0.45: x = 0.4 x / 0.45 + 1 = 9
    9.0
    """
    try:
        radius = law_radius(A, B, K, mu) if radius is None else radius
    except NumericalError:
        return None
    if not (np.isfinite(radius) and radius < c):
        return None
    r = max(0.5 * (max(radius, 0.0) + c), 0.5 * c)
    step = second_moment_step(A, B, K, mu)
    try:
        return solve_fixed_point(lambda X: step(X) / r, lambda: second_moment_matrix(A, B, K, mu) / r,
                                 np.eye(A.shape[0]), "a stability witness")
    except (NumericalError, np.linalg.LinAlgError):
        return None


def law_proved_stable(A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: np.ndarray, radius: float | None = None,
                      c: float = 1.0 - MEAN_SQUARE_MARGIN) -> bool:
    """Is ``rho(L_K) < c`` (default ``1 - MEAN_SQUARE_MARGIN``, the margin of a "stable" verdict) proved exactly by
    the witness of `stability_witness`? Arrays as stability.check_law returns them. Time O(n^6).

    >>> A, B = np.array([[2.0]]), np.array([[1.0]])     # k = a: radius a^2 (1 - mu)
    >>> [law_proved_stable(A, B, np.array([[2.0]]), np.array([mu])) for mu in (0.8, 0.75)]
    [True, False]
    """
    return inside_proved(A, B, K, mu, stability_witness(A, B, K, mu, c, radius), c)


def tilted(A: np.ndarray, P: np.ndarray, c: float) -> list[np.ndarray]:
    """``P - t ||P|| S / ||S||`` for t in `TILTS`, S the solution of the Stein equation ``cS - A'SA = I``
    (none where it has no finite solution). A certificate P that is singular (a rank-one Perron eigenvector ``vv'``:
    every law leaves ``v'x`` to grow, v a left eigenvector of A) proves its bound only with its exact kernel, which
    the rounding of v misses; tilted, ``T_c`` gains ``t (cS - A'SA) = t I`` on that kernel (where no input acts on
    it, as at a Perron eigenvector whose inputs all deliver with probability in (0, 1)) and is then definite by a
    margin the rounding cannot undo, while ``v'(P - tS)v > 0`` keeps it a certificate (P need not be PSD). Time
    O(n^6) (a dense n^2 solve).

    >>> A = np.array([[2.0, 1.0], [0.0, 0.5]])        # x'A = 2 x' for x = (3, 2): every law leaves it at radius >= ...
    >>> B, mu = np.array([[0.6], [-0.2]]), np.array([0.5])
    >>> v = np.array([3.0, 2.0]) / np.sqrt(13.0)       # ... 4 (1 - mu) = 2, by the scalar case; v'B is not 0
    >>> [outside_proved(A, B, mu, P, 1.9) for P in [np.outer(v, v), *tilted(A, np.outer(v, v), 1.9)]]
    [False, True, True, True, True, True, True]
    """
    n = A.shape[0]
    with np.errstate(all="ignore"):
        try:
            S = np.linalg.solve(c * np.eye(n * n) - np.kron(A.T, A.T), np.eye(n).ravel()).reshape(n, n)
        except np.linalg.LinAlgError:
            return []
    return tilted_by(P, 0.5 * (S + S.T))


def tilted_by(P: np.ndarray, S: np.ndarray | None) -> list[np.ndarray]:
    """``P - t ||P|| S / ||S||`` for t in `TILTS` (largest first; Frobenius norms over the whole array, a tuple of
    modes tilted as one), S a Stein solution (`tilted`'s, a coupled one); none for an S that is None, zero or not
    finite. O(size of P).

    >>> [Q.item() for Q in tilted_by(np.ones((1, 1)), 2.0 * np.ones((1, 1)))][:2]
    [0.9999, 0.999999]
    """
    if S is None:
        return []
    size = frobenius(S)
    if not (np.isfinite(size) and size > 0):
        return []
    scale = frobenius(P) / size
    return [P - t * scale * S for t in TILTS]


def snapped(P: np.ndarray) -> list[np.ndarray]:
    """P with its entries at or below each fraction in `SNAP` of its largest set to exactly 0 (where that
    zeroes anything, and differs from the last). Exact block structure of the plant (a zero row of B, decoupled
    blocks) gives certificates with exact zeros, which an orthogonal transform or an iteration leaves at 1e-17 to
    1e-13 instead; the exact check needs them back. Candidates only: the check decides. O(n^2).

    >>> [Q.tolist() for Q in snapped(np.array([[1.0, 2e-13], [2e-13, 3e-33]]))]
    [[[1.0, 2e-13], [2e-13, 0.0]], [[1.0, 0.0], [0.0, 0.0]]]
    """
    P = np.asarray(P, dtype=float)
    out, last = [], P
    for level in SNAP:
        small = np.abs(P) <= level * float(np.abs(P).max(initial=0.0))
        Q = np.where(small, 0.0, P)
        if not np.array_equal(Q, last):
            out.append(Q)
            last = Q
    return out


def candidates(A: np.ndarray, P: np.ndarray, c: float, tilt: bool = False) -> list[np.ndarray]:
    """The certificates tried for P at c: P and P `snapped`; with ``tilt``, each of those `tilted`
    instead. O(n^2), O(n^6) with the tilts' Stein solve.

    >>> len(candidates(np.array([[2.0]]), np.eye(1), 1.0)), len(candidates(np.array([[2.0]]), np.eye(1), 1.0, True))
    (1, 6)
    """
    plain = [P, *snapped(P)]
    return [Q for R in plain for Q in tilted(A, R, c)] if tilt else plain


def no_law_proved(A: np.ndarray, B: np.ndarray, mu: np.ndarray, P: np.ndarray) -> bool:
    """Does P, or P tilted (`tilted`), prove exactly that every law's radius is at least 1 (so that no law is
    mean-square stable)? The proof the DP (simulation.riccati) needs to say "no stabilising solution" from the
    direction of its diverging iterate. Time O((n + m)^3) integer operations a try (`candidates`).

    >>> A, B = np.array([[2.0]]), np.array([[1.0]])      # every law's radius >= a^2 (1 - mu): 1 at mu = 3/4
    >>> [no_law_proved(A, B, np.array([mu]), np.eye(1)) for mu in (0.75, 0.75 + 2.0 ** -40)]
    [True, False]
    """
    if not np.all(np.isfinite(P)):
        return False
    P = 0.5 * (P + P.T)
    P = P / max(frobenius(P), np.finfo(float).tiny)
    return any(outside_proved(A, B, mu, Q, 1.0) for tilt in (False, True) for Q in candidates(A, P, 1.0, tilt))


def chain_inside_proved(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, K: np.ndarray, X: np.ndarray | None,
                        c: float, delivery: str = "next") -> bool:
    """Does the tuple X (M, n, n) prove ``rho(L_K) < c`` exactly for the mode gains K (M, m, n) behind ``channel``:
    every ``X_a > 0`` and every ``cX_b - L_K(X)_b > 0``, with the coupled second-moment map (closedloop.mjls)
    ``L_K(X)_b = sum_a T_ab ((A - B D K_a) X_a (A - B D K_a)' + B diag(d (1 - d) ∘ diag(K_a X_a K_a')) B')``, d the
    deliveries of b ("next") or of a ("current"), D = diag(d). (L_K is a positive map of the tuples, so
    ``L_K^j(X) <= c'^j X`` blockwise for some ``c' < c``: `inside_proved`'s argument, on tuples.) Formed from the
    very doubles of A, B, K, X and the channel as stored (`exact_transition`). False for an X that is None or not
    finite. Time O(M^2 (n^3 + n^2 m)) integer operations.

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> ch = GilbertElliott(p=[0.3], r=[0.2])      # deadbeat when delivered: x+ = 2 x in the bad state, radius 3.2
    >>> A, B, K = np.array([[2.0]]), np.array([[1.0]]), np.full((2, 1, 1), 2.0)
    >>> X = np.ones((2, 1, 1))                     # L_K(X) = (0, 4 (0.3 + 0.8)) blockwise
    >>> [chain_inside_proved(A, B, ch, K, X, c) for c in (4.5, 4.3)]
    [True, False]
    """
    modes, _, h = mode_chain(channel)
    M, n = len(modes), np.asarray(A).shape[0]
    if X is None or np.shape(X) != (M, n, n) or not (np.all(np.isfinite(X)) and np.all(np.isfinite(K))):
        return False
    T = exact_transition(channel)
    A_, B_, c_ = Dyadic.of(A), Dyadic.of(B), Dyadic.of(float(c))
    X_ = [_symmetric(Xa) for Xa in X]
    K_ = [Dyadic.of(np.asarray(Ka, dtype=float)) for Ka in K]
    if not all(exact_psd(Xa, strict=True) for Xa in X_):
        return False
    one = Dyadic.of(np.ones(h.shape[1]))
    for b in range(M):
        image = None
        for a in range(M):
            if T.ints[a, b] == 0:
                continue
            d = Dyadic.of(np.asarray(h[b] if delivery == "next" else h[a], dtype=float))
            Abar = A_ - (B_ * d) @ K_[a]
            term = Abar @ X_[a] @ Abar.T + B_ @ ((d * (one - d)) * (K_[a] @ X_[a] @ K_[a].T).diag()).diag() @ B_.T
            term = Dyadic(T.ints[a, b], T.exp) * term
            image = term if image is None else image + term
        if image is None:
            image = Dyadic.of(np.zeros((n, n)))
        if not exact_psd(c_ * X_[b] - image, strict=True):
            return False
    return True


def chain_stability_witness(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, K: np.ndarray, radius: float,
                            c: float, delivery: str = "next") -> np.ndarray | None:
    """A candidate X for `chain_inside_proved` at c: the solution of ``X = L_K(X) / r + I`` (every mode) for r the
    midpoint of the law's computed coupled radius and c, by a dense solve of the coupled operator (closedloop.modes'
    ``mode_matrix``, row-major vec, modes stacked); None where the radius is not below c or the solve fails.
    Time O((M n^2)^3).

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> ch = GilbertElliott(p=[0.3], r=[0.2])
    >>> X = chain_stability_witness(np.array([[0.5]]), np.array([[1.0]]), ch, np.zeros((2, 1, 1)), 0.25, 1.0)
    >>> # x+ = x / 2, r = 0.625: X_b = 0.4 sum_a T_ab X_a + 1, i.e. 0.72 X_g - 0.08 X_b = 1 = -0.12 X_g + 0.68 X_b
    >>> bool(np.allclose(X.ravel(), [0.76 / 0.48, 0.84 / 0.48], rtol=1e-14))
    True
    """
    if not (np.isfinite(radius) and radius < c):
        return None
    modes, T, h = mode_chain(channel)
    M, n = len(modes), np.asarray(A).shape[0]
    r = max(0.5 * (max(radius, 0.0) + c), 0.5 * c)
    with np.errstate(all="ignore"):
        try:
            op = mode_matrix(np.asarray(A, dtype=float), np.asarray(B, dtype=float), np.asarray(K, dtype=float), h,
                             T, delivery)
            x = np.linalg.solve(np.eye(M * n * n) - op / r, np.tile(np.eye(n).ravel(), M))
        except np.linalg.LinAlgError:
            return None
    X = x.reshape(M, n, n)
    X = 0.5 * (X + X.transpose(0, 2, 1))
    return X if np.all(np.isfinite(X)) else None


def chain_law_proved_stable(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, K: np.ndarray, radius: float,
                            delivery: str = "next", c: float = 1.0 - MEAN_SQUARE_MARGIN) -> bool:
    """Is the coupled radius of the mode gains K (M, m, n) below c (default ``1 - MEAN_SQUARE_MARGIN``) proved
    exactly by `chain_stability_witness`'s X (`chain_inside_proved`)? ``radius`` the computed one. Time
    O((M n^2)^3).

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> ch = GilbertElliott(p=[0.3], r=[0.8])          # deadbeat when delivered, x+ = 2 x when lost: radius 4 (1 - r)
    >>> A, B, K = np.array([[2.0]]), np.array([[1.0]]), np.full((2, 1, 1), 2.0)
    >>> chain_law_proved_stable(A, B, ch, K, 0.8), chain_law_proved_stable(A, B, ch.__class__.gilbert_elliott(
    ...     p=[0.3], r=[0.7]), K, 0.8)              # r = 0.7: radius 1.2, a claimed 0.8 does not prove
    (True, False)
    """
    return chain_inside_proved(A, B, channel, K, chain_stability_witness(A, B, channel, K, radius, c, delivery), c,
                               delivery)
