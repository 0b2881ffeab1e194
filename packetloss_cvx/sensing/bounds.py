"""Bounds on the TCP-like filter's expected error covariance and on the critical arrival rate
(Sinopoli et al., "Kalman filtering with intermittent observations", IEEE TAC 49(9), 2004, Theorems 3-5,
generalised here to g independent sensor channels by summing over the ``2^g`` arrival patterns).

With ``P^-`` the predicted covariance, ``q = prod_j (1 - gamma_j)`` the probability that every channel is lost and
``U_a(V) = V - V C_a' (C_a V C_a' + R_a)^+ C_a V`` the update with the rows of pattern a:

* **Lower bound.** ``P_k >= 0`` always and ``P_k = P^-_k`` when every channel is lost (probability q, independent
  of ``P^-_k``), so ``E[P^-_{k+1}] >= q A E[P^-_k] A' + Sigma_W``: ``E[P^-] >= S``, ``S = q A S A' + Sigma_W``
  (the series ``sum_k q^k A^k Sigma_W A'^k``; infinite when it diverges, e.g. ``q rho(A)^2 >= 1`` with the noise
  exciting the unstable mode).
* **Upper bound.** The modified algebraic Riccati map ``g(V) = A (sum_a p_a U_a(V)) A' + Sigma_W`` is concave and
  monotone in V (each ``U_a`` is), so Jensen gives ``E[P^-_{k+1}] = E[g_a(P^-_k)] <= g(E[P^-_k])`` and by
  induction ``E[P^-_k] <= V_k``, ``V_{k+1} = g(V_k)``, ``V_0 = P0``: the stationary ``V = g(V)`` bounds the limit.
* **Critical arrival rate** along ``gamma = t d``: below ``t_low``, where ``q(t) rho(A)^2 = 1``, E[P] diverges
  for some P0 (single channel: ``1 - 1/rho(A)^2``, Sinopoli's Theorem 3); above ``t_up``, the least t with an X
  satisfying ``X > g(X)`` (checked in numpy), every V_k is bounded (Sinopoli's Lemma: such an X bounds the
  iteration from any P0). ``t_up`` is the same set that Sinopoli's LMI decides ([`.lmi`][packetloss_cvx.sensing.lmi],
  the cross-check). Exact (``t_low = t_up``) for one channel with C invertible (Sinopoli et al. 2004) and, for several
  channels, when every channel's rows alone have rank n (each arrival resets ``P <= C_j^+ R_j C_j^+'``-like: every
  pattern but "all lost" is one-step observable, and the lower bound's argument is then tight).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..errors import CrossCheckError, InputError, NumericalError
from ..model.sensor import Sensor
from ..results.sensing import CovarianceBounds, CriticalGamma
from .arrivals import arrival_patterns
from .kalman import RowUpdate, pattern_rows, predict

__all__ = ["DIVERGENCE_MARGIN", "covariance_bounds", "critical_gamma", "expected_riccati_map", "lower_bound_covariance",
           "lower_bound_diverges", "riccati_map", "stable_certificate", "upper_bound_covariance"]

#: The value iteration of the upper bound stops when an update changes V by less than this (relative).
MARE_RTOL = 1e-12
#: ... and gives up after this many steps, or when ||V|| exceeds MARE_DIVERGENCE times the noise scale.
MARE_MAX_ITER = 20_000
#: A certificate is looked for in at most this many steps: near the critical rate the iteration slows down
#: without bound, and a point left uncertified only loosens the upper bound (never makes it wrong).
CERTIFICATE_MAX_ITER = 2_000
MARE_DIVERGENCE = 1e12


def riccati_map(A: np.ndarray, Sigma_W: np.ndarray, sensor: Sensor,
                gamma: np.ndarray | None = None) -> Callable[[np.ndarray], np.ndarray]:
    """``V -> g(V) = A (sum_a p_a U_a(V)) A' + Sigma_W`` (module docstring), the arrival patterns and their
    rows selected once (`.kalman.RowUpdate`): the expected filter step, the update averaged
    over the patterns. Time O(2^g (n^3 + p^3)) per call."""
    arrived, prob = arrival_patterns(sensor.gamma if gamma is None else np.asarray(gamma, dtype=float))
    terms = [(float(pk), RowUpdate(sensor.C, sensor.noise_cov, pattern_rows(sensor, a)))
             for a, pk in zip(arrived, prob, strict=True) if pk > 0.0]

    def apply(V: np.ndarray) -> np.ndarray:
        V = np.asarray(V, dtype=float)
        return predict(sum(pk * update.covariance(V) for pk, update in terms), A, Sigma_W)

    return apply


def expected_riccati_map(V: np.ndarray, A: np.ndarray, Sigma_W: np.ndarray, sensor: Sensor,
                         gamma: np.ndarray | None = None) -> np.ndarray:
    """``g(V)`` once ([`riccati_map`][packetloss_cvx.sensing.bounds.riccati_map]). Time O(2^g (n^3 + p^3)).

    >>> s = Sensor(C=[[1.0]], gamma=[0.5], noise_cov=[[1.0]])
    >>> float(expected_riccati_map(np.array([[1.0]]), np.array([[2.0]]), np.array([[1.0]]), s)[0, 0])
    4.0
    """
    return riccati_map(A, Sigma_W, sensor, gamma)(V)


def lower_bound_covariance(A: np.ndarray, Sigma_W: np.ndarray, q: float) -> np.ndarray | None:
    """``S = sum_k q^k A^k Sigma_W A'^k`` (``S = q A S A' + Sigma_W``), or None when the series diverges.
    Lyapunov solve when ``q rho(A)^2 < 1``; otherwise doubling ``S <- S + q^j A^j S A'^j`` (the noise may
    leave the unstable modes unexcited). Time O(n^3) per doubling, at most 64.

    >>> round(float(lower_bound_covariance(np.array([[2.0]]), np.array([[1.0]]), 0.2)[0, 0]), 12)   # 1/(1 - 0.8)
    5.0
    >>> lower_bound_covariance(np.array([[2.0]]), np.array([[1.0]]), 0.25) is None
    True
    """
    rho = float(np.max(np.abs(np.linalg.eigvals(A))))
    if q * rho * rho < 1.0 - 1e-12:
        from scipy.linalg import solve_discrete_lyapunov  # optional.LAZY_IMPORTS

        S = solve_discrete_lyapunov(np.sqrt(q) * A, Sigma_W)
        return 0.5 * (S + S.T)
    S, F = np.array(Sigma_W, dtype=float), np.sqrt(q) * A
    scale = max(float(np.linalg.norm(Sigma_W)), np.finfo(float).tiny)
    for _ in range(64):
        term = F @ S @ F.T
        S, F = S + term, F @ F
        size = float(np.linalg.norm(term))
        if size <= 1e-15 * float(np.linalg.norm(S)) or not np.isfinite(size):
            break
        if size > MARE_DIVERGENCE * scale:
            return None
    if float(np.linalg.norm(Sigma_W)) == 0.0:
        return np.zeros_like(S)
    if not np.all(np.isfinite(S)) or float(np.linalg.norm(term)) > 1e-12 * float(np.linalg.norm(S)):
        return None          # grows polynomially (a Jordan block on the critical circle): unbounded
    return 0.5 * (S + S.T)


#: A divergence verdict is proved at ``q (1 - DIVERGENCE_MARGIN)``: the lower bound rises with q, so a series that
#: diverges there diverges at q, and a q rho(A)^2 within rounding of 1 is left undecided rather than guessed.
DIVERGENCE_MARGIN = 1e-9


def lower_bound_diverges(A: np.ndarray, Sigma_W: np.ndarray, P0: np.ndarray, q: float) -> bool:
    """Whether ``E[P^-_k] >= q^k A^k P0 A'^k + sum_{i<k} q^i A^i Sigma_W A'^i`` (P >= 0, and P = P^- with the
    all-lost probability q, independent of the past) is proved unbounded in k: at ``q' = q (1 -
    DIVERGENCE_MARGIN)`` the noise series diverges (then it does at q), or the series of the P0 terms does (then
    ``q' rho^2 >= 1`` on the modes P0 excites, so at q those terms grow by ``1 / (1 - DIVERGENCE_MARGIN)`` or more a
    step). [`lower_bound_covariance`][packetloss_cvx.sensing.bounds.lower_bound_covariance] twice: O(n^3) per doubling.

    >>> lower_bound_diverges(np.array([[2.0]]), np.zeros((1, 1)), np.ones((1, 1)), 0.5)   # 0.5^k 4^k P0 = 2^k
    True
    >>> lower_bound_diverges(np.array([[2.0]]), np.zeros((1, 1)), np.zeros((1, 1)), 0.5)  # nothing to grow
    False
    >>> lower_bound_diverges(np.array([[2.0]]), np.ones((1, 1)), np.zeros((1, 1)), 0.25)  # q a^2 = 1: undecided
    False
    """
    q = q * (1.0 - DIVERGENCE_MARGIN)
    return (lower_bound_covariance(A, Sigma_W, q) is None
            or lower_bound_covariance(A, np.asarray(P0, dtype=float), q) is None)


def _frobenius(X: np.ndarray) -> float:
    """``np.linalg.norm(X)`` of a float array by the operations it applies (the flattened array's dot with itself,
    its square root: the same float) without its generic argument handling, which was a fifth of a step of
    `_iterate` at n = 2-4. O(size).

    >>> X = np.random.default_rng(0).normal(size=(50, 4, 4)) * 1e3
    >>> all(_frobenius(x) == float(np.linalg.norm(x)) for x in (*X, X, X[:, :2].swapaxes(1, 2)))
    True
    """
    flat = X.ravel(order="K")
    return math.sqrt(flat.dot(flat))


def _iterate(V: np.ndarray, A: np.ndarray, Q: np.ndarray, sensor: Sensor,
             gamma: np.ndarray, steps: int = MARE_MAX_ITER) -> np.ndarray | None:
    """The fixed point of ``V <- g(V)`` with noise Q from V, or None when it diverges or does not settle."""
    scale = max(float(np.linalg.norm(Q)), float(np.linalg.norm(V)), np.finfo(float).tiny)
    step = riccati_map(A, Q, sensor, gamma)
    tiny = np.finfo(float).tiny
    for _ in range(steps):
        new = step(V)
        size = _frobenius(new)
        if not math.isfinite(size) or size > MARE_DIVERGENCE * scale:
            return None
        if _frobenius(new - V) <= MARE_RTOL * max(size, tiny):
            return new
        V = new
    return None


def upper_bound_covariance(A: np.ndarray, Sigma_W: np.ndarray, sensor: Sensor,
                           gamma: np.ndarray | None = None) -> np.ndarray | None:
    """The stationary ``V = g(V)`` reached from ``V_0 = P0`` (an upper bound on the limit of E[P^-]), or None
    when the iteration diverges (no bound: not a proof that E[P] diverges). Residual checked.
    Time O(iterations 2^g (n^3 + p^3)).

    >>> s = Sensor(C=[[1.0]], gamma=[1.0], noise_cov=[[1.0]])   # gamma = 1: the filter DARE V = V/(V+1) + 1
    >>> V = upper_bound_covariance(np.array([[1.0]]), np.array([[1.0]]), s)
    >>> bool(np.isclose(V[0, 0], (1 + 5 ** 0.5) / 2))
    True
    """
    gamma_ = sensor.gamma if gamma is None else np.asarray(gamma, dtype=float)
    if lower_bound_covariance(A, Sigma_W, float(np.prod(1.0 - gamma_))) is None:
        return None                  # E[P-] >= the diverging lower bound: no upper bound (and no slow divergence)
    V = _iterate(np.array(sensor.P0, dtype=float), A, Sigma_W, sensor, gamma_)
    if V is None:
        return None
    residual = float(np.linalg.norm(V - expected_riccati_map(V, A, Sigma_W, sensor, gamma_)))
    if residual > 1e-9 * max(float(np.linalg.norm(V)), 1.0):
        raise NumericalError(f"modified Riccati upper bound: residual {residual:.1e} after convergence")
    return V


def stable_certificate(A: np.ndarray, sensor: Sensor, gamma: np.ndarray) -> np.ndarray | None:
    """An X with ``X - g(X) > 0`` (least eigenvalue checked in numpy), ``g`` with the noise ``I``: such an X
    bounds the expected Riccati iteration for every P0 and every noise (Sinopoli's Lemma), so the expected
    error covariance is bounded at ``gamma``. Found along ``X_{k+1} = g(X_k) + I`` from 0 (increasing): then
    ``X_k - g(X_k) = I - (X_{k+1} - X_k)``, positive once a step moves X by less than I. None when no step within
    CERTIFICATE_MAX_ITER does (near the critical rate, or beyond it). Time O(CERTIFICATE_MAX_ITER 2^g (n^3 + p^3)).

    >>> X = stable_certificate(np.array([[2.0]]), Sensor(C=[[1.0]], gamma=[0.8], noise_cov=[[1.0]]), np.array([0.8]))
    >>> X is not None and float(X[0, 0] - expected_riccati_map(X, np.array([[2.0]]), np.eye(1),
    ...     Sensor(C=[[1.0]], gamma=[0.8], noise_cov=[[1.0]]))[0, 0]) > 0
    True
    """
    n = A.shape[0]
    eye = np.eye(n)
    X = np.zeros((n, n))
    step = riccati_map(A, 2.0 * eye, sensor, gamma)
    for _ in range(CERTIFICATE_MAX_ITER):
        new = step(X)                                                      # g(X) + I
        size = float(np.linalg.norm(new))                                  # inf or nan where an entry is
        if not math.isfinite(size) or size > MARE_DIVERGENCE * n:
            return None
        gap = X - (new - eye)                                              # X - g(X)
        if float(np.linalg.eigvalsh(0.5 * (gap + gap.T))[0]) > 0.0:
            check = X - expected_riccati_map(X, A, eye, sensor, gamma)     # the certificate, evaluated afresh
            if float(np.linalg.eigvalsh(0.5 * (check + check.T))[0]) > 0.0:
                return X
        X = new
    return None


def covariance_bounds(A: np.ndarray, Sigma_W: np.ndarray, sensor: Sensor) -> CovarianceBounds:
    """The lower and upper bounds of the module docstring at the sensor's gamma; the two must be ordered
    (``upper - lower`` PSD to rounding), else CrossCheckError. Time as
    [`upper_bound_covariance`][packetloss_cvx.sensing.bounds.upper_bound_covariance].

    >>> s = Sensor(C=[[1.0]], gamma=[0.5], noise_cov=[[0.0]])   # R = 0: lower = upper = 1 / (1 - 0.5 * 1.21)
    >>> b = covariance_bounds(np.array([[1.1]]), np.array([[1.0]]), s)
    >>> round(b.trace_lower, 9), round(b.trace_upper, 9)
    (2.53164557, 2.53164557)
    """
    q = float(np.prod(1.0 - sensor.gamma))
    lower = lower_bound_covariance(A, Sigma_W, q)
    upper = upper_bound_covariance(A, Sigma_W, sensor)
    if lower is None and upper is not None:
        raise CrossCheckError("expected error covariance: the lower bound diverges where the upper bound is finite",
                              {"lower": float("inf"), "upper": float(np.trace(upper))})
    if lower is not None and upper is not None:
        least = float(np.linalg.eigvalsh(upper - lower)[0])
        if least < -1e-8 * max(float(np.linalg.norm(upper)), 1.0):
            raise CrossCheckError("expected error covariance: the upper bound lies below the lower bound",
                                  {"lower": float(np.trace(lower)), "upper": float(np.trace(upper))})
    return CovarianceBounds(lower, upper)


def _all_lost(t: float, d: np.ndarray) -> float:
    return float(np.prod(1.0 - t * d))


def critical_gamma(A: np.ndarray, sensor: Sensor, direction: np.ndarray | None = None,
                   tol: float = 1e-5) -> CriticalGamma:
    """Bounds on the critical arrival rate along ``gamma = t d`` (default d = 1: every channel at the same
    rate): ``lower`` solves ``q(t) rho(A)^2 = 1`` (bisection; ``1 - 1/rho(A)^2`` for one channel), ``upper`` the
    least t with a `stable_certificate` (bisection on certified points: the certified set is upward
    closed, ``g`` falling in each gamma_j). Exact when one channel has C invertible, or every channel's rows
    have rank n (module docstring): then ``upper = lower`` and a certificate must exist 5 % of the way to
    ``1 / max d`` (else CrossCheckError); a certificate below the lower bound is a CrossCheckError too.
    Time O(log(1/tol)) certificate searches.

    Examples
    --------
    >>> cg = critical_gamma(np.array([[2.0]]), Sensor(C=[[1.0]], gamma=[0.5], noise_cov=[[1.0]]))
    >>> round(cg.lower, 12), abs(cg.upper - 0.75) < 1e-5, cg.exact     # scalar: 1 - 1/a^2
    (0.75, True, True)
    """
    d = np.ones(sensor.g) if direction is None else np.asarray(direction, dtype=float).reshape(-1)
    if d.shape != (sensor.g,) or np.any(d < 0) or not np.any(d > 0) or not np.all(np.isfinite(d)):
        raise InputError("direction", f"expected {sensor.g} non-negative numbers, not all zero, found {d.tolist()}")
    t_max = 1.0 / float(d.max())
    rho = float(np.max(np.abs(np.linalg.eigvals(A))))
    if rho * rho * _all_lost(t_max, d) >= 1.0:
        lower = t_max
    elif rho <= 1.0:
        lower = 0.0
    elif sensor.g == 1:
        lower = (1.0 - 1.0 / (rho * rho)) / float(d[0])
    else:
        lo, hi = 0.0, t_max          # q(t) rho^2 falls in t
        while hi - lo > 1e-15 * t_max:
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if _all_lost(mid, d) * rho * rho >= 1.0 else (lo, mid)
        lower = hi
    n = A.shape[0]
    if all(np.linalg.matrix_rank(sensor.C[list(rows)]) == n for rows in sensor.groups):
        probe = lower + 0.05 * (t_max - lower)          # the theorem's answer, checked above it
        if lower < t_max and stable_certificate(A, sensor, probe * d) is None:
            raise CrossCheckError("critical arrival rate: every channel alone observes the state, yet no certificate "
                                  "just above the lower bound", {"lower (exact)": lower, "probe": probe})
        return CriticalGamma(d, lower, lower, True, "every sensor channel's rows have rank n (C invertible): the "
                                                    "lower bound is exact (Sinopoli et al. 2004)")
    if stable_certificate(A, sensor, t_max * d) is None:
        upper = float("inf")
    else:
        lo, hi = lower, t_max
        while hi - lo > tol:
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if stable_certificate(A, sensor, mid * d) is not None else (mid, hi)
        upper = hi
    if upper < lower - tol:
        raise CrossCheckError("critical arrival rate: a certified bounded rate lies below the proven lower bound",
                              {"lower (q rho^2 = 1)": lower, "upper (certificate)": upper})
    return CriticalGamma(d, lower, upper, False, "bounds: q rho(A)^2 = 1 below, a checked X > g(X) above")
