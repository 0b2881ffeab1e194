"""The loop behind Markov channels as a Markov jump linear system (MJLS).

Mode theta_k = the joint channel state (of the prod_i k_i joint states of a
[`MarkovChannel`][packetloss_cvx.model.channel.MarkovChannel], 2^m for Gilbert–Elliott channels, those the chain can
visit from its start: model.chain.mode_chain; channels independent: the mode chain's transition matrix is the
Kronecker product of the channels' own, restricted to them). A state the chain never reaches never enters the loop,
so it decides no radius, gain or certificate here. In mode a, actuator i's
packet arrives with probability h_{a,i} (d_i of the state; h_good or h_bad), independently. The closed loop
``x_{k+1} = (A - B V_k K_a) x_k``
is mean-square stable iff the spectral radius of its coupled second-moment operator

    Q_b  <-  sum_a T_ab E_v[(A - B V K_a) Q_a (A - B V K_a)' | a]

is below 1 (Costa, Fragoso, Marques, *Discrete-Time Markov Jump Linear Systems*, 2005, Thm 3.9).

With the mode known to the controller (the channel state observed), the optimal mode-dependent law for
``sum_k x_k' Omega x_k + (V_k u_k)' Psi (V_k u_k)`` solves the coupled Riccati equations (CFM05, ch. 4)

    E_a = sum_b T_ab P_b,   G_a = B'E_a B + Psi,   S_a = H_a G_a H_a + diag(h_a (1 - h_a)) ∘ G_a,
    P_a = Omega + A'E_a A - A'E_a B H_a S_a^{-1} H_a B'E_a A,   K_a = S_a^{-1} H_a B'E_a A

(H_a = diag(h_a); S_a inverted on the actuators that can deliver; an actuator that cannot, h_{a,i} = 0, keeps the row
of ``G_a^{-1} B'E_a A`` with ``S_a = H_a G_a``, the limit of its optimal row as h_{a,i} -> 0+: closedloop.riccati's
mode_riccati, the one solver of these equations and of the Bernoulli one, its one-mode case). With a memoryless
chain (p + r = 1) every E_a is the same, and pbar = sum_a pi_a P_a solves the Bernoulli TCP-like
Riccati equation with mu = r (for one channel: P = Omega + A'PA - mu A'PB (B'PB + Psi)^{-1} B'PA).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..budgets import check, gib_text, operator_bytes
from ..errors import InputError, NumericalError
from ..model.chain import MAX_CHANNELS, MAX_MODES, mode_chain, mode_start, product_chain, reachable_modes
from ..model.channel import (
    GilbertElliott,  # noqa: F401 (GilbertElliott: the doctests' constructor)
    MarkovChannel,
)
from ..model.system import System, check_system, loop_weights
from ..results import MjlsResult
from ..tolerances import RICCATI_MAX_ITER
from .certificates import chain_outside_proved
from .modes import DENSE_MAX_DIM, MAX_OPERATOR_DIM, delivery_moments, mode_matrix, mode_radius, mode_stage_costs
from .riccati import mode_riccati

# MAX_CHANNELS, MAX_MODES and the mode chain (mode_chain, product_chain, mode_start) are the channel model's
# (model.chain); MAX_OPERATOR_DIM (rows of the dense coupled operator at most) and DENSE_MAX_DIM (rows up to which the
# radius takes its dense eigenvalues by default) the mode engine's (closedloop.modes): all re-exported here.

__all__ = [
    "DENSE_MAX_DIM", "MAX_CHANNELS", "MAX_OPERATOR_DIM", "check_operator_size", "coupled_riccati",
    "MAX_MODES", "delivery_moments", "jump_law_stage_costs", "mean_square_radius", "mode_chain",
    "delivery_patterns", "mode_start", "product_chain", "second_moment_operator",
]


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
    """Refuse, before building it, a dense coupled operator beyond the ``operator_rows`` budget (budgets.py; by
    default `MAX_OPERATOR_DIM` rows).

    Raises
    ------
    BudgetError
        ``modes n^2`` beyond the budget, under ``channel``: the message names the size, its memory and the way out.

    Examples
    --------
    >>> check_operator_size(4, 3), check_operator_size(2**10, 10)    # 4 * 3^2 = 36 rows pass; 102400 do not
    Traceback (most recent call last):
    packetloss_cvx.errors.BudgetError: channel: the MJLS second-moment operator, dense with 2^m n^2 = 1024 * 10^2 ...
    """
    dim = modes * n * n
    check("operator_rows", dim, "channel",
          f"the MJLS second-moment operator, dense with 2^m n^2 = {modes} * {n}^2 = {dim} rows (about "
          f"{gib_text(operator_bytes(dim))} and O({dim}^3) time for its eigenvalues)",
          instead="use fewer chain states or channels (mean_square_radius's method='krylov' builds no dense operator)")


def _reachable_rows(K: np.ndarray, channel: MarkovChannel, M: int, axis: int) -> np.ndarray:
    """Gains given for every joint state (prod k_i along ``axis`` of a 3-axis-or-more K) cut to `mode_chain`'s M
    reachable modes; K as it is otherwise (the caller checks its shape). O(size)."""
    live = reachable_modes(channel)
    if K.ndim == axis + 3 and K.shape[axis] == live.size != M:
        return np.compress(live, K, axis=axis)
    return K


def _mode_gains(gains: np.ndarray, channel: MarkovChannel, M: int, m: int, n: int) -> np.ndarray:
    """One gain per mode of `mode_chain` (M of them); gains given for every joint state (prod k_i, reachable or not)
    keep the reachable modes' rows."""
    K = np.asarray(gains, dtype=float)
    K = _reachable_rows(np.repeat(K[None], M, axis=0) if K.ndim == 2 else K, channel, M, 0)
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
    beyond `MAX_OPERATOR_DIM` rows (`check_operator_size`).

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
    return mode_matrix(A, B, _mode_gains(gains, channel, M, m, n), h, T, delivery)


def mean_square_radius(A: np.ndarray, B: np.ndarray, channel: MarkovChannel, gains: np.ndarray,
                       delivery: str = "current", method: str = "auto") -> float:
    """Spectral radius of the coupled second-moment map (`second_moment_operator`): < 1 iff the switched
    loop is mean-square stable.

    ``method``: "dense", the eigenvalues of the (M n^2)^2 matrix, time O((M n^2)^3), refused (BudgetError)
    beyond the ``operator_rows`` budget (`MAX_OPERATOR_DIM` rows); "krylov", ARPACK on the map applied matrix-free
    (O(M^2 n^2 + M n^2 (n + m)) per product, O(M n^2) memory per vector), its value checked against
    Collatz–Wielandt bounds proven from its eigenvector and a power bound, falling back to dense within
    `MAX_OPERATOR_DIM` rows where it fails the check (NumericalError beyond); "auto", dense up to
    `DENSE_MAX_DIM` rows, else Krylov (`mode_radius`). A failed
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
    K = _mode_gains(gains, channel, M, m, n)
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
        raise NumericalError("MJLS mean-square radius: the gains or the plant are not finite")

    def matrix() -> np.ndarray:
        check_operator_size(M, n)
        return mode_matrix(A, B, K, h, T, delivery)

    return mode_radius(A, B, K, h, T, delivery, method, matrix, label="MJLS mean-square radius")


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
    Omega, psi = loop_weights(system)
    M, n, m = len(modes), system.n, system.m
    K_all = np.asarray(gains, dtype=float)
    K_all = np.broadcast_to(K_all, (steps, *K_all.shape)) if K_all.ndim == 3 else K_all
    K_all = _reachable_rows(K_all, system.channel, M, 1)           # a gain for every joint state: the modes' rows
    if K_all.shape != (steps, M, m, n):
        raise InputError("gains", f"expected ({M}, {m}, {n}) or ({steps}, {M}, {m}, {n}) mode gains, found "
                                  f"{K_all.shape}")
    if delivery == "next" and first_gain is None:
        raise InputError("first_gain", "the law at t = 0 is needed with delivery='next'")
    stage, _ = mode_stage_costs(A, B, Omega, psi, Sigma, system.x0, K_all, h, T, mode_start(system.channel),
                                delivery, first_gain)
    return stage


def coupled_riccati(system: System, max_iter: int = RICCATI_MAX_ITER) -> MjlsResult:
    """Optimal mode-dependent gains with the channel state known: the stabilising solution of the coupled Riccati
    equations (module docstring), and the mean-square radius of the loop its gains close.

    `mode_riccati` behind the mode chain, the solver of
    [`dp_riccati`][packetloss_cvx.closedloop.riccati.dp_riccati] (its one-mode case): value iteration from P_a = Omega,
    then policy iteration (the coupled Lyapunov equations of each law) to the fixed point. An actuator that cannot
    deliver in a mode keeps the row ``G_a^{-1} B'E_aA`` (the limit of its optimal row as h -> 0+; it never reaches
    the loop). Uses A, B, the first stage's weights (Omega_1, Psi_0) and the system's Markov channel.
    Time O(iterations M (M n^2 + 2^m m^3 + n^3)) plus O((M n^2)^3) per policy step.

    Raises
    ------
    InputError
        No Markov channel, or more than `MAX_CHANNELS` channels.
    NumericalError
        The loop is proved not mean-square stabilisable by any mode-dependent law (the diverging iteration's
        direction, checked in exact arithmetic: certificates.chain_outside_proved); or, without a verdict, no
        convergence within ``max_iter`` value steps, a limit that is not stabilising, or a residual of the coupled
        equations above ``MOMENT_RESIDUAL_RTOL`` relative to ||P|| (Frobenius over the modes).

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
    A, B, channel = system.A, system.B, system.channel
    modes, T, h = mode_chain(channel)
    K, P, iterations, residual, radius = mode_riccati(
        A, B, system.state_weights[0], system.input_weights[0], h, T,
        proves=lambda P: chain_outside_proved(A, B, channel, P, 1.0, "current"), max_iter=max_iter,
        label="coupled Riccati equations", where=" behind the chain")
    return MjlsResult(gains=K, cost_matrices=P, modes=modes, transition=T, spectral_radius=radius,
                      iterations=iterations, residual=residual)
