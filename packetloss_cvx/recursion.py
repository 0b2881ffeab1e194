"""The exact O(N) backward recursion for both protocols (DESIGN.md §2).

Both expected costs are deterministic LQ problems in the mean state

.. math:: \\hat x_{t+1} = A \\hat x_t + B M_t u_t,

with stage input weight ``M_t Psi_t`` and, for the UDP-like protocol, the extra
diagonal weight ``diag(Omega_g)_t M_t (I - M_t)``, where ``diag(Omega_g)_t =
diag(B' S_t B)`` and ``S_t = sum_{s>t} (A^{s-t-1})' Omega_s A^{s-t-1}`` is a
backward Lyapunov sum. The Hessian of stage t factors as ``M_t G_t`` with

.. math:: G_t = \\Psi_t + D_t + B' P_{t+1} B M_t, \\qquad D_t = \\mathrm{diag}(B'S_tB)(I - M_t)
   \\ (\\text{UDP}),\\ 0\\ (\\text{TCP}),

which is invertible even when some mu = 0; ``u_t = -G_t^{-1} B' P_{t+1} A \\hat x_t`` is then
the same minimiser as the paper's dense law ``-G^{-1} Omega_gp x`` (Theorem 1).

Time O(N (n^3 + m^3)), memory O(N n m) for the gains; no (N n)×(N m) matrix is formed.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dgesv as _gesv

from .linalg import check_finite
from .model import STRUCTURE_CACHE_MAX_BYTES, CacheKey, System
from .protocols import check_protocol

#: the cached structure of a system (System.structure_cached): each key says the fields its value depends on
VARIANCE_WEIGHTS_KEY = CacheKey("recursion.udp_variance_weights", ("A", "B", "horizon", "state_weights", "noise_cov"))
CONDITION_KEY = CacheKey("recursion.condition_estimate", ("A", "B", "horizon", "state_weights", "input_weights"))

__all__ = ["backward_pass", "condition_estimate", "mean_trajectory", "recursion_cost", "udp_variance_weights"]


def _finite(name: str, value: np.ndarray | float, protocol: str) -> None:
    check_finite(name, value, why=f"the exact {protocol}-like expected cost exceeds the double-precision range, "
                 "1e308: the open-loop prediction of an unstable plant over this horizon",
                 advice="shorten the horizon or stabilise the plant")


def udp_variance_weights(system: System) -> tuple[np.ndarray, float]:
    """The diagonal of Omega_g per step and the noise term tr(Omega_l Sigma_W).

    Omega_d (I - Vbar) is the loss-variance term of the UDP-like law, eq:opt-law-2.

    Returns ``(d, noise)`` with ``d[t, i] = (B' S_t B)_{ii}`` and
    ``noise = sum_t tr(S_t Sigma_W)``. Time O(N n^3), memory O(N m), the first time for a system
    structure: ``d`` (read-only) is kept on the system and its with_mu / with_x0 copies
    (:meth:`~packetloss_cvx.model.System.structure_cached`; it depends on neither mu nor x0).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> d, noise = udp_variance_weights(s)         # S_1 = 1, S_0 = 1 + A' S_1 A = 5
    >>> d.ravel().tolist(), noise
    ([5.0, 1.0], 0.0)
    >>> from packetloss_cvx.prediction import prediction
    >>> bool(np.allclose(d.ravel(), prediction(s).Omega_d))    # the dense diagonal of Omega_g
    True
    """
    return system.structure_cached(VARIANCE_WEIGHTS_KEY, lambda: _lyapunov_weights(system),
                                   nbytes=8 * system.horizon * system.m)


def _lyapunov_weights(system: System) -> tuple[np.ndarray, float]:
    """udp_variance_weights, computed: the backward Lyapunov sum S_t, O(N n^3)."""
    A, B, W, N = system.A, system.B, system.state_weights, system.horizon
    d = np.empty((N, system.m))
    noise = 0.0
    has_noise = bool(np.any(system.noise_cov != 0))
    S = W[N - 1].copy()
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(N - 1, -1, -1):
            d[t] = np.einsum("ij,ik,kj->j", B, S, B)
            if has_noise:
                noise += float(np.sum(S * system.noise_cov))
            if t > 0:
                S = W[t - 1] + A.T @ S @ A
    d.setflags(write=False)
    return d, noise


def condition_estimate(system: System, weights: tuple[np.ndarray, float] | None = None) -> float:
    """``(trace Omega_g + max Psi) / min Psi``: an upper estimate of the spread of curvatures of
    both expected costs (trace Omega_g bounds its largest eigenvalue, min Psi bounds the smallest
    curvature per delivered input). The dense formulas lose about ``log10(estimate * eps)``
    digits; the recursion does not depend on it. ``inf`` when Omega_g overflows.
    Time O(N n^3) (the Lyapunov sums of :func:`udp_variance_weights`), no dense matrix; O(1) once kept
    on the system structure (with ``weights`` None or the system's own).

    Examples
    --------
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> condition_estimate(s)                      # (trace Omega_g + max Psi) / min Psi = (5 + 1 + 1) / 1
    7.0
    """
    kept = 8 * system.horizon * system.m <= STRUCTURE_CACHE_MAX_BYTES    # udp_variance_weights keeps d
    if weights is None or (kept and weights is udp_variance_weights(system)):   # the system's own weights
        return system.structure_cached(CONDITION_KEY,
                                       lambda: _spread(system, udp_variance_weights(system)[0]))
    return _spread(system, weights[0])


def _spread(system: System, d: np.ndarray) -> float:
    psi = system.input_weights
    with np.errstate(over="ignore", invalid="ignore"):
        total = float(np.sum(d))
    if not np.isfinite(total):
        return float("inf")
    return (total + float(psi.max())) / float(psi.min())


def backward_pass(system: System, protocol: str,
                  weights: tuple[np.ndarray, float] | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Riccati recursion of the mean-state LQ problem: the laws of Theorem 1 (eq:control-laws), step by step.

    Returns ``(K, P0, noise)``: the gains ``K[t]`` (m×n, ``u_t = -K[t] xhat_t``),
    the cost-to-go matrix at step 0 (without Q) and the noise term. The Lyapunov sum
    S_t (UDP-like weights, noise) runs in the same backward loop, unless ``weights`` (the
    result of :func:`udp_variance_weights`, already computed by the caller) supplies it.
    Time O(N (n^3 + m^3)), memory O(N m n).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> K, P0, noise = backward_pass(s, "udp")
    >>> # J_udp(u) = 0.5 (1 + u)^2 + 0.5 + 0.5 u^2 is least at u = -1/2, where it is 0.75
    >>> float(K[0, 0, 0]), float(P0[0, 0]), noise
    (0.5, 0.75, 0.0)
    """
    protocol = check_protocol(protocol)
    A, B, W, N = system.A, system.B, system.state_weights, system.horizon
    m = system.m
    mu, psi = system.mu_schedule, system.input_weights
    udp = protocol == "udp"
    has_noise = bool(np.any(system.noise_cov != 0))
    track_S = (udp or has_noise) and weights is None   # given the Lyapunov sums, do not redo them
    keep = np.where(mu < 1.0, 1.0 - mu, 0.0)  # (1 - mu) on lossy channels, 0 on perfect ones
    D = np.zeros((N, m))                      # diag(Omega_g) per step (UDP-like)
    K = np.empty((N, m, system.n))
    P = W[N - 1].copy()
    S = W[N - 1].copy()
    noise = 0.0
    if weights is not None:
        D, noise = weights[0], weights[1]
    diag = np.arange(m) * (m + 1)
    AT = A.T
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(N - 1, -1, -1):
            PB = P @ B
            G = (B.T @ PB) * mu[t]
            G.flat[diag] += psi[t]
            if weights is not None and udp:
                G.flat[diag] += D[t] * keep[t]
            if track_S:
                if udp:
                    D[t] = ((S @ B) * B).sum(axis=0)
                    G.flat[diag] += D[t] * keep[t]
                if has_noise:
                    noise += float(np.sum(S * system.noise_cov))
                if t > 0:
                    S = W[t - 1] + AT @ S @ A
            rhs = PB.T @ A                    # B' P A (P is symmetric)
            _, _, K[t], info = _gesv(G, rhs)
            if info != 0:
                _finite("the cost-to-go matrix", np.array(np.nan), protocol)
            P = AT @ (P @ A) - (rhs.T * mu[t]) @ K[t]
            if t > 0:
                P += W[t - 1]
            P = 0.5 * (P + P.T)
    if udp:
        _finite("diag(Omega_g)", D[mu < 1.0], protocol)
    _finite("the noise term tr(Omega_l Sigma_W)", noise, protocol)
    _finite("the cost-to-go matrix", P, protocol)
    _finite("the gains", K, protocol)
    return K, P, noise


def mean_trajectory(system: System, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Roll out ``u_t = -K[t] xhat_t``: returns inputs (N×m) and mean states (N+1×n).

    The mean states are the expected trajectory of eq:pred-err, Xhat = Phi x + Gamma Vbar U, step by step.
    Time O(N n (n + m)).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> u, x = mean_trajectory(s, np.array([[[0.5]]]))     # u_0 = -0.5, xhat_1 = 1 + 0.5 (-0.5)
    >>> u.tolist(), x.ravel().tolist()
    ([[-0.5]], [1.0, 0.75])
    """
    A, B, mu = system.A, system.B, system.mu_schedule
    N = system.horizon
    x = np.empty((N + 1, system.n))
    u = np.empty((N, system.m))
    x[0] = system.x0
    with np.errstate(over="ignore", invalid="ignore"):   # callers check finiteness
        for t in range(N):
            u[t] = -K[t] @ x[t]
            x[t + 1] = A @ x[t] + B @ (mu[t] * u[t])
    return u, x


def recursion_cost(system: System, inputs: np.ndarray, protocol: str,
                   weights: tuple[np.ndarray, float] | None = None) -> float:
    """J(U) of eq:opt-lqg-simplest with Lemma 1, by a forward pass of the mean state.

    Every term added is nonnegative (stage costs of the mean state, the input and loss-variance
    weights, the noise term), so the sum has no cancellation: this is the referee the closed
    forms check their costs against. ``weights`` reuses ``udp_variance_weights(system)``.
    Time O(N n^3) (the Lyapunov sums), memory O(N m).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> # J_tcp = xhat_1^2 + mu psi u^2 = 0.5625 + 0.125; J_udp adds mu (1 - mu) (B'S B) u^2 = 0.0625
    >>> recursion_cost(s, np.array([[-0.5]]), "tcp"), recursion_cost(s, np.array([[-0.5]]), "udp")
    (0.6875, 0.75)
    """
    protocol = check_protocol(protocol)
    A, B, W, mu, psi = system.A, system.B, system.state_weights, system.mu_schedule, system.input_weights
    d, noise = udp_variance_weights(system) if weights is None else weights
    x = system.x0.copy()
    total = float(x @ system.initial_weight @ x) + noise
    with np.errstate(over="ignore", invalid="ignore"):
        # the per-step input terms for all steps at once (the same products and per-step sums as step by step)
        mean = mu * inputs                      # the mean applied input: products in this order stay
        stage = np.sum(mean * (psi * inputs), axis=1)          # in range when mu is tiny and u huge
        extra = np.zeros(system.horizon)
        if protocol == "udp":
            lossy = mu < 1.0
            variance = mean * ((1.0 - mu) * d * inputs)
            extra = np.sum(variance, axis=1) if lossy.all() else [
                np.sum(v[k]) for v, k in zip(variance, lossy, strict=True)]
        for t in range(system.horizon):
            total += float(stage[t])
            if protocol == "udp":
                total += float(extra[t])
            x = A @ x + B @ mean[t]
            total += float(x @ W[t] @ x)
    return total
