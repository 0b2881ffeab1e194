"""Bounds on the TCP-like filter's expected error covariance behind Markov (Gilbert–Elliott) sensor links, and
whether it stays bounded: the Bernoulli bounds of [`.bounds`][packetloss_cvx.sensing.bounds] carried over to the arrival
chain of [`.arrivals`][packetloss_cvx.sensing.arrivals] (S joint states, transition T, pattern emission e(a|s), limit
distribution pi).

With ``Lambda = diag(e(all lost | s)) T``
([`.arrivals.Arrivals.loss_matrix`][packetloss_cvx.sensing.arrivals.Arrivals.loss_matrix]):

* **Lower bound.** ``P^-_k >= sum_{i <= L_k} A^i Sigma_W A'^i`` with ``L_k`` the number of all-lost steps just
  before k (``P >= 0``, and ``P = P^-`` on a loss), and ``P(L_k >= i) = pi_{k-i} Lambda^i 1``, so
  ``E[P^-_k] >= sum_{i<k} (pi_{k-i} Lambda^i 1) A^i Sigma_W A'^i``; as ``pi_k -> pi`` the stationary bound is
  ``sum_s pi_s Y_s`` with ``Y_s = Sigma_W + sum_s' Lambda[s, s'] A Y_s' A'`` (a coupled Lyapunov equation; the
  Bernoulli ``S = q A S A' + Sigma_W`` is its one-state case). Also ``E[P^-_k] >= (pi_0 Lambda^k 1) A^k P0 A'^k``.
  So does the noise series from ``pi_1`` (term i: ``P(L_{i+1} >= i) A^i Sigma_W A'^i``, the transient of a bad
  start). Any of these diverging at ``Lambda (1 - DIVERGENCE_MARGIN)`` proves ``E[P^-_k]`` unbounded (root test:
  its terms then grow without bound); each runs over the states its start reaches (others never contribute). It
  converges when ``rho(Lambda) rho(A)^2 < 1`` (Lambda on the states the chain visits: `reachable_loss_radius`).
* **Upper bound** (Jensen, per chain state). Given ``S_k = s`` the pattern ``a_k`` is independent of ``P^-_k``
  and of ``S_{k+1}``, and each ``g_a(V) = A U_a(V) A' + Sigma_W`` is concave and monotone, so with
  ``W_{k,s} = E[P^-_k | S_k = s]``: ``E[P^-_{k+1} 1{S_{k+1} = s'}] <= sum_s T[s, s'] pi_k(s) sum_a e(a|s)
  g_a(W_{k,s})``. By induction ``W_k <= V_k`` for the same recursion run on V from ``V_0 = P0``, and
  ``E[P^-_k] <= sum_s pi_k(s) V_{k,s}``; `markov_upper_bound` iterates it from the file's belief to its
  limit (None when it diverges or does not settle: no bound, not a verdict). One state: Sinopoli's ``g``.
* **Bounded, proved** ([`filter_stability`][packetloss_cvx.sensing.markov_bounds.filter_stability]), two ways. (1) Every
channel's rows alone have rank n (one-step
  observable): after any arrival ``P <= C_j^+ R_j C_j^+'`` (the Kalman update is no worse than the pure-measurement
  estimate), so ``E[P^-_k] <= sum_i P(L_k >= i) A^i Q A'^i + (pi_0 Lambda^k 1) A^k P0 A'^k`` for a fixed Q, finite
  when ``rho(Lambda) rho(A)^2 < 1``: then that condition is necessary and sufficient (given noise exciting the
  unstable modes). (2) Otherwise a checked certificate: stacked ``X_s > 0`` with ``X - H(X) > 0``, ``H(X)_{s'} =
  sum_s w(s|s') (A sum_a e(a|s) U_a(X_s) A' + I)``, ``w(s|s') = pi(s) T[s, s'] / pi(s')`` (the recursion above in the
  stationary chain, conditioned on S_{k+1}); Sinopoli's Lemma carries over (fix the gains at X: the linear part
  maps X strictly below itself, so its radius is below 1, and H at those gains bounds H from above), so the
  bound sequence stays bounded for the chain started in pi. From the file's belief the recursion's weights
  ``w_k(s|s') = pi_k(s) T[s, s'] / pi_{k+1}(s')`` tend to w (pi_k -> pi > 0), so its linear parts tend to one of
  radius below 1, hence are contractive in one norm from some step on: bounded from any belief. Neither and no
  divergence: undecided.

For Gilbert channels (``h_good = 1, h_bad = 0``) ``rho(Lambda) = prod_j (1 - r_j)``: one channel needs
``r > 1 - 1/rho(A)^2`` whatever p (Huang and Dey, Automatica 2007, state stability conditions for this channel;
the proofs used here are the ones above), exactly that when C is invertible.
"""

from __future__ import annotations

import numpy as np

from ..errors import CrossCheckError, InputError, NumericalError
from ..model.chain import reachable_states
from ..model.sensor import Sensor
from ..results.sensing import CovarianceBounds, FilterStability
from .arrivals import Arrivals, sensor_arrivals
from .bounds import CERTIFICATE_MAX_ITER, DIVERGENCE_MARGIN, MARE_DIVERGENCE, MARE_MAX_ITER, MARE_RTOL
from .kalman import RowUpdate, pattern_rows, predict

__all__ = ["MARKOV_MAX_UNKNOWNS", "filter_stability", "markov_certificate", "markov_covariance_bounds",
           "markov_lower_bound", "markov_lower_diverges", "markov_upper_bound", "reachable_loss_radius",
           "weighted_series"]

#: The coupled Lyapunov equation of the lower bound has S n^2 unknowns: at most this many (S = 2^g states).
MARKOV_MAX_UNKNOWNS = 2048


def weighted_series(A: np.ndarray, X: np.ndarray, Lam: np.ndarray, start: np.ndarray) -> np.ndarray | None:
    """``sum_i (start Lambda^i 1) A^i X A'^i`` (module docstring), or None when it diverges: the stacked
    ``Y = X 1 + (Lambda kron A kron A) Y``, solved directly when ``rho(Lambda) rho(A)^2 < 1 - 1e-12``, else summed
    by doubling (divergence past MARE_DIVERGENCE times |X|). Time O((S n^2)^3).

    >>> round(float(weighted_series(np.array([[2.0]]), np.eye(1), np.array([[0.2]]), np.ones(1))[0, 0]), 12)  # 1/0.2
    5.0
    >>> weighted_series(np.array([[2.0]]), np.eye(1), np.array([[0.25]]), np.ones(1)) is None     # 0.25 * 4 = 1
    True
    """
    S, n = Lam.shape[0], A.shape[0]
    if S * n * n > MARKOV_MAX_UNKNOWNS:
        raise InputError("sensor.groups", f"the Markov bounds solve for S n^2 = {S * n * n} numbers, over "
                                          f"{MARKOV_MAX_UNKNOWNS}: fewer Gilbert-Elliott sensor channels")
    X = np.asarray(X, dtype=float)
    if float(np.linalg.norm(X)) == 0.0:
        return np.zeros((n, n))
    keep = reachable_states(Lam, start)        # (start Lambda^i)_s = 0 elsewhere: states start never runs into
    Lam, start, S = Lam[np.ix_(keep, keep)], start[keep], int(keep.sum())
    M = np.kron(Lam, np.kron(A, A))
    v = np.tile(X.ravel(), S)
    rho = _radius(Lam) * _radius(A) ** 2
    if rho < 1.0 - 1e-12:
        y = np.linalg.solve(np.eye(S * n * n) - M, v)
    else:
        y, scale = v.copy(), float(np.linalg.norm(v))
        with np.errstate(over="ignore", invalid="ignore"):
            for _ in range(64):
                term = M @ y
                y, M = y + term, M @ M
                size = float(np.linalg.norm(term))
                if not np.isfinite(size) or size > MARE_DIVERGENCE * scale:
                    return None
                if size <= 1e-15 * float(np.linalg.norm(y)):
                    break
            else:
                return None
    Y = y.reshape(S, n, n)
    out = np.einsum("s,sij->ij", start, Y)
    return 0.5 * (out + out.T)


def _radius(M: np.ndarray) -> float:
    """The spectral radius (0 for an empty matrix). O(S^3)."""
    return float(np.max(np.abs(np.linalg.eigvals(M)))) if M.size else 0.0


def markov_lower_diverges(A: np.ndarray, Sigma_W: np.ndarray, P0: np.ndarray, arrivals: Arrivals) -> bool:
    """A lower-bound series (noise from the limit distribution; noise from ``pi_1``, the run of losses since step 1,
    whose term i is ``P(L_{i+1} >= i) A^i Sigma_W A'^i <= E[P^-_{i+1}]``; P0 from the initial distribution)
    diverges at ``Lambda (1 - DIVERGENCE_MARGIN)``: E[P^-_k] proved unbounded (module docstring). Each series runs
    over the states its start reaches (`weighted_series`): a bad state the chain never enters proves nothing.
    False when the chain has no limit distribution (nothing proved). Time as `weighted_series`."""
    if arrivals.limit is None:
        return False
    Lam = arrivals.loss_matrix() * (1.0 - DIVERGENCE_MARGIN)
    return (weighted_series(A, Sigma_W, Lam, arrivals.limit) is None
            or weighted_series(A, Sigma_W, Lam, arrivals.initial @ arrivals.transition) is None
            or weighted_series(A, P0, Lam, arrivals.initial) is None)


def reachable_loss_radius(arrivals: Arrivals) -> float:
    """``rho(Lambda)`` over the states the chain can visit from its initial distribution (closed under T, so
    ``P(L_k >= i) = pi_{k-i} Lambda^i 1`` only involves them): the radius the one-step observability proof needs.
    O(S^3)."""
    keep = reachable_states(arrivals.transition, arrivals.initial)
    return _radius(arrivals.loss_matrix()[np.ix_(keep, keep)])


def markov_lower_bound(A: np.ndarray, Sigma_W: np.ndarray, arrivals: Arrivals) -> np.ndarray | None:
    """The stationary lower bound ``sum_i (pi Lambda^i 1) A^i Sigma_W A'^i`` on lim E[P^-_k] (None: infinite, or
    the chain has no limit distribution). Time as `weighted_series`."""
    if arrivals.limit is None:
        return None
    return weighted_series(A, Sigma_W, arrivals.loss_matrix(), arrivals.limit)


def _expected_step(A: np.ndarray, Q: np.ndarray, sensor: Sensor, arrivals: Arrivals):
    """``V (S, n, n) -> (A sum_a e(a|s) U_a(V_s) A' + Q)_s``, the per-state expected filter step."""
    terms = [(arrivals.emission[:, k, None, None], RowUpdate(sensor.C, sensor.noise_cov, pattern_rows(sensor, a)))
             for k, a in enumerate(arrivals.patterns) if np.any(arrivals.emission[:, k] > 0.0)]

    def apply(V: np.ndarray) -> np.ndarray:
        V = np.asarray(V, dtype=float)
        return predict(sum(e * update.covariance(V) for e, update in terms), A, Q)

    return apply


def markov_upper_bound(A: np.ndarray, Sigma_W: np.ndarray, sensor: Sensor,
                       arrivals: Arrivals | None = None) -> np.ndarray | None:
    """The limit of ``sum_s pi_k(s) V_{k,s}`` (module docstring: ``V_{k+1,s'} = sum_s pi_k(s) T[s, s'] G_s(V_{k,s})
    / pi_{k+1}(s')``, ``V_0 = P0``, pi_k from the file's belief), an upper bound on lim sup E[P^-_k]; None when
    the iteration diverges or does not settle within MARE_MAX_ITER steps. Time O(iterations 2^g S (n^3 + p^3)).

    >>> ch = {"model": "gilbert-elliott", "p": [0.5], "r": [0.5]}        # p + r = 1: i.i.d., rate 0.5
    >>> V = markov_upper_bound(np.array([[1.0]]), np.eye(1), Sensor(C=[[1.0]], noise_cov=[[1.0]], channel=ch))
    >>> from packetloss_cvx.sensing.bounds import upper_bound_covariance
    >>> W = upper_bound_covariance(np.array([[1.0]]), np.eye(1), Sensor(C=[[1.0]], noise_cov=[[1.0]], gamma=[0.5]))
    >>> bool(np.isclose(V[0, 0], W[0, 0], rtol=1e-10))
    True
    """
    arrivals = sensor_arrivals(sensor) if arrivals is None else arrivals
    if arrivals.limit is None:
        return None
    step = _expected_step(A, Sigma_W, sensor, arrivals)
    T = arrivals.transition
    pi = arrivals.initial
    V = np.broadcast_to(np.asarray(sensor.P0, dtype=float), (arrivals.states, *A.shape)).copy()
    scale = max(float(np.linalg.norm(Sigma_W)), float(np.linalg.norm(sensor.P0)), np.finfo(float).tiny)
    bound = np.einsum("s,sij->ij", pi, V)
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(MARE_MAX_ITER):
            mass = np.einsum("st,sij->tij", T, pi[:, None, None] * step(V))      # E-bound of P^- 1{S = t}
            nxt = pi @ T
            V = np.where(nxt[:, None, None] > 0, mass / np.where(nxt > 0, nxt, 1.0)[:, None, None], 0.0)
            new = mass.sum(axis=0)
            size = float(np.linalg.norm(new))
            if not np.isfinite(size) or size > MARE_DIVERGENCE * scale:
                return None
            settled = float(np.abs(nxt - pi).sum()) <= 1e-15
            pi = nxt
            if settled and float(np.linalg.norm(new - bound)) <= MARE_RTOL * max(size, np.finfo(float).tiny):
                return 0.5 * (new + new.T)
            bound = new
    return None


def markov_certificate(A: np.ndarray, sensor: Sensor, arrivals: Arrivals | None = None) -> np.ndarray | None:
    """Stacked ``X_s`` with ``X - H(X) > 0`` in every state (module docstring, least eigenvalues checked in
    numpy), found along ``X_{k+1} = H(X_k) + I`` from 0 as `.bounds.stable_certificate`; None when none is
    found within CERTIFICATE_MAX_ITER steps, or the limit distribution is not positive. Time
    O(CERTIFICATE_MAX_ITER 2^g S (n^3 + p^3)).

    >>> ch = {"model": "gilbert-elliott", "p": [0.1], "r": [0.6]}     # Gilbert: needs r > 1 - 1/a^2 = 0.75 ...
    >>> markov_certificate(np.array([[2.0]]), Sensor(C=[[1.0]], noise_cov=[[1.0]], channel=ch)) is None
    True
    >>> ch["r"] = [0.8]                                               # ... which 0.8 is
    >>> markov_certificate(np.array([[2.0]]), Sensor(C=[[1.0]], noise_cov=[[1.0]], channel=ch)) is not None
    True
    """
    arrivals = sensor_arrivals(sensor) if arrivals is None else arrivals
    pi = arrivals.limit
    if pi is None or np.any(pi <= 0.0):
        return None
    n, S = A.shape[0], arrivals.states
    eye = np.eye(n)
    w = (pi[:, None] * arrivals.transition) / (pi @ arrivals.transition)[None, :]      # w[s, s'] = P(S = s | S+ = s')
    step = _expected_step(A, np.zeros((n, n)), sensor, arrivals)

    def H(X: np.ndarray, noise: float) -> np.ndarray:
        return np.einsum("st,sij->tij", w, step(X)) + noise * eye

    X = np.zeros((S, n, n))
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(CERTIFICATE_MAX_ITER):
            new = H(X, 2.0)
            if not np.all(np.isfinite(new)) or float(np.linalg.norm(new)) > MARE_DIVERGENCE * n * S:
                return None
            gap = X - (new - eye)
            if float(np.min(np.linalg.eigvalsh(0.5 * (gap + np.swapaxes(gap, 1, 2))))) > 0.0:
                check = X - H(X, 1.0)                                       # the certificate, evaluated afresh
                if float(np.min(np.linalg.eigvalsh(0.5 * (check + np.swapaxes(check, 1, 2))))) > 0.0:
                    return X
            X = new
    return None


def markov_covariance_bounds(A: np.ndarray, Sigma_W: np.ndarray, sensor: Sensor) -> CovarianceBounds:
    """The stationary lower and upper bounds on E[P^-] behind the sensor's chains (module docstring), checked to be
    ordered (else CrossCheckError); InputError (field ``sensor.p``) for a chain with no limit distribution
    (p = r = 1), or beyond MARKOV_MAX_UNKNOWNS. Time as `markov_upper_bound`.

    >>> ch = {"model": "gilbert-elliott", "p": [0.2], "r": [0.8]}    # p + r = 1: the Bernoulli twin, rate 0.8
    >>> b = markov_covariance_bounds(np.array([[1.1]]), np.eye(1), Sensor(C=[[1.0]], channel=ch))
    >>> round(b.trace_lower, 9), round(b.trace_upper, 9)                # R = 0: 1 / (1 - 0.2 * 1.21), both
    (1.319261214, 1.319261214)
    """
    arrivals = sensor_arrivals(sensor)
    if arrivals.limit is None:
        raise InputError("sensor.p", "a sensor channel with p = r = 1 alternates for ever: its state distribution has "
                                     "no limit, so there are no stationary bounds (not analysed)")
    lower = markov_lower_bound(A, Sigma_W, arrivals)
    upper = markov_upper_bound(A, Sigma_W, sensor, arrivals)
    if lower is None and upper is not None:
        raise CrossCheckError("expected error covariance (Markov sensor links): the lower bound diverges where the "
                              "upper bound is finite", {"lower": float("inf"), "upper": float(np.trace(upper))})
    if lower is not None and upper is not None:
        least = float(np.linalg.eigvalsh(upper - lower)[0])
        if least < -1e-8 * max(float(np.linalg.norm(upper)), 1.0):
            raise CrossCheckError("expected error covariance (Markov sensor links): the upper bound lies below the "
                                  "lower bound", {"lower": float(np.trace(lower)), "upper": float(np.trace(upper))})
    return CovarianceBounds(lower, upper)


def filter_stability(A: np.ndarray, Sigma_W: np.ndarray, sensor: Sensor) -> FilterStability:
    """Whether the TCP-like filter's E[P^-_k] stays bounded behind the sensor's links (module docstring): proved
    unbounded by the lower bound, proved bounded by one-step observability with ``rho(Lambda) rho(A)^2 < 1 -
    DIVERGENCE_MARGIN`` or by a certificate, else undecided (None). Bernoulli sensors are the one-state chain.
    Time O(certificate search).

    Examples
    --------
    >>> ch = {"model": "gilbert-elliott", "p": [0.3], "r": [0.8]}         # C = 1: exact, (1 - 0.8) 4 = 0.8 < 1
    >>> fs = filter_stability(np.array([[2.0]]), np.eye(1), Sensor(C=[[1.0]], channel=ch))
    >>> fs.bounded, round(fs.loss_radius, 12), fs.exact
    (True, 0.8, True)
    >>> ch["r"] = [0.7]                                                   # (1 - 0.7) 4 = 1.2
    >>> filter_stability(np.array([[2.0]]), np.eye(1), Sensor(C=[[1.0]], channel=ch)).bounded
    False
    """
    arrivals = sensor_arrivals(sensor)
    n = A.shape[0]
    rho_A = float(np.max(np.abs(np.linalg.eigvals(A))))
    loss = reachable_loss_radius(arrivals) * rho_A * rho_A
    exact = all(np.linalg.matrix_rank(sensor.C[list(rows)]) == n for rows in sensor.groups)
    if arrivals.limit is None:
        return FilterStability(None, loss, exact, "", "undecided: a channel with p = r = 1 alternates for ever, so "
                                                     "its state distribution has no limit (not analysed)")
    if markov_lower_diverges(A, Sigma_W, sensor.P0, arrivals):
        return FilterStability(False, loss, exact, "lower bound",
                               "unbounded, proved: the lower bound on E[P-] diverges (all-lost runs of the chain "
                               f"against the plant: rho(Lambda) rho(A)^2 = {loss:.6g})")
    if exact and loss < 1.0 - DIVERGENCE_MARGIN:
        return FilterStability(True, loss, exact, "one-step observability",
                               "bounded, proved: every sensor channel alone observes the state, and rho(Lambda) "
                               f"rho(A)^2 = {loss:.6g} < 1")
    try:
        certificate = markov_certificate(A, sensor, arrivals)
    except NumericalError:
        certificate = None
    if certificate is not None:
        return FilterStability(True, loss, exact, "certificate",
                               "bounded, proved: a checked certificate X - H(X) > 0 (coupled over the chain's "
                               "states)")
    return FilterStability(None, loss, exact, "", "undecided: the lower bound is finite and no certificate was found "
                                                  f"(rho(Lambda) rho(A)^2 = {loss:.6g}; < 1 is necessary)")
