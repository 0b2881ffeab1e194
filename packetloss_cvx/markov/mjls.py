"""The loop behind Markov channels as a Markov jump linear system (MJLS).

Mode theta_k = the joint channel state (prod_i k_i modes of a
:class:`~packetloss_cvx.markov_channel.MarkovChannel`, 2^m for Gilbert–Elliott channels; channels independent:
the mode chain's transition matrix is the Kronecker product of the channels' own). In mode a, actuator i's
packet arrives with probability h_{a,i} (d_i of the state; h_good or h_bad), independently. The closed loop
``x_{k+1} = (A - B V_k K_a) x_k``
is mean-square stable iff the spectral radius of its coupled second-moment operator

    Q_b  <-  sum_a T_ab E_v[(A - B V K_a) Q_a (A - B V K_a)' | a]

is below 1 (Costa, Fragoso, Marques, *Discrete-Time Markov Jump Linear Systems*, 2005, Thm 3.9).

With the mode known to the controller (the channel state observed), the optimal mode-dependent law for
``sum_k x_k' Omega x_k + (V_k u_k)' Psi (V_k u_k)`` solves the coupled Riccati equations (CFM05, ch. 4)

    E_a = sum_b T_ab P_b,   G_a = B'E_a B + Psi,   S_a = H_a G_a H_a + diag(h_a (1 - h_a)) ∘ G_a,
    P_a = Omega + A'E_a A - A'E_a B H_a S_a^{-1} H_a B'E_a A,   K_a = S_a^{-1} H_a B'E_a A

(H_a = diag(h_a); S_a inverted on the actuators that can deliver, K_a = 0 elsewhere). With a memoryless
chain (p + r = 1) every E_a is the same, and pbar = sum_a pi_a P_a solves the Bernoulli TCP-like
Riccati equation with mu = r (for one channel: P = Omega + A'PA - mu A'PB (B'PB + Psi)^{-1} B'PA).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..errors import InputError, NumericalError, ResourceError
from ..markov_channel import GilbertElliott, MarkovChannel  # noqa: F401 (GilbertElliott: the doctests' constructor)
from ..model import System, check_system
from ..recursion import riccati_step
from ..results import MjlsResult
from ..tolerances import ARPACK_TOL, MEMORY_BUDGET_BYTES, SELF_CHECK_RTOL
from .chain import chain_matrices

__all__ = [
    "DENSE_MAX_DIM", "MAX_CHANNELS", "MAX_OPERATOR_DIM", "check_operator_size", "coupled_riccati",
    "MAX_MODES", "delivery_moments", "jump_law_stage_costs", "mean_square_radius", "moment_step", "mode_chain",
    "mode_start", "product_chain", "second_moment_operator",
]

#: 2^m modes and 2^m delivery patterns per mode: beyond this many channels the operator is refused.
MAX_CHANNELS = 6
#: The product chain of k-state channels is refused beyond as many modes as MAX_CHANNELS Gilbert–Elliott ones give.
MAX_MODES = 2 ** MAX_CHANNELS
#: Rows M n^2 of the dense coupled operator beyond which it is refused (ResourceError): its eigenvalues take
#: O((M n^2)^3) time and 16 (M n^2)^2 bytes (2048 rows: 64 MiB, a few seconds).
MAX_OPERATOR_DIM = 2048
#: Rows up to which :func:`mean_square_radius` takes the dense eigenvalues by default (above: matrix-free Krylov).
DENSE_MAX_DIM = 400


def mode_chain(channel: MarkovChannel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(modes, T, h)``: the M = prod_i k_i joint states (each row the state indices, channel 0 the most
    significant, state 0 first; Gilbert–Elliott channels: 0 = good), their transition matrix (the Kronecker
    product of the channels' chains) and per-mode delivery probabilities (M, m). Refused beyond
    :data:`MAX_MODES`. Time O(M^2 + M m).

    Raises
    ------
    InputError
        A product chain beyond :data:`MAX_MODES` modes (more than :data:`MAX_CHANNELS` Gilbert–Elliott channels).

    Examples
    --------
    >>> [a.tolist() for a in mode_chain(GilbertElliott(p=[0.1], r=[0.3]))]      # good, bad: the Gilbert channel
    [[[0], [1]], [[0.9, 0.1], [0.3, 0.7]], [[1.0], [0.0]]]
    """
    M = int(np.prod(channel.sizes))
    if M > MAX_MODES:
        raise InputError("channel", f"the MJLS has one mode per joint state, prod k_i = "
                                    f"{' * '.join(map(str, channel.sizes))} = {M}; expected at most {MAX_MODES} "
                                    f"(at most {MAX_CHANNELS} two-state channels)")
    return product_chain(channel)[:3]


def product_chain(channel: MarkovChannel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(modes, T, h, start)``: :func:`mode_chain`'s joint states, transition matrix and per-mode delivery
    probabilities, and P(joint state at the first step) from each channel's start (the product of the channels'
    own), with no limit on the number of modes M = prod_i k_i (the caller prices it). Time O(M^2 + M m).

    Examples
    --------
    >>> modes, T, h, start = product_chain(GilbertElliott(p=[0.1, 0.1], r=[0.3, 0.3], belief=[1.0, 0.25]))
    >>> modes.tolist(), start.tolist()                     # good, good: 0.25
    ([[0, 0], [0, 1], [1, 0], [1, 1]], [0.25, 0.75, 0.0, 0.0])
    """
    m, M = channel.m, int(np.prod(channel.sizes))
    modes = np.array(list(itertools.product(*(range(k) for k in channel.sizes))), dtype=int).reshape(M, m)
    T = np.ones((1, 1))
    for Ti in channel.transition:
        T = np.kron(T, Ti)
    starts = [pi0 for _, _, pi0 in chain_matrices(channel)]
    start = np.prod([starts[i][modes[:, i]] for i in range(m)], axis=0)
    return modes, T, channel.padded_delivery[np.arange(m), modes], start


def mode_start(channel: MarkovChannel) -> np.ndarray:
    """P(mode at the first step) from each channel's start in :func:`~packetloss_cvx.markov.chain.chain_matrices`,
    in :func:`mode_chain`'s order. O(M m).

    Examples
    --------
    >>> mode_start(GilbertElliott(p=[0.1, 0.1], r=[0.3, 0.3], belief=[1.0, 0.25])).tolist()   # good, good: 0.25
    [0.25, 0.75, 0.0, 0.0]
    """
    mode_chain(channel)                                   # refused beyond MAX_MODES, as the chain it starts
    return product_chain(channel)[3]


def _patterns(h: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """The delivery patterns v in {0,1}^m with positive probability given per-channel probabilities h."""
    out = []
    for v in itertools.product([1, 0], repeat=h.size):
        v = np.array(v, dtype=float)
        prob = float(np.prod(np.where(v == 1, h, 1 - h)))
        if prob > 0:
            out.append((prob, v))
    return out


def delivery_patterns(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every delivery pattern v in {0, 1}^m (2^m, m), and P(v | mode) (M, 2^m) for per-mode delivery probabilities
    ``h`` (M, m), the channels independent given the mode. O(M 2^m m).

    Examples
    --------
    >>> patterns, prob = delivery_patterns(np.array([[0.9], [0.2]]))
    >>> patterns.tolist(), prob.round(12).tolist()
    ([[1.0], [0.0]], [[0.9, 0.1], [0.2, 0.8]])
    """
    patterns = np.array(list(itertools.product([1, 0], repeat=h.shape[1])), dtype=float)
    return patterns, np.prod(np.where(patterns[None] == 1, h[:, None], 1 - h[:, None]), axis=2)


def check_operator_size(modes: int, n: int) -> None:
    """Refuse, before building it, a dense coupled operator beyond :data:`MAX_OPERATOR_DIM` rows.

    Raises
    ------
    ResourceError
        ``modes n^2 > MAX_OPERATOR_DIM``: the message names the size, its memory and the way out.

    Examples
    --------
    >>> check_operator_size(4, 3), check_operator_size(2**10, 10)    # 4 * 3^2 = 36 rows pass; 102400 do not
    Traceback (most recent call last):
    packetloss_cvx.errors.ResourceError: the MJLS second-moment operator is dense with 2^m n^2 = 1024 * 10^2 ...
    """
    dim = modes * n * n
    if dim > MAX_OPERATOR_DIM:
        needed = 8.0 * dim * dim * 2
        raise ResourceError(f"the MJLS second-moment operator is dense with 2^m n^2 = {modes} * {n}^2 = {dim} rows "
                            f"(about {needed / 2**30:.2f} GiB and O({dim}^3) time for its eigenvalues); this "
                            f"computation is limited to {MAX_OPERATOR_DIM} rows: fewer states or channels",
                            needed, 8.0 * MAX_OPERATOR_DIM ** 2 * 2)


def _mode_gains(gains: np.ndarray, M: int, m: int, n: int) -> np.ndarray:
    K = np.asarray(gains, dtype=float)
    K = np.repeat(K[None], M, axis=0) if K.ndim == 2 else K
    if K.shape != (M, m, n):
        raise InputError("gains", f"expected an ({m}, {n}) gain or ({M}, {m}, {n}) mode gains, found {K.shape}")
    return K


def second_moment_operator(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, gains: np.ndarray,
                           delivery: str = "current") -> np.ndarray:
    """The matrix of the coupled second-moment map on stacked vec(Q_a), (M n^2)×(M n^2).

    ``gains``: one m×n K for every mode, or an (M, m, n) array of mode gains K_a. ``delivery="current"``:
    the gain and the deliveries both follow the mode a (``Q_b <- sum_a T_ab E_{v|a}[G Q_a G']``, the mode known
    to the controller); ``"next"``: the gain follows the previous mode a, the deliveries the mode b the chain
    moves to (``Q_b <- sum_a T_ab E_{v|b}[G_a Q_a G_a']``, the TCP-like law of a Gilbert channel, whose
    acknowledgement reveals the last state). Time O(M 2^m n^4 + M^2 n^4), memory O(M^2 n^4); refused
    beyond :data:`MAX_OPERATOR_DIM` rows (:func:`check_operator_size`).

    Examples
    --------
    >>> one = np.ones((1, 1))
    >>> op = second_moment_operator(2 * one, one, GilbertElliott(p=[0.5], r=[0.5]), one)
    >>> op.shape, round(float(max(abs(np.linalg.eigvals(op)))), 12)     # x+ = (2 - v) x: E[(2 - v)^2] = 5 / 2
    ((2, 2), 2.5)
    """
    if delivery not in ("current", "next"):
        raise InputError("delivery", f"expected current or next, found {delivery!r}")
    modes, T, h = mode_chain(channel)
    M, n, m = len(modes), A.shape[0], B.shape[1]
    check_operator_size(M, n)
    K = _mode_gains(gains, M, m, n)
    patterns, prob = delivery_patterns(h)
    kron = np.empty((M, len(patterns), n * n, n * n))
    for a in range(M):
        for k, v in enumerate(patterns):
            G = A - B @ (v[:, None] * K[a])
            kron[a, k] = np.kron(G, G)
    if delivery == "current":
        blocks = np.einsum("av,avij->aij", prob, kron)[:, None] * T[:, :, None, None]          # [a, b]
    else:
        blocks = np.einsum("ab,bv,avij->abij", T, prob, kron)
    return blocks.transpose(1, 2, 0, 3).reshape(M * n * n, M * n * n)                        # rows b, columns a


def mean_square_radius(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, gains: np.ndarray,
                       delivery: str = "current", method: str = "auto") -> float:
    """Spectral radius of the coupled second-moment map (:func:`second_moment_operator`): < 1 iff the switched
    loop is mean-square stable.

    ``method``: "dense", the eigenvalues of the (M n^2)^2 matrix, time O((M n^2)^3), refused (ResourceError)
    beyond :data:`MAX_OPERATOR_DIM` rows; "krylov", ARPACK on the map applied matrix-free
    (O(M^2 n^2 + M n^2 (n + m)) per product, O(M n^2) memory per vector), its value checked against
    Collatz–Wielandt bounds proven from its eigenvector (NumericalError outside them); "auto", dense up to
    :data:`DENSE_MAX_DIM` rows, else Krylov (falling back to dense within :data:`MAX_OPERATOR_DIM` rows). A failed
    eigenvalue routine (numpy.linalg.LinAlgError) is a NumericalError, as is an operator that is not finite.

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.5], r=[0.5])            # memoryless, delivers half the time
    >>> # x+ = (2 - v) x: E[x^2] grows by (4 + 1) / 2 per step
    >>> round(mean_square_radius(np.array([[2.0]]), np.array([[1.0]]), ch, np.array([[1.0]])), 12)
    2.5
    """
    if method not in ("auto", "dense", "krylov"):
        raise InputError("method", f"expected auto, dense or krylov, found {method!r}")
    if delivery not in ("current", "next"):
        raise InputError("delivery", f"expected current or next, found {delivery!r}")
    modes, T, h = mode_chain(channel)
    M, n, m = len(modes), A.shape[0], B.shape[1]
    K = _mode_gains(gains, M, m, n)
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
        raise NumericalError("MJLS mean-square radius: the gains or the plant are not finite")
    dim = M * n * n
    if method == "krylov" or (method == "auto" and dim > DENSE_MAX_DIM and dim >= 8):
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                return _krylov_radius(A, B, T, h, K, delivery)
        except NumericalError:
            if method == "krylov" or dim > MAX_OPERATOR_DIM:
                raise
    op = second_moment_operator(A, B, channel, K, delivery)
    with np.errstate(over="ignore", invalid="ignore"):
        try:
            vals = np.linalg.eigvals(op) if np.all(np.isfinite(op)) else np.array([np.inf])
        except np.linalg.LinAlgError as err:
            raise NumericalError(f"MJLS mean-square radius: the eigenvalue routine failed ({err})") from None
    if not np.all(np.isfinite(vals)):
        raise NumericalError("MJLS mean-square radius: the second-moment operator is not finite")
    return float(max(abs(vals)))


def moment_step(Q: np.ndarray, K: np.ndarray, R: np.ndarray, A: np.ndarray, B: np.ndarray, h: np.ndarray,
                H2: np.ndarray, delivery: str) -> tuple[np.ndarray, np.ndarray]:
    """One noise-free step of the coupled second moments: ``(Q', KQK)``.

    ``Q`` (a, n, n) and ``K`` (a, m, n) per information mode a, ``R`` (a, M) its transition rows, ``h`` (M, m)
    and ``H2`` (M, m, m) the first and second delivery moments per mode. ``"current"``:
    ``Q'_b = sum_a R_ab E_{v|a}[G_a Q_a G_a']``, ``KQK[a] = K_a Q_a K_a'``; ``"next"``:
    ``Q'_b = sum_a R_ab E_{v|b}[G_a Q_a G_a']``, ``KQK[b] = sum_a R_ab K_a Q_a K_a'``. With
    ``E_{v|c}[G Q G'] = AQA' - AQK'H_c B' - B H_c KQA' + B((KQK') ∘ H2_c)B'``; the expected input cost is
    ``sum_c sum_i psi_i h_ci KQK[c]_ii``. Time O(a M n^2 + a n^2 (n + m)).

    Examples
    --------
    >>> one, half = np.ones((1, 1)), np.full((1, 1), 0.5)     # x+ = (2 - v) x, v ~ Bernoulli(1/2), E[x^2] = 1
    >>> [a.tolist() for a in moment_step(one[None], one[None], one, 2 * one, one, half, half[None], "current")]
    [[[[2.5]]], [[[1.0]]]]
    """
    AQA = np.einsum("ij,ajk,lk->ail", A, Q, A)
    C = np.einsum("ij,ajk,alk->ail", A, Q, K)                                                  # A Q_a K_a'
    KQK = np.einsum("aij,ajk,alk->ail", K, Q, K)
    if delivery == "next":
        AQA, C, KQK = (np.einsum("ab,aij->bij", R, X) for X in (AQA, C, KQK))               # sum_a R_ab X_a
    Y = AQA - np.einsum("cij,cj,kj->cik", C, h, B) - np.einsum("ij,cj,ckj->cik", B, h, C) \
        + np.einsum("ij,cjk,lk->cil", B, KQK * H2, B)
    return (np.einsum("ab,aij->bij", R, Y) if delivery == "current" else Y), KQK


def delivery_moments(h: np.ndarray) -> np.ndarray:
    """``E[v v' | mode] = h h' + diag(h (1 - h))`` per mode (independent channels), (M, m, m). O(M m^2).

    Examples
    --------
    >>> delivery_moments(np.array([[0.5, 1.0]])).tolist()     # h h' + diag(h (1 - h))
    [[[0.5, 0.5], [0.5, 1.0]]]
    """
    return h[:, :, None] * h[:, None, :] + np.einsum("ai,ij->aij", h * (1 - h), np.eye(h.shape[1]))


def _krylov_radius(A: np.ndarray, B: np.ndarray, T: np.ndarray, h: np.ndarray, K: np.ndarray, delivery: str) -> float:
    """ARPACK on the coupled map (never forming it), checked against Collatz–Wielandt bounds from a positive
    definite tuple X near the Perron vector: ``L(X) >= c X`` proves rho >= c, ``L(X) <= c X`` proves rho <= c
    (blockwise Loewner order; L maps PSD tuples to PSD tuples). Time O(iterations (M^2 n^2 + M n^2 (n + m)))."""
    from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, LinearOperator, eigs  # optional.LAZY_IMPORTS

    M, n = T.shape[0], A.shape[0]
    D, H2 = M * n * n, delivery_moments(h)
    k = min(6, D - 2)
    ncv = min(D, max(2 * k + 1, 20))
    if 8.0 * D * (ncv + 4) > MEMORY_BUDGET_BYTES:
        raise ResourceError(f"the MJLS radius needs {ncv + 4} Krylov vectors of 2^m n^2 = {D} entries "
                            f"({8.0 * D * (ncv + 4) / 2**30:.1f} GiB)", 8.0 * D * (ncv + 4), MEMORY_BUDGET_BYTES)

    def apply(v: np.ndarray) -> np.ndarray:
        Q = v.reshape(M, n, n)
        return moment_step(0.5 * (Q + Q.transpose(0, 2, 1)), K, T, A, B, h, H2, delivery)[0].ravel()

    op = LinearOperator((D, D), matvec=apply, dtype=float)
    try:
        vals, vecs = eigs(op, k=k, which="LM", tol=ARPACK_TOL, v0=np.tile(np.eye(n).ravel(), M),
                          ncv=ncv, maxiter=max(300, 10 * n))
    except (ArpackNoConvergence, ArpackError) as err:
        raise NumericalError(f"MJLS mean-square radius: ARPACK did not converge ({err})") from None
    top = int(np.argmax(np.abs(vals)))
    radius = float(abs(vals[top]))
    v = vecs[:, top] * np.exp(-1j * np.angle(vecs[np.argmax(np.abs(vecs[:, top])), top]))
    X = v.real.reshape(M, n, n)
    X = 0.5 * (X + X.transpose(0, 2, 1))
    X = X if np.einsum("aii->", X) >= 0 else -X
    try:
        w, U = np.linalg.eigh(X)
    except np.linalg.LinAlgError as err:
        raise NumericalError(f"MJLS mean-square radius: the Collatz-Wielandt check failed ({err})") from None
    w = np.maximum(w, 1e-10 * max(float(w.max()), np.finfo(float).tiny))
    root_inv = np.einsum("aij,aj,akj->aik", U, 1 / np.sqrt(w), U)
    Y = moment_step(np.einsum("aij,aj,akj->aik", U, w, U), K, T, A, B, h, H2, delivery)[0]
    Z = np.einsum("aij,ajk,akl->ail", root_inv, Y, root_inv)
    try:
        ratios = np.linalg.eigvalsh(0.5 * (Z + Z.transpose(0, 2, 1)))
    except np.linalg.LinAlgError as err:
        raise NumericalError(f"MJLS mean-square radius: the Collatz-Wielandt check failed ({err})") from None
    lower, upper = max(float(ratios[:, 0].min()), 0.0), float(ratios[:, -1].max())
    if not (np.isfinite(radius) and lower * (1.0 - 1e-9) <= radius <= upper * (1.0 + 1e-9)):
        raise NumericalError(f"MJLS mean-square radius: ARPACK's {radius:.6g} lies outside the proven bounds "
                             f"[{lower:.6g}, {upper:.6g}]")
    return radius


def jump_law_stage_costs(system: System, gains: np.ndarray, steps: int, delivery: str = "current",
                         first_gain: np.ndarray | None = None) -> np.ndarray:
    """Exact E[x_t' Omega_1 x_t + (V_t u_t)' Psi_0 (V_t u_t)], t = 0..steps-1, of the mode-dependent law
    ``u_t = -K_{t,a} x_t`` behind the system's chain, from x0 and the channel's initial belief.

    ``gains``: (M, m, n) or (steps, M, m, n). ``delivery="current"``: a = the chain's mode at t (known to the
    controller); ``"next"``: a = its mode at t - 1 (revealed by the acknowledgements), the law at t = 0 being
    ``first_gain`` (m×n, the information of the initial belief). Exact recursion on
    ``Q_{a,t} = E[x_t x_t' 1{mode = a}]`` (CFM05, ch. 3), using ``E[v | b] = h_b`` and
    ``E[v v' | b] = h_b h_b' + diag(h_b (1 - h_b))``; noise enters with P(mode). Entries stay inf past an overflow.
    Time O(steps (M^2 n^2 + M (n^3 + n^2 m))), memory O(M n^2 + steps M m n).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.5], r=[0.5]))          # u = -x: 1 + 1/2, then 5/2 (1 + 1/2)
    >>> jump_law_stage_costs(s, np.ones((2, 1, 1)), 2).tolist()
    [1.5, 3.75]
    """
    system = check_system(system)
    if system.channel is None:
        raise InputError("system", "expected a system with a Gilbert-Elliott channel ([channel] model = ...)")
    if delivery not in ("current", "next"):
        raise InputError("delivery", f"expected current or next, found {delivery!r}")
    modes, T, h = mode_chain(system.channel)
    A, B, Sigma = system.A, system.B, system.noise_cov
    Omega, psi = system.state_weights[0], system.input_weights[0]
    M, n, m = len(modes), system.n, system.m
    K_all = np.asarray(gains, dtype=float)
    K_all = np.broadcast_to(K_all, (steps, *K_all.shape)) if K_all.ndim == 3 else K_all
    if K_all.shape != (steps, M, m, n):
        raise InputError("gains", f"expected ({M}, {m}, {n}) or ({steps}, {M}, {m}, {n}) mode gains, found "
                                  f"{K_all.shape}")
    pi = mode_start(system.channel)                                                          # P(mode at 0)
    H2 = delivery_moments(h)
    x0 = system.x0
    if delivery == "next":
        if first_gain is None:
            raise InputError("first_gain", "the law at t = 0 is needed with delivery='next'")
        Q, K, R = np.outer(x0, x0)[None], np.asarray(first_gain, dtype=float)[None], pi[None]
    else:
        Q, K, R = pi[:, None, None] * np.outer(x0, x0), K_all[0], T
    out = np.empty(steps)
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(steps):
            state = float(np.einsum("ij,aji->", Omega, Q))
            Q_next, KQK = moment_step(Q, K, R, A, B, h, H2, delivery)
            inputs = float(np.einsum("i,ci,cii->", psi, h, KQK))
            if delivery == "current":
                pi = pi @ T                                                                  # P(mode at t + 1)
            else:
                pi, R = (pi if t == 0 else pi @ T), T                                        # P(mode at t)
            out[t] = state + inputs
            Q = Q_next + pi[:, None, None] * Sigma
            if t + 1 < steps:
                K = K_all[t + 1]
    return np.where(np.isfinite(out), out, np.inf)


def coupled_riccati(system: System, max_iter: int = 20000) -> MjlsResult:
    """Optimal mode-dependent gains with the channel state known: the coupled Riccati equations,
    solved by value iteration from P_a = Omega (the backward DP of the infinite horizon), then the
    mean-square radius of the loop they close.

    Uses A, B, the first stage's weights (Omega_1, Psi_0) and the system's Gilbert–Elliott channel.
    Time O(iterations M (M n^2 + 2^m m^3 + n^3)).

    Raises
    ------
    InputError
        No Markov channel, or more than :data:`MAX_CHANNELS` channels.
    NumericalError
        No convergence within ``max_iter`` (the loop is not mean-square stabilisable, or barely),
        or a residual of the coupled equations above ``SELF_CHECK_RTOL`` relative to max ||P_a||.

    Examples
    --------
    >>> res = coupled_riccati(System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0],
    ...                              x0=[1.0], channel=GilbertElliott(p=[0.0], r=[1.0])))   # always good next
    >>> P = 2 + 5 ** 0.5                  # the scalar DARE P = 1 + 4 P - 4 P^2 / (P + 1); K = 2 P / (P + 1)
    >>> bool(np.allclose([res.gains[0, 0, 0], res.spectral_radius], [2 * P / (P + 1), (2 - 2 * P / (P + 1)) ** 2]))
    True
    """
    system = check_system(system)
    if system.channel is None:
        raise InputError("system", "expected a system with a Gilbert-Elliott channel ([channel] model = ...)")
    A, B = system.A, system.B
    Omega, Psi = system.state_weights[0], np.diag(system.input_weights[0])
    modes, T, h = mode_chain(system.channel)
    P = np.repeat(Omega[None], len(modes), axis=0)
    iteration = 0
    while iteration < max_iter:
        iteration += 1
        new, K = _riccati_step(P, A, B, Omega, Psi, T, h)
        if not np.all(np.isfinite(new)):
            break
        change = float(np.max(np.abs(new - P))) / max(float(np.max(np.abs(new))), 1e-300)
        P = new
        if change <= 1e-2 * SELF_CHECK_RTOL:
            break
    again, K = _riccati_step(P, A, B, Omega, Psi, T, h)
    scale = max(float(np.max(np.abs(P))), 1e-300)
    residual = float(np.max(np.abs(again - P))) / scale if np.all(np.isfinite(again)) else float("inf")
    if not residual <= SELF_CHECK_RTOL:
        raise NumericalError(f"the coupled Riccati iteration did not converge in {iteration} steps (relative "
                             f"residual {residual:.1e}): the loop is not mean-square stabilisable by mode-dependent "
                             "gains, or only barely")
    radius = mean_square_radius(A, B, system.channel, K)
    return MjlsResult(gains=K, cost_matrices=P, modes=modes, transition=T, spectral_radius=radius,
                      iterations=iteration, residual=residual)


def _riccati_step(P: np.ndarray, A: np.ndarray, B: np.ndarray, Omega: np.ndarray, Psi: np.ndarray,
                  T: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One backward step of the coupled equations: (P_a, K_a) for every mode a, all modes as one batch of
    Theorem 1's step (:func:`packetloss_cvx.recursion.riccati_step` with ``mu = h_a``, ``P = E_a`` and the
    loss variance weighted by E_a): ``S_a = H_a G_a`` with ``G_a = B'E_aB H_a + diag(psi + (1 - h_a)
    diag(B'E_aB))`` (the diagonal of ``H Psi H + diag(h (1 - h)) Psi`` is ``h psi``), so ``S_a K = H_a B'E_a A``
    and ``G_a K = B'E_a A`` agree on the actuators that can deliver; K_a = 0 on the others (their row never
    reaches P_a: it is multiplied by h = 0). O(M (M n^2 + n^3 + m^3))."""
    E = np.einsum("ab,bij->aij", T, P)
    E = 0.5 * (E + E.transpose(0, 2, 1))
    psi = np.broadcast_to(np.diag(Psi), h.shape)
    with np.errstate(over="ignore", invalid="ignore"):
        try:   # a diverging iteration (no stabilising gains) overflows: the caller sees non-finite P
            gains, out = riccati_step(E, A, B, h, psi, Omega, variance=True)
        except np.linalg.LinAlgError:
            return np.full_like(P, np.nan), np.full((P.shape[0], B.shape[1], A.shape[0]), np.nan)
    gains[np.broadcast_to((h <= 0)[:, :, None], gains.shape)] = 0.0
    return out, gains
