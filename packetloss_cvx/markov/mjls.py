"""The loop behind Gilbert–Elliott channels as a Markov jump linear system (MJLS).

Mode theta_k = the joint channel state (2^m modes, channels independent: the mode chain's transition
matrix is the Kronecker product of the channels' 2×2 ones). In mode a, actuator i's packet arrives with
probability h_{a,i} (h_good or h_bad), independently. The closed loop ``x_{k+1} = (A - B V_k K_a) x_k``
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

from ..channel import GilbertElliott
from ..errors import InputError, NumericalError
from ..model import System, check_system
from ..results import MjlsResult
from ..tolerances import SELF_CHECK_RTOL

__all__ = ["MAX_CHANNELS", "coupled_riccati", "mean_square_radius", "mode_chain", "second_moment_operator"]

#: 2^m modes and 2^m delivery patterns per mode: beyond this many channels the operator is refused.
MAX_CHANNELS = 6


def mode_chain(channel: GilbertElliott) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(modes, T, h)``: the 2^m joint states (1 = good, channel 0 the most significant), their
    transition matrix (Kronecker product of the channels' chains) and per-mode delivery probabilities.
    Time O(4^m m)."""
    m = channel.m
    if m > MAX_CHANNELS:
        raise InputError("channel", f"the MJLS has 2^m modes; expected at most {MAX_CHANNELS} channels, found {m}")
    modes = np.array(list(itertools.product([1, 0], repeat=m)), dtype=int)
    T = np.ones((1, 1))
    for i in range(m):
        Ti = np.array([[1 - channel.p[i], channel.p[i]], [channel.r[i], 1 - channel.r[i]]])
        T = np.kron(T, Ti)
    h = np.where(modes == 1, channel.h_good, channel.h_bad)
    return modes, T, h


def _patterns(h: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """The delivery patterns v in {0,1}^m with positive probability given per-channel probabilities h."""
    out = []
    for v in itertools.product([1, 0], repeat=h.size):
        v = np.array(v, dtype=float)
        prob = float(np.prod(np.where(v == 1, h, 1 - h)))
        if prob > 0:
            out.append((prob, v))
    return out


def second_moment_operator(A: np.ndarray, B: np.ndarray, channel: GilbertElliott, gains: np.ndarray) -> np.ndarray:
    """The matrix of Q -> (sum_a T_ab E_v[Gamma Q_a Gamma'])_b on stacked vec(Q_a), (M n^2)×(M n^2).

    ``gains``: one m×n K for every mode, or an (M, m, n) array of mode gains. Time O(M^2 n^4 + 2^m M n^4).
    """
    modes, T, h = mode_chain(channel)
    M, n = len(modes), A.shape[0]
    K = np.asarray(gains, dtype=float)
    K = np.repeat(K[None], M, axis=0) if K.ndim == 2 else K
    if K.shape != (M, B.shape[1], n):
        raise InputError("gains", f"expected an ({B.shape[1]}, {n}) gain or ({M}, {B.shape[1]}, {n}) mode gains, "
                                  f"found {K.shape}")
    blocks = []
    for a in range(M):
        acc = np.zeros((n * n, n * n))
        for prob, v in _patterns(h[a]):
            G = A - B @ (v[:, None] * K[a])
            acc += prob * np.kron(G, G)
        blocks.append(acc)
    op = np.zeros((M * n * n, M * n * n))
    for a in range(M):
        for b in range(M):
            op[b * n * n:(b + 1) * n * n, a * n * n:(a + 1) * n * n] = T[a, b] * blocks[a]
    return op


def mean_square_radius(A: np.ndarray, B: np.ndarray, channel: GilbertElliott, gains: np.ndarray) -> float:
    """Spectral radius of :func:`second_moment_operator`: < 1 iff the switched loop is mean-square stable.

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.5], r=[0.5])            # memoryless, delivers half the time
    >>> # x+ = (2 - v) x: E[x^2] grows by (4 + 1) / 2 per step
    >>> round(mean_square_radius(np.array([[2.0]]), np.array([[1.0]]), ch, np.array([[1.0]])), 12)
    2.5
    """
    return float(max(abs(np.linalg.eigvals(second_moment_operator(A, B, channel, gains)))))


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
    """One backward step of the coupled equations: (P_a, K_a) for every mode a."""
    M, n, m = P.shape[0], A.shape[0], B.shape[1]
    E = np.einsum("ab,bij->aij", T, P)
    out, gains = np.empty_like(P), np.zeros((M, m, n))
    with np.errstate(over="ignore", invalid="ignore"):
        for a in range(M):
            Ea = 0.5 * (E[a] + E[a].T)
            G = B.T @ Ea @ B + Psi
            L = h[a][:, None] * (B.T @ Ea @ A)                       # H B'E A
            S = h[a][:, None] * G * h[a][None, :] + np.diag(h[a] * (1 - h[a]) * np.diag(G))
            active = h[a] > 0
            Pa = Omega + A.T @ Ea @ A
            if np.any(active):
                Ka = np.linalg.solve(S[np.ix_(active, active)], L[active])
                gains[a][active] = Ka
                Pa = Pa - L[active].T @ Ka
            out[a] = 0.5 * (Pa + Pa.T)
    return out, gains
