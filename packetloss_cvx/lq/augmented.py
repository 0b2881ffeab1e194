"""The exact UDP-like expected cost under finite-state Markov losses as a deterministic LQ problem on an
augmented state, solved in O(N) time and memory (docs/mathematics.md, "Bursty links", "The exact cost at any
horizon").

With ``xhat_t = E[x_t]``, ``e_t = x_t - xhat_t``, ``delta_t = v_t - mu_t`` and channel i's chain
(`chain_matrices`: T_i, d_i, pi_{i,0}), the correlations
``xi_{t,i}(a) = E[e_t 1{S_{i,t} = a}]`` (n×k_i, rows summing to zero) obey

.. math:: \\xi_{t+1,i} = A \\xi_{t,i} T_i + b_i u_{t,i} c_{t,i}' T_i, \\qquad
          c_{t,i} = \\pi_{t,i} \\circ (d_i - \\mu_{t,i}),

and ``E[e_t delta_{t,i}] = xi_{t,i} d_i``. In an orthonormal basis E_i of the vectors orthogonal to 1
(k_i×(k_i - 1)), ``eta_i = xi_i E_i`` (n×(k_i - 1)) follows ``eta+ = A eta Lambda_i + b_i u_i gamma_i'``
with ``Lambda_i = E_i' T_i E_i`` (for two states the chain's second eigenvalue 1 - p - r) and
``gamma_{t,i} = E_i' T_i' c_{t,i}``; ``E[e_t delta_{t,i}] = eta_{t,i} g_i``, ``g_i = E_i' d_i``. The error
covariance follows

.. math:: \\Sigma_{t+1} = A\\Sigma_t A' + \\sum_i (A \\eta_{t,i} g_i u_{t,i} b_i' + b_i u_{t,i} g_i'\\eta_{t,i}'A')
          + \\sum_i \\mu_{t,i}(1 - \\mu_{t,i}) u_{t,i}^2 b_i b_i' + \\Sigma_W,

so with the backward Lyapunov sums ``S_t = Omega_{t+1} + A'S_{t+1}A`` the expected cost is, on
``z_t = (xhat_t, eta_{t,1}, ..., eta_{t,m})`` of size ``n (1 + sum_i (k_i - 1))``,

    x'Q x + sum_t [xhat_{t+1}'Omega_{t+1} xhat_{t+1} + u_t'R_t u_t + 2 u_t'N_t z_t] + sum_t tr(S_t Sigma_W),

``R_t = M_t (Psi_t + (I - M_t) diag(B'S_t B))`` (Lemma 1's UDP-like weight), row i of ``N_t`` pairing
``b_i'S_t A`` with ``eta_{t,i} g_i``: a deterministic LQ problem with a state-input cross term, whose
backward Riccati recursion (`lq_cross_step`) gives the exact minimiser. `chain_cost` is the
referee: the forward pass of ``xhat``, ``eta`` and ``Sigma``, every cost term nonnegative.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..budgets import check, duration_text, estimated_seconds, markov_recursion_work
from ..errors import InputError, NumericalError
from ..linalg import lapack_dgesv
from ..model.chain import chain_matrices
from ..model.system import CacheKey, System, SystemStore
from ..tolerances import PLAN_COST_RTOL, SELF_CHECK_ATOL
from .policy import self_check
from .recursion import (
    STATIONARY_RUN,
    forward_cost,
    input_weight,
    leading_run,
    lyapunov_cross_weights,
    mean_states,
    overflow_error,
    plan_cost,
    states_by_powers,
    stationary_close,
    weight_head,
)
from .structure import structure_of

#: The lift of a system's own chains (:func:`chain_lift`), kept per system (a SystemStore): n and m (A's and B's
#: shapes), the horizon, the schedule the chains must predict and the chains themselves.
LIFT_KEY = CacheKey("markov.augmented.chain_lift", ("A", "B", "horizon", "mu_schedule", "channel"))
_LIFTS = SystemStore(LIFT_KEY)

__all__ = ["ChainLift", "augmented_size", "augmented_solve", "chain_cost", "chain_lift", "check_recursion_budget",
           "lq_cross_step", "mean_state_bound"]


@dataclass(frozen=True)
class ChainLift:
    """The chain part of the augmented state, per channel i (q_i = k_i - 1, 0 without a chain):
    ``Lam[i]`` (q_i, q_i), ``g[i]`` (q_i,), ``gamma[i]`` (N, q_i) (zero where mu_{t,i} = 0), and the
    offsets of each eta_i in z (``offsets[i]:offsets[i + 1]``, row-major n×q_i). ``size`` is dim z."""

    Lam: tuple[np.ndarray, ...]
    g: tuple[np.ndarray, ...]
    gamma: tuple[np.ndarray, ...]
    offsets: tuple[int, ...]
    size: int


@lru_cache(maxsize=64)
def _orthogonal_basis(k: int) -> np.ndarray:
    """An orthonormal basis (k×(k-1)) of the vectors orthogonal to the ones vector, read-only: one QR per k per
    process (a function of k alone; a chain allocation's grid lifts the same 2-state chains thousands of times).
    O(k^3) once, O(1) after."""
    if k == 1:
        basis = np.zeros((1, 0))
    else:
        basis = np.linalg.qr(np.eye(k)[:, : k - 1] - 1.0 / k)[0]
    basis.setflags(write=False)
    return basis


def _check_chain(i: int, T: np.ndarray, d: np.ndarray, pi0: np.ndarray) -> None:
    """The chain_matrices() contract, checked where an object outside this package may have answered. O(k^2)."""
    k = d.size
    if T.shape != (k, k) or pi0.shape != (k,) or d.ndim != 1:
        raise InputError("channel", f"channel {i}: chain_matrices() gave T {T.shape}, d {d.shape}, pi0 {pi0.shape}; "
                                    "expected (k, k), (k,), (k,)")
    tol = 1e-12 * k
    if not (np.all(T >= 0) and np.all(np.abs(T.sum(axis=1) - 1.0) <= tol)):
        raise InputError("channel", f"channel {i}: the transition matrix is not row-stochastic")
    if not np.all((d >= 0) & (d <= 1)):
        raise InputError("channel", f"channel {i}: delivery probabilities outside [0, 1]")
    if not (np.all(pi0 >= 0) and abs(pi0.sum() - 1.0) <= tol):
        raise InputError("channel", f"channel {i}: the initial distribution is not a probability vector")


def chain_lift(system: System, chains: tuple | None = None) -> ChainLift:
    """The lifted chains (`ChainLift`) of ``chains`` (per channel ``(T, d, pi0)``, default
    ``chain_matrices(system.channel)``); a system without a channel has none (q_i = 0: the augmented problem
    is then the paper's Bernoulli UDP-like one). The state distributions ``pi_{t+1} = pi_t T`` are propagated
    from each ``pi0``; their delivery probabilities ``pi_t d`` must be the system's ``mu_schedule`` (to 1e-9):
    the mean state uses the schedule, the covariances the chain. Time O(N m k^2), O(L m k^2 + N m k) for
    distributions that reach their float fixed point in L steps (the rest are copies, to the bit).

    Raises
    ------
    InputError
        Chains of the wrong number or shapes, or whose predicted delivery rates are not the system's schedule.

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.2]))
    >>> lift = chain_lift(s)               # Lambda = 1 - p - r; gamma = E'T'c with c = b (1 - b) (1, -1)
    >>> bool(np.isclose(lift.Lam[0][0, 0], 0.6) and np.allclose(np.abs(lift.gamma[0]), 0.6 * 0.25 * 2 ** 0.5))
    True
    """
    if chains is None:           # the system's own chains: lifted once and kept for the system (the exact minimum
        # and the referee's cost of a plan both lift them; a read-only value, as every kept one)
        kept = _LIFTS.get(system)
        if kept is None:
            kept = _LIFTS.put(system, _lift(system, chain_matrices(system.channel)
                                            if system.channel is not None else None))
        return kept
    return _lift(system, chains)


def _lift(system: System, chains: tuple | None) -> ChainLift:
    """`chain_lift` of ``chains`` (None: independent losses). Time O(N m k^2)."""
    N, n, m = system.horizon, system.n, system.m
    if chains is None:                                   # independent losses: nothing to lift
        none = [np.zeros(shape) for shape in ((0, 0), (0,), (N, 0))]
        for value in none:
            value.setflags(write=False)
        return ChainLift((none[0],) * m, (none[1],) * m, (none[2],) * m, (n,) * (m + 1), n)
    if len(chains) != m:
        raise InputError("channel", f"expected {m} chains (one per actuator), found {len(chains)}")
    Lam, g, gamma, offsets = [], [], [], [n]
    for i, (T, d, pi0) in enumerate(chains):
        T, d, pi0 = (np.asarray(a, dtype=float) for a in (T, d, pi0))
        _check_chain(i, T, d, pi0)
        E = _orthogonal_basis(d.size)
        pi = np.empty((N, d.size))
        pi[0] = pi0
        for t in range(1, N):
            pi[t] = pi[t - 1] @ T
            if np.array_equal(pi[t], pi[t - 1]):          # a fixed point of the float step: the rest are copies
                pi[t + 1:] = pi[t]
                break
        rate = pi @ d
        gap = np.abs(rate - system.mu_schedule[:, i])
        if not np.all(gap <= 1e-9):
            t = int(np.argmax(~(gap <= 1e-9)))
            raise InputError("channel", f"channel {i}: the chain's delivery probability at step {t} is {rate[t]!r} but "
                                        f"the system's mu_schedule has {system.mu_schedule[t, i]!r}")
        c = pi * (d - rate[:, None])                      # pi_t o (d - mu_t): sums to zero
        gam = (c @ T) @ E
        gam[system.mu_schedule[:, i] == 0.0] = 0.0        # a channel that cannot deliver adds no covariance
        for value, out in ((E.T @ T @ E, Lam), (E.T @ d, g), (gam, gamma)):
            value.setflags(write=False)                   # a frozen result: read-only arrays
            out.append(value)
        offsets.append(offsets[-1] + n * E.shape[1])
    return ChainLift(tuple(Lam), tuple(g), tuple(gamma), tuple(offsets), offsets[-1])


def augmented_size(system: System, chains: tuple | None = None) -> int:
    """D = n (1 + sum_i (k_i - 1)), the size of the augmented state (n without a chain), from the chains' sizes
    alone (nothing lifted). O(m).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.2]))
    >>> augmented_size(s)                  # n (1 + m) for Gilbert–Elliott channels
    2
    """
    if chains is None:
        chains = chain_matrices(system.channel) if system.channel is not None else ()
    return system.n * (1 + sum(max(np.shape(d)[0] - 1, 0) for _, d, _ in chains))


def check_recursion_budget(system: System, size: int, instead: str) -> None:
    """Refuse, before any work, an augmented recursion beyond the ``markov_recursion_work`` budget
    (`markov_recursion_work`, an upper bound: every step priced in full, though a stable chain's pass closes its
    settled tail sooner), naming the channel, the most time it takes and ``instead`` (what to use in its place). O(1).

    Raises
    ------
    BudgetError
        Field ``channel``: the chain (its number of states) makes the recursion too long.
    """
    N = system.horizon
    work = markov_recursion_work(N, size)
    seconds = estimated_seconds("markov_recursion_work", work)
    check("markov_recursion_work", work, "channel",
          f"the exact Markov recursion over N = {N} steps on an augmented state of size D = {size} (at most about "
          f"{duration_text(seconds)}, every step priced in full: a stable chain's settled tail ends sooner; {instead})")


def _dynamics(system: System, lift: ChainLift) -> np.ndarray:
    """The constant augmented transition: blkdiag(A, A ⊗ Lambda_1', ...) on row-major eta's. O(D^2). Each
    Kronecker block as the broadcast product of A and Lambda_i' (the products np.kron forms, one multiplication
    per entry, without its generic dimension handling, a sizeable share of a small chain's evaluation)."""
    n, A = system.n, system.A
    out = np.zeros((lift.size, lift.size))
    out[:n, :n] = A
    for i, L in enumerate(lift.Lam):
        a, b = lift.offsets[i], lift.offsets[i + 1]
        out[a:b, a:b] = (A[:, None, :, None] * L.T[None, :, None, :]).reshape(b - a, b - a)
    return out


def _input_maps(system: System, lift: ChainLift) -> np.ndarray:
    """ℬ_t (N, D, m) for every step: B M_t on xhat, b_i ⊗ gamma_{t,i} on eta_i (row-major). O(N D m)."""
    N, n, m = system.horizon, system.n, system.m
    out = np.zeros((N, lift.size, m))
    out[:, :n] = system.B[None] * system.mu_schedule[:, None, :]
    for i, gam in enumerate(lift.gamma):
        a, b = lift.offsets[i], lift.offsets[i + 1]
        out[:, a:b, i] = (system.B[None, :, i, None] * gam[:, None, :]).reshape(N, b - a)
    return out


def lq_cross_step(P: np.ndarray, F: np.ndarray, G: np.ndarray, R: np.ndarray, Ncross: np.ndarray,
                  scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One backward step of the LQ problem ``z+ = F z + G u`` with stage cost ``u'R u + 2 u'N z``:

    .. math:: H = R + G'PG,\\quad K = H^{-1}(G'PF + N),\\quad P^- = F'PF - (G'PF + N)'K

    (the caller adds the state weight of the step). ``scale`` (m,) scales H symmetrically before the solve
    (``sqrt(mu)``: H is ``M``-sized for rarely delivering channels); an input of scale 0 does not enter
    (its gain is 0, H's row and column are replaced by the identity's). Returns ``(K, P-)``, P- symmetrised.
    This is not Theorem 1's step ([`riccati_step`][packetloss_cvx.lq.recursion.riccati_step]): the input map is not
    ``B M`` and the cross term ``N`` has no counterpart there. Time O(D^3 + m^3), D = dim z.

    Examples
    --------
    >>> K, P = lq_cross_step(np.ones((1, 1)), np.ones((1, 1)), np.ones((1, 1)), np.ones((1, 1)), np.zeros((1, 1)),
    ...                      np.ones(1))
    >>> float(K[0, 0]), float(P[0, 0])          # scalar DARE step: H = 2, K = 1/2, P- = 1 - 1/2
    (0.5, 0.5)
    """
    PG = P @ G
    PF = P @ F
    H = R + G.T @ PG
    rhs = PG.T @ F + Ncross
    off = scale == 0.0
    s = np.where(off, 1.0, scale)[:, None]
    Hs = H / (s * s.T)
    rhs = rhs / s
    if off.any():
        Hs[off] = 0.0
        Hs[:, off] = 0.0
        Hs[off, off] = 1.0
        rhs[off] = 0.0
    _, _, y, info = lapack_dgesv()(Hs, rhs)                    # LAPACK's gesv: no stacked-solve wrapper for one point
    if info != 0:
        raise np.linalg.LinAlgError("singular H")
    K = y / s
    P_prev = F.T @ PF - rhs.T @ y
    return K, 0.5 * (P_prev + P_prev.T)


def augmented_solve(system: System, chains: tuple | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """The exact UDP-like minimiser under the system's chains (or ``chains``, as `chain_lift`) by the
    augmented Riccati recursion.

    Returns ``(U, gain, cost)``: the plan (N×m), the first step's gain on ``x`` (m×n) and the exact
    minimum, checked against `chain_cost` of the plan to ``SELF_CHECK_RTOL`` (plus
    ``SELF_CHECK_ATOL ||P_0|| ||x||^2``). Time O(N (D^3 + m^3)) with D = n (1 + sum_i (k_i - 1)), memory
    O(N m D) for the gains; where the steps from s on are one map (s: the step where the chains' distributions
    reach their float fixed point, 1 for chains started in their stationary distributions; a stable A whose
    Lyapunov sums closed) the value closes its stationary tail after L steps, the steps before s are taken one by
    one and the run of one gain is rolled out by powers of its closed loop: O((s + L) (D^3 + m^3) + N D^2) for the
    solve; the referee `chain_cost` is O(N n^2 (n + m + sum_i (k_i - 1))) array work, in about 2 sqrt(N) stacked
    steps where A is stable (`_blocked_chain_cost`).

    Raises
    ------
    BudgetError
        The recursion's estimated time is beyond the ``markov_recursion_work`` budget (checked before any work:
        `check_recursion_budget`; the message names the dense route when it fits the memory budget).
    NumericalError
        An overflow (an unstable plant over a long horizon), a singular step, or a failed self-check.
    """
    W, N, n, m = system.state_weights, system.horizon, system.n, system.m
    lift = chain_lift(system, chains)
    D = lift.size
    F = _dynamics(system, lift)
    mu = system.mu_schedule
    scale = np.sqrt(mu)
    d, noise, BSA = lyapunov_cross_weights(system)     # the backward Lyapunov sum S_t: diag(B'S_tB) and B'S_tA
    with np.errstate(over="ignore", invalid="ignore"):   # Lemma 1's UDP-like input weight, M (Psi + (I - M) D)
        R = np.where(mu > 0.0, mu * input_weight(system, "udp", mu, d), 0.0)
    K = np.empty((N, m, D))
    Gs = _input_maps(system, lift)
    P = np.zeros((D, D))
    P[:n, :n] = W[N - 1]
    # steps first..head are one map (the input maps, R, the cross terms and Omega equal to the bit: from the step
    # where the chains' distributions reached their float fixed point, first = 1 for chains started in it, below the
    # step where the Lyapunov sums closed): there the value closes its stationary tail as recursion._backward's does
    # (remaining drift under STATIONARY_RTOL), and the steps before first are taken one by one
    first = _steady_from(Gs, mu) if N >= 2 * STATIONARY_RUN else 1
    head = first - 1 + min(leading_run(Gs[None, first:]), leading_run(R[None, first:]),
                           leading_run(BSA[None, first:]), len(weight_head(system)) - first + 1) \
        if N >= 2 * STATIONARY_RUN and first < N - 1 else 0
    q, run = None, None
    with np.errstate(over="ignore", invalid="ignore"):
        try:
            t = N - 1
            while t >= 0:
                K[t], new = _augmented_step(P, F, Gs[t], R[t], BSA[t], lift, scale[t], W[t - 1] if t > 0 else None)
                if first + 1 <= t <= head and run is None:
                    if q is None and stationary_close(new, P, 0.01):      # near: the change below 99 STATIONARY_RTOL
                        q = float(np.max(np.abs(np.linalg.eigvals(F - Gs[t] @ K[t])))) ** 2
                    if q is not None and stationary_close(new, P, q):
                        # P_t = P_{t-1} = ... = P_first to rounding: its gain for steps first..t-1, then the steps
                        # before first one by one
                        a = first
                        K[a], new = _augmented_step(new, F, Gs[a], R[a], BSA[a], lift, scale[a], W[a - 1])
                        K[a + 1:t] = K[a]
                        run, t = (a, t), a
                P = new
                t -= 1
        except np.linalg.LinAlgError:
            raise overflow_error("the augmented cost-to-go matrix", "udp") from None
        if not (np.all(np.isfinite(P)) and np.all(np.isfinite(K)) and np.isfinite(noise)):
            raise overflow_error("the augmented cost-to-go matrix", "udp")
        x = system.x0
        U, Z = np.empty((N, m)), np.zeros((N + 1, D))
        Z[0, :n] = x
        t = 0
        while t < N:
            if run is not None and t == run[0]:     # the run of one gain by powers of its closed loop (stable: q < 1)
                states_by_powers(Z[None, t:run[1]], (F - Gs[t] @ K[t]).T)
                U[t:run[1]] = -Z[t:run[1]] @ K[t].T
                t = run[1] - 1
                Z[t + 1] = F @ Z[t] + Gs[t] @ U[t]
                t += 1
                continue
            U[t] = -K[t] @ Z[t]
            Z[t + 1] = F @ Z[t] + Gs[t] @ U[t]
            t += 1
        cost = float(x @ (system.initial_weight + P[:n, :n]) @ x) + noise
    forward = float(chain_cost(system, U[None], lift)[0])
    atol = SELF_CHECK_ATOL * float(np.linalg.norm(P[:n, :n], 2)) * float(x @ x)
    if not (np.isfinite(cost) and np.isfinite(forward)):
        raise overflow_error("the exact Markov cost", "udp")
    bound = mean_state_bound(system, U)
    if not bound <= PLAN_COST_RTOL * forward:
        raise NumericalError(f"the augmented recursion's referee, the expected cost of its own plan rolled out open "
                             f"loop ({forward:.6g}), is not resolved (rounding may move it by up to {bound:.2g}): the "
                             "open-loop growth of A over the horizon amplifies a fixed plan's rounding; shorten the "
                             "horizon")
    self_check(system, "udp", cost, forward, "markov-recursion", atol=atol)
    return U, K[0][:, :n].copy(), cost


def _steady_from(Gs: np.ndarray, mu: np.ndarray) -> int:
    """The first step s >= 1 from which the input maps ``Gs`` (N, D, m) and the channels ``mu`` (N, m) are the same
    floats at every later step (1 for chains started in their stationary distributions; N - 1 where they never stop
    changing). O(N D m)."""
    N = mu.shape[0]
    changed = np.any((Gs[1:] != Gs[:-1]).reshape(N - 1, -1), axis=1) | np.any(mu[1:] != mu[:-1], axis=1)
    last = np.flatnonzero(changed[1:])
    return int(last[-1]) + 2 if last.size else 1


def _augmented_step(P: np.ndarray, F: np.ndarray, G: np.ndarray, R: np.ndarray, BSA: np.ndarray, lift: ChainLift,
                    scale: np.ndarray, Omega: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """One step of `augmented_solve`'s backward pass: the cross term ``N`` (row i: b_i'S_t A ⊗ g_i, row-major
    eta_i) from ``BSA`` = B'S_t A, `lq_cross_step`, then the state weight ``Omega`` on the xhat block (None:
    step 0). Returns ``(K_t, P_t)``. O(D^3 + m^3)."""
    Ncross = np.zeros((G.shape[1], F.shape[0]))
    for i, gi in enumerate(lift.g):
        Ncross[i, lift.offsets[i]:lift.offsets[i + 1]] = np.outer(BSA[i], gi).ravel()
    K, P_prev = lq_cross_step(P, F, G, np.diag(R), Ncross, scale)
    if Omega is not None:
        n = Omega.shape[0]
        P_prev[:n, :n] += Omega
    return K, P_prev


def mean_state_bound(system: System, inputs: np.ndarray) -> float:
    """A bound on the rounding of `chain_cost`'s mean-state part for the plan ``inputs`` (N×m): the TCP-like
    forward pass of the paper's system on the chains' predicted mu_t without its noise term
    ([`plan_cost`][packetloss_cvx.lq.recursion.plan_cost]). The correlations and the error covariance are sums of
    nonnegative terms driven by the plan itself (no cancellation of an open-loop growth against the plan): only
    the mean states can carry the plan's rounding amplified by an unstable A. O(N n (n + m) L), L = 32.

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[0.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.2]))
    >>> round(float(chain_cost(s, np.ones((1, 2, 1)))[0]), 12), bool(mean_state_bound(s, np.ones((2, 1))) < 1e-14)
    (3.3, True)
    """
    N, m = system.horizon, system.m
    states = None
    if _blocked(system):                       # chain_cost's mean states: the same blocks, the same floats
        with np.errstate(over="ignore", invalid="ignore", under="ignore"):
            states = _mean_blocks(system, np.asarray(inputs, dtype=float)[None])[:, 0, :, 0]
    return plan_cost(system.with_mu(system.mu_schedule), inputs, "tcp", (np.zeros((N, m)), 0.0), states)[1]


def _blocked(system: System) -> bool:
    """Whether `chain_cost` takes `_blocked_chain_cost`: a stable A (rho(A) < 1) and one state weight. O(1) once the
    structure is kept."""
    structure = structure_of(system)
    return structure.open_loop_radius < 1.0 and structure.time_invariant_weight


def _mean_blocks(system: System, U: np.ndarray) -> np.ndarray:
    """The mean states x_1..x_N (N, points, n, 1) of plans U (points, N, m) from x0 by `_forward_blocks`
    (``x+ = A x + B M_t u_t``) in spans (`_span`). O(N points n (n + m))."""
    N, points = system.horizon, U.shape[0]
    moved = ((U.transpose(1, 0, 2) * system.mu_schedule[:, None, :]) @ system.B.T)[..., None]    # (N, points, n, 1)
    out = np.empty_like(moved)
    start = np.repeat(system.x0[None, :, None], points, axis=0)
    span = _span(points, system.n)
    for a in range(0, N, span):
        out[a:a + span] = _forward_blocks(system.A, np.ones((1, 1)), start, moved[a:a + span])
        start = out[min(N, a + span) - 1]
    return out


def chain_cost(system: System, inputs: np.ndarray, lift: ChainLift | None = None) -> np.ndarray:
    """The exact UDP-like expected cost of plans ``inputs`` (points, N, m) under the system's chains, by the
    forward pass of the mean state, the correlations eta and the error covariance Sigma (module docstring):

        x'Q x + sum_t mu_t psi_t u_t^2 + xhat_{t+1}'Omega_{t+1} xhat_{t+1} + tr(Omega_{t+1} Sigma_{t+1}),

    every term nonnegative (Sigma is a covariance): the referee of `augmented_solve`. Without a chain
    it is the paper's J_udp. Returns (points,). Time O(points N n^2 (n + m + sum_i (k_i - 1))), memory O(points n^2).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[0.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.2]))
    >>> # x = 0, U = (1, 1): E[v1^2] + E[(v1 + v2)^2] + E[v1] + E[v2] = 0.5 + (1 + 2 * 0.4) + 1 = 3.3
    >>> round(float(chain_cost(s, np.ones((1, 2, 1)))[0]), 12)
    3.3
    """
    lift = chain_lift(system) if lift is None else lift
    A, B, W, N, n, m = system.A, system.B, system.state_weights, system.horizon, system.n, system.m
    U = np.asarray(inputs, dtype=float)
    points = U.shape[0]
    mu = system.mu_schedule
    x = system.x0
    chained = [i for i in range(m) if lift.Lam[i].size]
    if _blocked(system):
        return _blocked_chain_cost(system, lift, U, chained)
    structure = structure_of(system)
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        # the mean state's part, sum mu psi u^2 + xhat'Omega xhat: the package's one forward kernel
        X = mean_states(structure, mu[None], U, np.repeat(x[None], points, axis=0))
        total = forward_cost(structure, mu[None], U, X, system.input_weights, float(x @ system.initial_weight @ x))
        var_u2 = mu * (1.0 - mu) * U * U                      # (points, N, m)
        eta = {i: np.zeros((points, n, lift.Lam[i].shape[0])) for i in chained}
        Sig = np.zeros((points, n, n))
        Y = np.zeros((points, n, m))                               # column i: E[e_t delta_{t,i}] u_{t,i}
        end = _plan_end(U)
        for t in range(end):
            u = U[:, t]
            for i in chained:
                Y[:, :, i] = (eta[i] @ lift.g[i]) * u[:, i, None]
                eta[i] = A @ eta[i] @ lift.Lam[i] + B[:, i][None, :, None] * (u[:, i, None, None]
                                                                               * lift.gamma[i][t][None, None, :])
            cross = A @ Y @ B.T
            Sig = A @ Sig @ A.T + cross + cross.transpose(0, 2, 1) + (B * var_u2[:, t, None, :]) @ B.T \
                + system.noise_cov
            total += np.einsum("ij,pji->p", W[t], Sig)
        if end < N:
            total += _free_tail(system, Sig, end)
    return total


#: `_blocked_chain_cost` and `_mean_blocks` take the steps in spans of at most this many entries per array (8 MiB),
#: carrying the state from one span to the next: memory bounded whatever N (each span in about 2 sqrt(span) stacked
#: steps).
CHAIN_SPAN_ENTRIES = 2**20


def _span(points: int, width: int) -> int:
    """The steps of one span: CHAIN_SPAN_ENTRIES over ``points width`` entries a step, at least STATIONARY_RUN. O(1)."""
    return max(STATIONARY_RUN, CHAIN_SPAN_ENTRIES // max(1, points * width))


def _blocked_chain_cost(system: System, lift: ChainLift, U: np.ndarray, chained: list[int]) -> np.ndarray:
    """`chain_cost` where A is stable (rho(A) < 1) and the state weight is one weight: the same forward recursions
    of the mean state, the correlations eta and the error covariance Sigma, each of them ``X+ = L X R + C_t`` with
    constant L and R, run over the steps up to the plan's end (`_plan_end`) by `_forward_blocks` (about 2 sqrt(end)
    stacked steps instead of end, in spans of CHAIN_SPAN_ENTRIES), every stage term still computed and nonnegative;
    after the plan's end the second moment ``xhat xhat' + Sigma`` is free (``Pi+ = A Pi A' + Sigma_W``) and its
    remaining stage terms are the Stein sums of `_free_sums`. Agrees with the step-by-step pass to rounding (the
    powers of a stable A): within 1.9e-13 relative on benchmarks/markov_tail.py's examples, each of the two within
    1.0e-13 of an 80-bit loop. Time O(end points n^2 (n + sum_i q_i) + N points n^2 + sqrt(N) n^3 + n^3 log(N - end))
    for a plan ending at step ``end`` (the mean states over all N, as `mean_state_bound` bounds them); memory
    O(N points n) for the mean states and O(CHAIN_SPAN_ENTRIES) for the rest."""
    A, B, N, n, m = system.A, system.B, system.horizon, system.n, system.m
    W = system.state_weights[0]
    points = U.shape[0]
    mu = system.mu_schedule
    x = system.x0
    end = _plan_end(U)
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        total = np.full(points, float(x @ system.initial_weight @ x))
        last = np.repeat(x[None], points, axis=0)                          # x_end (points, n)
        Sig = np.zeros((points, n, n))
        if end:
            states = _mean_blocks(system, U)[:end, :, :, 0]            # x_1 .. x_end (end, points, n)
            u = U[:, :end].transpose(1, 0, 2)                         # (end, points, m)
            total += np.einsum("tpk,tpk->p", (mu[:end, None, :] * u), system.input_weights[:end, None, :] * u)
            total += np.einsum("tpj,jk,tpk->p", states, W, states)
            last = states[-1]
            eta = {i: np.zeros((points, n, lift.Lam[i].shape[0])) for i in chained}
            var = (mu * (1.0 - mu))[:end, None, :] * u * u                # (end, points, m)
            span = _span(points, n * (n + m + lift.size // n))
            for a in range(0, end, span):
                b = min(end, a + span)
                Y = np.zeros((b - a, points, n, m))                        # column i: E[e_t delta_{t,i}] u_{t,i}
                for i in chained:
                    ui = u[a:b, :, i, None, None]
                    drive = B[None, None, :, i, None] * (ui * lift.gamma[i][a:b, None, None, :])
                    later = _forward_blocks(A, lift.Lam[i], eta[i], drive)         # eta_{a+1} .. eta_b
                    Y[:, :, :, i] = (np.concatenate([eta[i][None], later[:-1]]) @ lift.g[i]) * ui[..., 0]
                    eta[i] = later[-1]
                cross = A @ Y @ B.T
                drive = cross + cross.transpose(0, 1, 3, 2) + (B * var[a:b, :, None, :]) @ B.T + system.noise_cov
                later = _forward_blocks(A, A.T, Sig, drive)                      # Sigma_{a+1} .. Sigma_b
                total += np.einsum("ij,tpji->p", W, later)
                Sig = later[-1]
        if end < N:
            total += _free_sums(A, W, system.noise_cov, Sig + last[:, :, None] * last[:, None, :], N - end)
    return total


def _forward_blocks(L: np.ndarray, R: np.ndarray, X0: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``X_{k+1} = L X_k R + C_k`` for k = 0..steps-1 from X0 (points, a, b), C (steps, points, a, b): returns
    X_1..X_steps (steps, points, a, b). In blocks of c = ceil(sqrt(steps)) steps: the particular solutions of every
    block at once (c stacked steps, each as the step-by-step pass takes it), the block starts one after another
    (steps / c steps by the c-th powers), then every state as ``L^j X_start R^j`` plus its block's particular
    solution. For a stable map (the powers do not grow) this agrees with the step-by-step pass to rounding.
    O(steps points a b (a + b) + sqrt(steps) (a^3 + b^3)), about 2 sqrt(steps) stacked steps."""
    steps, points, a, b = C.shape
    c = max(1, math.isqrt(steps - 1) + 1) if steps else 1
    blocks = -(-steps // c)
    S = blocks * points                                            # the blocks' states side by side: a×(S b) products
    Cb = np.zeros((blocks * c, points, a, b))
    Cb[:steps] = C
    Cb = Cb.reshape(blocks, c, points, a, b).transpose(1, 3, 0, 2, 4).reshape(c, a, S * b)
    Ys = np.empty((c, a, S * b))                              # Ys[j]: the particular solutions j + 1 steps in
    y = np.zeros((a, S * b))
    Lp, Rp = np.empty((c, a, a)), np.empty((c, b, b))           # L^(j + 1), R^(j + 1)
    Lk, Rk = L, R
    for j in range(c):
        y = ((L @ y).reshape(a * S, b) @ R).reshape(a, S * b) + Cb[j]
        Ys[j] = y
        Lp[j], Rp[j] = Lk, Rk
        Lk, Rk = L @ Lk, Rk @ R
    last = Ys[-1].reshape(a, blocks, points, b)
    starts = np.empty((a, blocks, points, b))
    start = X0
    for k in range(blocks):
        starts[:, k] = start.transpose(1, 0, 2)
        start = Lp[-1] @ start @ Rp[-1] + last[:, k].transpose(1, 0, 2)
    out = ((Lp.reshape(c * a, a) @ starts.reshape(a, S * b)).reshape(c, a * S, b) @ Rp).reshape(c, a, S * b) + Ys
    return out.reshape(c, a, blocks, points, b).transpose(2, 0, 3, 1, 4).reshape(blocks * c, points, a, b)[:steps]


def _free_sums(A: np.ndarray, W: np.ndarray, noise_cov: np.ndarray, Pi: np.ndarray, L: int) -> np.ndarray:
    """``sum_{k=1}^{L} tr(W Pi_k)`` for the free second moment ``Pi_{k+1} = A Pi_k A' + Sigma_W`` from Pi_0 = ``Pi``
    (points, n, n): ``tr(A'S_L A Pi) + tr(T_L Sigma_W)`` with the Stein sums ``S_L = sum_{j<L} E_j`` and
    ``T_L = sum_{j<L} (L - j) E_j`` of ``E_j = A'^j W A^j``, by doubling over the binary digits of L
    (``S_{k+l} = S_k + A'^k S_l A^k``, ``T_{k+l} = T_k + l S_k + A'^k T_l A^k``): sums of positive semidefinite terms
    with nonnegative coefficients, no cancellation. O(n^3 log L). Returns (points,)."""
    n = A.shape[0]
    power, S, Tsum, k = A, W, W, 1                           # the block of k = 2^i steps: A^k, S_k, T_k
    accA, accS, accT, acc = np.eye(n), np.zeros((n, n)), np.zeros((n, n)), 0
    rest = L
    while rest:
        if rest & 1:                                             # append the block of k steps after the acc ones
            accT = accT + k * accS + accA.T @ Tsum @ accA
            accS = accS + accA.T @ S @ accA
            accA, acc = power @ accA, acc + k
        rest >>= 1
        if rest:
            Tsum = Tsum + k * S + power.T @ Tsum @ power
            S = S + power.T @ S @ power
            power, k = power @ power, 2 * k
    G = A.T @ accS @ A
    return np.einsum("ij,pji->p", G, Pi) + float(np.sum(accT * noise_cov))


def _plan_end(U: np.ndarray) -> int:
    """One past the last step at which some plan of ``U`` (points, N, m) has a nonzero input (0 for all-zero plans):
    from there on the correlations no longer enter the error covariance. O(points N m)."""
    moving = np.flatnonzero(np.any(U != 0.0, axis=(0, 2)))
    return int(moving[-1]) + 1 if moving.size else 0


def _free_tail(system: System, Sig: np.ndarray, start: int) -> np.ndarray:
    """``sum_{t >= start} tr(Omega_{t+1} Sigma_{t+1})`` once every plan has ended (`_plan_end`): the cross
    terms and the loss variance of the input are exact zeros, so the error covariance is the free Lyapunov recursion
    ``Sigma+ = A Sigma A' + Sigma_W`` from ``Sig`` (points, n, n) = Sigma_start, the same floats as `chain_cost`'s
    full step, step by step (an unstable A or a time-varying weight: a stable A with one weight takes
    `_blocked_chain_cost`'s Stein sums). O((N - start) n^3). Returns (points,)."""
    A, W, N, noise_cov = system.A, system.state_weights, system.horizon, system.noise_cov
    total = np.zeros(Sig.shape[0])
    for t in range(start, N):
        Sig = A @ Sig @ A.T + noise_cov
        total += np.einsum("ij,pji->p", W[t], Sig)
    return total
