"""A law ``u = -K xhat`` run for ever on the estimate of a filter with stationary gains: the loop
``z = (xhat, e)``, ``e = x - xhat``, is linear with independent random matrices, so its mean-square radius
and stationary cost are exact from second moments (the operator of simulation.stability on the augmented state,
averaged over the sensor's arrival patterns).

The filter's gains: ``Pbar`` the stationary predicted covariance of the expected Riccati map (sensing.bounds,
the modified Riccati fixed point) and, for each arrival pattern a, ``L_a`` the update gain of its rows at
``Pbar`` (zero columns for rows not received). With ``v_i ~ Bernoulli(mu_i)``, ``a`` the arrivals, noise ``w``
and ``r``:

    TCP-like (acks, prediction A xhat + B V u):   the V u terms cancel in the error, so
        xhat+ = (A - B V K) xhat + L_a C A e + L_a (C w + r)
        e+    = (I - L_a C) A e + (I - L_a C) w - L_a r
    UDP-like (prediction A xhat + B M u):   e- = A e - B (V - M) K xhat + w, so
        xhat+ = (A - B M K) xhat + L_a C A e - L_a C B (V - M) K xhat + L_a (C w + r)
        e+    = (I - L_a C) A e - (I - L_a C) B (V - M) K xhat + (I - L_a C) w - L_a r

``z+ = (F_a + sum_i (v_i - mu_i) D_{a,i}) z + N_a (w, r)``: the TCP-like ``D_i = -[b_i; 0] [k_i, 0]``, the UDP-like
``D_{a,i} = -[L_a C b_i; (I - L_a C) b_i] [k_i, 0]``. So ``E[z+ z+'] = sum_a p_a (F_a S F_a' + sum_i mu_i (1 -
mu_i) D_{a,i} S D_{a,i}' + N_a diag(Sigma_W, R) N_a')``; its matrix is
``sum_a p_a random_matrix_moment(F_a, D_a, mu (1 - mu))``. Stage cost ``x'Omega x + (V u)'Psi(V u)`` has mean
``tr(W S)``, ``W = [[Omega + K'M Psi K, Omega], [Omega, Omega]]`` (``x = xhat + e``, ``v_i^2 = v_i``).

**The cost splits** (the audit's claim, checked by simulation in the tests): with P the DP's cost-to-go
(simulation.riccati, full state) and ``H = M Psi + M B'PB M + D(P)`` its input Hessian, for any u chosen
without knowing V (``E[.|x, u]`` over V and w)

    E[x'Omega x + (V u)'Psi(V u) + x+'P x+ | x, u] = x'P x + (u + K_dp x)' H (u + K_dp x) + tr(P Sigma_W),

so in the stationary loop the average cost is ``tr(P Sigma_W)`` (control part: the full-state optimum) plus
``E[(u + K_dp x)' H (u + K_dp x)]`` (estimation part; for the DP law on the estimate, ``tr(K'HK E[e e'])``).
TCP-like with the DP law is then optimal for the estimate's filter (separation, Schenato et al. 2007); the
UDP-like law on the UDP estimate is certainty equivalence, NOT optimal: its error covariance grows with the
inputs (the actuation term), which the law ignores.
"""

from __future__ import annotations

import numpy as np

from ..closedloop.moments import solve_fixed_point, stationary_channel
from ..closedloop.riccati import NO_SOLUTION, dp_input_hessian, dp_riccati
from ..closedloop.stability import mean_square_radius, random_matrix_moment
from ..closedloop.tails import error_bar_reason
from ..errors import InputError, NumericalError
from ..lq.costs import closed_form
from ..model.system import System, loop_weights
from ..results import Riccati
from ..results.sensing import EstimatedLoop
from ..tolerances import KRONECKER_MAX_N, MEAN_SQUARE_MARGIN
from .arrivals import arrival_patterns, sensor_arrivals
from .bounds import lower_bound_diverges, upper_bound_covariance
from .kalman import measurement_update, pattern_rows
from .markov_bounds import filter_stability, markov_lower_diverges

__all__ = ["LOOP_MAX_N", "MAP_LAWS", "chain_loop_verdict", "estimated_loop", "filter_gains", "loop_error_bar_reason",
           "loop_map", "loop_terms", "loop_verdict", "no_gains_verdict", "require_sensor", "second_moment_map",
           "stage_weight", "undetermined_gains", "window_costs"]

#: The exact moments of z = (xhat, e) form (2n)^2 x (2n)^2 matrices: up to n = KRONECKER_MAX_N.
LOOP_MAX_N = KRONECKER_MAX_N


def require_sensor(system: System, chains: bool = False) -> None:
    """An InputError (field ``sensor``) unless the system has a sensor: a Bernoulli one, or (``chains``) also
    Gilbert–Elliott links (field ``sensor.model`` otherwise)."""
    if system.sensor is None:
        raise InputError("sensor", "expected a system with a [sensor] section (the full-state loop is "
                                   "simulation.closed_loop)")
    if system.sensor.channel is not None and not chains:
        raise InputError("sensor.model", "a Gilbert-Elliott sensor's losses are correlated: the independent-arrival "
                                         "analysis does not describe it (give gamma for the Bernoulli twin)")


def loop_verdict(radius: float) -> bool | None:
    """The verdict a radius of the (xhat, e) second-moment operator proves: True below ``1 - MEAN_SQUARE_MARGIN``,
    False above ``1 + MEAN_SQUARE_MARGIN`` (inf included), None (no verdict) within the margin of 1 or for nan (the
    eigenvalue solvers agree to about 1e-12 relative, so a radius that close to 1 proves neither). O(1).

    >>> loop_verdict(0.5), loop_verdict(2.0), loop_verdict(1.0), loop_verdict(float("nan"))
    (True, False, None, None)
    """
    if np.isnan(radius):
        return None
    if radius < 1.0 - MEAN_SQUARE_MARGIN:
        return True
    return False if radius > 1.0 + MEAN_SQUARE_MARGIN else None


#: Why ``stable`` is False where the filter has no stationary gains and the lower bound diverges.
UNBOUNDED_REASON = ("not mean-square stable, proved: the lower bound on the filter's expected error covariance "
                    "diverges at this gamma (sensing.bounds.lower_bound_diverges), and E[x x'] >= E[P_k] for any law "
                    "on any estimate (the Kalman filter's P_k is the least error covariance given the TCP-like "
                    "information, which contains the UDP-like one)")
#: Why ``stable`` is null where the filter has no stationary gains but the lower bound is finite.
UNDECIDED_REASON = ("undecided: the filter has no stationary gains at this gamma (the expected Riccati upper-bound "
                    "iteration diverges or does not settle), yet the lower bound on E[P] is finite: gamma lies between "
                    "the certified bounds on the critical rate, where neither bound decides")


#: Why the loop behind Gilbert–Elliott sensor links has no exact moments (unless proved unbounded).
CHAIN_REASON = ("no exact loop behind Gilbert-Elliott sensor links: with stationary gains the loop (xhat, e) is a "
                "Markov jump system, not derived here (the time-varying filter: simulate --closed-loop's Monte Carlo)")


def no_gains_verdict(system: System) -> tuple[bool | None, str]:
    """The verdict where [`filter_gains`][packetloss_cvx.sensing.loop.filter_gains] is None: ``(False, reason)`` when
    the lower bound on E[P^-] diverges at the system's gamma (sensing.bounds.lower_bound_diverges: from the noise or
    from P0; proved, since E[x x'] >= E[P_k] >= q E[P^-_k] -> inf for every law on every estimate), else ``(None,
    reason)``: the upper-bound iteration diverging proves nothing (Jensen's bound, not E[P]). O(n^3 log).

    >>> from packetloss_cvx.model.sensor import Sensor
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[0.0],
    ...            noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], gamma=[0.5]))   # (1 - 0.5) 2^2 = 2 >= 1
    >>> no_gains_verdict(s)[0]
    False
    """
    sensor = system.sensor
    if sensor.channel is not None:      # Markov arrivals: the same argument with the chain's all-lost runs
        try:
            diverges = markov_lower_diverges(system.A, system.noise_cov, sensor.P0, sensor_arrivals(sensor))
        except InputError as err:       # more joint chain states than the coupled equations take
            return None, f"undecided: {err}"
        if diverges:
            return False, UNBOUNDED_REASON.replace("sensing.bounds.lower_bound_diverges",
                                                   "sensing.markov_bounds.markov_lower_diverges")
        return None, "undecided: " + CHAIN_REASON
    if lower_bound_diverges(system.A, system.noise_cov, sensor.P0, float(np.prod(1.0 - sensor.gamma))):
        return False, UNBOUNDED_REASON
    return None, UNDECIDED_REASON


#: Why the TCP-like loop on the Kalman estimate behind Gilbert-Elliott links is proved mean-square stable.
SEPARATION_REASON = ("mean-square stable, proved by separation (the loop with the time-varying Kalman filter): the "
                     "filter's E[P] is bounded (sensing.markov_bounds.filter_stability: {by}) and the law's full-state "
                     "loop over the actuator links has second-moment radius {radius:.6g} < 1; "
                     "x+ = (A - BVK) x + BVK e + w with V independent of e and w. The cost is not derived: Monte Carlo")


def chain_loop_verdict(system: System, gain: np.ndarray, protocol: str, mu: np.ndarray) -> tuple[bool | None, str]:
    """The verdict on ``u = -K xhat`` behind Gilbert–Elliott sensor links, with the time-varying Kalman filter:
    False where the lower bound on E[P] diverges (`no_gains_verdict`); TCP-like, True where the filter's E[P]
    is proved bounded and the law's full-state loop over the actuator links is mean-square stable (separation:
    ``x+ = (A - BVK) x + BVK e + w``, the products of ``A - B V_i K`` after step j independent of ``e_j``, ``w_j``, so
    ``|x_k|_2 <= sum_j (c rho^(k-j))^(1/2) |BVKe_j + w_j|_2`` is bounded: docs/mathematics.md); else None with the
    reason. UDP-like: the error depends on the inputs, so only the divergence proves anything. Time
    O(filter_stability + n^6).

    >>> from packetloss_cvx.model.sensor import Sensor
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[0.0],
    ...            noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], channel={"model": "gilbert-elliott", "p": [0.1],
    ...                                                                  "r": [0.8]}))
    >>> chain_loop_verdict(s, np.array([[1.8]]), "tcp", np.array([0.9]))[0]   # (1 - 0.8) 4 < 1; 0.2^2 + 0.09 1.8^2
    True
    """
    verdict, why = no_gains_verdict(system)
    if verdict is False or protocol != "tcp":
        return verdict, why
    try:
        fs = filter_stability(system.A, system.noise_cov, system.sensor)
        radius = mean_square_radius(system.A, system.B, gain, mu)
    except (InputError, NumericalError) as err:
        return None, f"undecided: {err}"
    if fs.bounded is True and loop_verdict(radius) is True:
        return True, SEPARATION_REASON.format(by=fs.by, radius=radius)
    return None, (f"undecided: the filter's E[P] is {'bounded' if fs.bounded else 'not proved bounded'} and the "
                  f"full-state loop's radius is {radius:.6g}; " + CHAIN_REASON)


def filter_gains(system: System) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(Pbar, gains (2^g, n, p), probabilities (2^g,))``: the stationary predicted covariance and each arrival
    pattern's update gain (module docstring); None when the expected Riccati iteration has no fixed point
    (the rate is not certified). Time as sensing.bounds.upper_bound_covariance."""
    require_sensor(system)
    sensor = system.sensor
    Pbar = upper_bound_covariance(system.A, system.noise_cov, sensor)
    if Pbar is None:
        return None
    arrived, prob = arrival_patterns(sensor.gamma)
    gains = np.stack([measurement_update(Pbar, sensor.C, sensor.noise_cov, pattern_rows(sensor, a))[1]
                      for a in arrived])
    return Pbar, gains, prob


def undetermined_gains(system: System, gains: tuple[np.ndarray, np.ndarray, np.ndarray]) -> str:
    """Why the stationary gains say nothing about the loop ("" when they do): some received pattern's innovation
    covariance ``C_r Pbar C_r' + R_r`` is singular (to 1e-12 of ``|C_r|^2 max(|Pbar|, |Sigma_W|, |P0|) + |R_r|``),
    so its gain is not fixed by ``Pbar`` and the pseudo-inverse's zero gain leaves the error uncorrected. The
    case: no noise reaches the measured rows and R = 0 (C = 1, R = 0, Sigma_W = 0, gamma = 1 has Pbar = 0 and a
    perfect sensor, yet the zero gain read as radius 4, "not stable"). O(2^g p^3)."""
    sensor = system.sensor
    Pbar, _, prob = gains
    arrived, _ = arrival_patterns(sensor.gamma)
    level = max(np.linalg.norm(Pbar, 2), np.linalg.norm(system.noise_cov, 2), np.linalg.norm(sensor.P0, 2))
    for a, pa in zip(arrived, prob, strict=True):
        rows = pattern_rows(sensor, a)
        if pa == 0.0 or rows.size == 0:
            continue
        Cr, Rr = sensor.C[rows], sensor.noise_cov[np.ix_(rows, rows)]
        S = Cr @ Pbar @ Cr.T + Rr
        scale = np.linalg.norm(Cr, 2) ** 2 * level + np.linalg.norm(Rr, 2)
        if np.linalg.eigvalsh(0.5 * (S + S.T))[0] <= 1e-12 * scale:
            return ("the stationary filter's innovation covariance is singular on the received rows (no noise reaches "
                    "them and R = 0 there): its gains are not determined by the stationary covariance, so no exact "
                    "stationary loop (use simulate's time-varying filter)")
    return ""


def estimated_loop(system: System, gain: np.ndarray, protocol: str, law: str = "",
                   gains: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None, split: bool = True,
                   dp: Riccati | None = None) -> EstimatedLoop:
    """The exact stationary loop of ``u = -K xhat`` (module docstring) at the system's mu and gamma.

    Returns the radius of the second-moment operator of ``(xhat, e)``, the verdict it proves (`loop_verdict`),
    the average stage cost (inf with the reason when proved not mean-square stable; nan with the reason, verdict
    None, when undecided: a radius within the margin of 1, or no stationary gains while the lower bound on E[P] is
    finite, `no_gains_verdict`) and its two parts
    (``split=False``: not computed, nan; it solves the DP). ``gains``:
    [`filter_gains`][packetloss_cvx.sensing.loop.filter_gains] of this system when the caller has them (a map over mu at
    one gamma); ``dp``: ``dp_riccati(system)`` when the caller has it (not solved again). Time O(2^g (m + 1) (2n)^4) to
    build the matrix, O((2n)^6) to solve.

    Raises
    ------
    InputError
        No sensor; a non-stationary or Gilbert-Elliott actuator channel (simulation.moments). Gilbert–Elliott
        sensor links give no exact loop: stable False where the lower bound on E[P] is proved to diverge
        (`no_gains_verdict`), else None, with the reason.

    Examples
    --------
    >>> from packetloss_cvx.model.sensor import Sensor
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[0.0],
    ...            noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], gamma=[1.0]))     # C = I, R = 0: full state
    >>> loop = estimated_loop(s, np.array([[0.5]]), "tcp")
    >>> round(loop.average_stage_cost, 12)      # x+ = x/2 + w: E x^2 = 4/3, cost (1 + 1/4) 4/3
    1.666666666667
    """
    require_sensor(system, chains=True)
    mu = stationary_channel(system)
    n = system.n
    K = np.asarray(gain, dtype=float)
    if system.sensor.channel is not None:          # Gilbert-Elliott sensor links: a verdict only where proved
        verdict, why = chain_loop_verdict(system, K, protocol, mu)
        inf_or_nan = float("inf") if verdict is False else float("nan")
        return EstimatedLoop(law, protocol, K, inf_or_nan, verdict, inf_or_nan, float("nan"), float("nan"), None, why)
    B, Sigma_W = system.B, system.noise_cov
    Omega, psi = loop_weights(system)
    dp = dp if split else None
    dp_reason = "not asked for (split=False)"
    if split and dp is None:
        try:
            dp = dp_riccati(system)
        except NumericalError as err:
            dp_reason = str(err)
    nan = float("nan")

    def result(radius: float, cost: float, control: float, estimation: float, S: np.ndarray | None,
               reason: str) -> EstimatedLoop:
        return EstimatedLoop(law, protocol, K, radius, loop_verdict(radius), cost, control, estimation, S, reason)

    if n > LOOP_MAX_N:
        return result(nan, nan, nan, nan, None, f"exact loop moments need n <= {LOOP_MAX_N} (a (2n)^2 matrix); "
                                               f"found n = {n}: use Monte Carlo")
    gains = filter_gains(system) if gains is None else gains
    if gains is None:           # proved unbounded (lower bound) or undecided (between the bounds): never a guess
        verdict, why = no_gains_verdict(system)
        return result(float("inf") if verdict is False else nan, float("inf") if verdict is False else nan,
                      nan, nan, None, why)
    undetermined = undetermined_gains(system, gains)
    if undetermined:
        return result(nan, nan, nan, nan, None, undetermined)
    matrix, noise = second_moment_map(system, K, protocol, gains)
    radius = float(np.max(np.abs(np.linalg.eigvals(matrix))))
    if loop_verdict(radius) is None:
        return result(radius, nan, nan, nan, None, f"undecided: the radius of (xhat, e) is {radius:.12g}, within "
                                                   f"{MEAN_SQUARE_MARGIN:g} of 1")
    if not loop_verdict(radius):
        return result(radius, float("inf"), nan, nan, None, f"not mean-square stable: the radius of (xhat, e) is "
                                                             f"{radius:.6g}")
    S = solve_fixed_point(lambda X: (matrix @ X.ravel()).reshape(2 * n, 2 * n), lambda: matrix, noise,
                          "the stationary second moment of (xhat, e)")
    cost = float(np.sum(stage_weight(system, K) * S))
    if dp is None:
        return result(radius, cost, nan, nan, S, f"no split: {dp_reason}" if split else "")
    P, Kdp = dp.cost_to_go, dp.gain
    H = dp_input_hessian(B, P, mu, psi)
    G = np.concatenate([Kdp - K, Kdp], axis=1)
    control = float(np.sum(P * Sigma_W))
    estimation = float(np.sum((G.T @ H @ G) * S))
    return result(radius, cost, control, estimation, S, "")


def loop_terms(system: System, gain: np.ndarray, protocol: str,
               gains: tuple[np.ndarray, np.ndarray, np.ndarray]) -> list[tuple[float, np.ndarray, np.ndarray,
                                                                               np.ndarray]]:
    """The random matrices of the loop ``z+ = (F_a + sum_i (v_i - mu_i) D_{a,i}) z + N_a (w, r)`` (module docstring),
    per arrival pattern a of positive probability: ``(p_a, F_a, left_a, N_a)`` with ``D_{a,i} = -left_a[:, i]
    [k_i, 0]`` (``left_a`` 2n×m: ``[b_i; 0]`` TCP-like, ``[L_a C b_i; (I - L_a C) b_i]`` UDP-like). ``gains``:
    `filter_gains`. O(2^g n^3)."""
    sensor, A, B, K, n = system.sensor, system.A, system.B, np.asarray(gain, dtype=float), system.n
    mu = stationary_channel(system)
    _, L, prob = gains
    eye, zero = np.eye(n), np.zeros((n, n))
    Abar = A - (B * mu) @ K
    out = []
    for La, pa in zip(L, prob, strict=True):
        if pa == 0.0:
            continue
        LC = La @ sensor.C
        F = np.block([[Abar, LC @ A], [zero, (eye - LC) @ A]])
        left = np.vstack([B, np.zeros_like(B)]) if protocol == "tcp" else np.vstack([LC @ B, (eye - LC) @ B])
        out.append((float(pa), F, left, np.block([[LC, La], [eye - LC, -La]])))
    return out


def second_moment_map(system: System, gain: np.ndarray, protocol: str,
                      gains: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``(matrix, noise)``: ``E[z+ z+'] = matrix vec(E[z z']) + noise`` on row-major vec, the second-moment map of
    the loop of `loop_terms` (``sum_a p_a random_matrix_moment(F_a, D_a, mu (1 - mu))`` and ``sum_a p_a N_a
    diag(Sigma_W, R) N_a'``). O(2^g (m + 1) (2n)^4)."""
    n, K = system.n, np.asarray(gain, dtype=float)
    mu = stationary_channel(system)
    c = mu * (1.0 - mu)
    matrix = np.zeros((4 * n * n, 4 * n * n))
    wide = np.hstack([K, np.zeros_like(K)])
    terms = loop_terms(system, K, protocol, gains)
    for pa, F, left, _ in terms:
        D = [-np.outer(left[:, i], wide[i]) for i in range(left.shape[1])]
        matrix += pa * random_matrix_moment(F, D, c)
    return matrix, _noise_moment(system, terms, system.noise_cov)


def _noise_moment(system: System, terms: list, state_cov: np.ndarray) -> np.ndarray:
    """``sum_a p_a N_a diag(state_cov, R) N_a'``: what a zero-mean state disturbance of covariance ``state_cov`` and
    the measurement noise add to E[z z'] through one update (Sigma_W each step; P0, the prior's error, at the
    first). O(2^g n^3)."""
    n, R = system.n, system.sensor.noise_cov
    cov = np.block([[state_cov, np.zeros((n, R.shape[0]))], [np.zeros((R.shape[0], n)), R]])
    return sum((pa * (N @ cov @ N.T) for pa, _, _, N in terms), np.zeros((2 * n, 2 * n)))


def stage_weight(system: System, gain: np.ndarray) -> np.ndarray:
    """``W`` with ``E[x'Omega x + (V u)'Psi (V u)] = tr(W E[z z'])`` for ``u = -K xhat``, ``x = xhat + e``:
    ``[[Omega + K'M Psi K, Omega], [Omega, Omega]]`` (module docstring). O(n^2 m)."""
    K = np.asarray(gain, dtype=float)
    Omega, psi = loop_weights(system)
    mu = stationary_channel(system)
    return np.block([[Omega + K.T @ ((mu * psi)[:, None] * K), Omega], [Omega, Omega]])


def window_costs(system: System, gain: np.ndarray, protocol: str, steps: int,
                 gains: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The exact expected stage costs ``E[x_k'Omega x_k + (V_k u_k)'Psi (V_k u_k)]``, k = 0..steps-1, of ``u = -K
    xhat`` on the filter's stationary gains from ``x_0 ~ N(x0, P0)`` with the prior ``x0`` (as
    sensing.montecarlo.simulate_estimated runs it): ``E[z_0 z_0'] = [x0; 0][x0; 0]' + sum_a p_a N_a diag(P0, R)
    N_a'``, then `second_moment_map` step by step. inf where it overflows (a loop that is not mean-square stable,
    over a long window). ``gains``: `filter_gains` when the caller has them. Time O(steps (2n)^4).

    Raises
    ------
    InputError
        No Bernoulli sensor; no stationary gains (field ``sensor.gamma``); n > LOOP_MAX_N (field ``n``).

    Examples
    --------
    >>> from packetloss_cvx.model.sensor import Sensor
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[2.0],
    ...            noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], gamma=[1.0]))     # C = I, R = 0: full state
    >>> window_costs(s, np.array([[0.5]]), "tcp", 2).round(12).tolist()   # (1 + 1/4) E x^2: E x^2 = 4, 4/4 + 1
    [5.0, 2.5]
    """
    require_sensor(system)
    if system.n > LOOP_MAX_N:
        raise InputError("n", f"exact loop moments need n <= {LOOP_MAX_N} (a (2n)^2 matrix); found n = {system.n}")
    gains = filter_gains(system) if gains is None else gains
    if gains is None:
        raise InputError("sensor.gamma", "the filter has no stationary gains at this gamma (the expected Riccati "
                                         "iteration diverges)")
    K = np.asarray(gain, dtype=float)
    matrix, noise = second_moment_map(system, K, protocol, gains)
    start = np.concatenate([system.x0, np.zeros(system.n)])
    S = np.outer(start, start) + _noise_moment(system, loop_terms(system, K, protocol, gains), system.sensor.P0)
    W = stage_weight(system, K)
    costs = np.empty(steps)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(steps):
            costs[k] = np.sum(W * S)
            S = (matrix @ S.ravel()).reshape(S.shape) + noise
    return np.where(np.isnan(costs), np.inf, costs)


def loop_error_bar_reason(system: System, gain: np.ndarray, protocol: str,
                          gains: tuple[np.ndarray, np.ndarray, np.ndarray]) -> str:
    """Why a sampled cost of the loop of `loop_terms` gets no error bar ("" when the fourth moments of (xhat, e) are
    proved bounded): closedloop.tails.error_bar_reason on that loop, ``z+ = (A_a - B_a V K~) z`` with ``A_a = F_a +
    left_a M K~``, ``B_a = left_a``, ``K~ = [K, 0]``, its modes the arrival patterns (independent from step to step:
    the chain whose every row is their probabilities). O(tails.fourth_moment_radius at dimension 2n, 2^g modes)."""
    K = np.asarray(gain, dtype=float)
    mu = stationary_channel(system)
    terms = loop_terms(system, K, protocol, gains)
    wide = np.hstack([K, np.zeros_like(K)])
    prob = np.array([t[0] for t in terms])
    A_modes = np.stack([F + (left * mu) @ wide for _, F, left, _ in terms])
    B_modes = np.stack([left for _, _, left, _ in terms])
    h = np.broadcast_to(mu, (len(terms), mu.size))
    return error_bar_reason(A_modes, B_modes, wide, h, np.broadcast_to(prob, (len(terms), len(terms))))


#: The laws of :func:`loop_map`: the DP law on the TCP-like estimate (optimal by separation), the paper's TCP-like
#: law on the TCP-like estimate and its UDP-like law on the UDP-like estimate, each re-designed at each mu.
MAP_LAWS = {"dp": "tcp", "tcp": "tcp", "udp": "udp"}


def loop_map(system: System, gamma_scales: np.ndarray, mu_scales: np.ndarray,
             laws: tuple[str, ...] = tuple(MAP_LAWS)) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each law's exact radius and average stage cost (``(G, M)`` arrays, rows gamma) on the grid
    ``gamma = s_g gamma_file / max``, ``mu = s_m mu_file / max``
    ([`estimated_loop`][packetloss_cvx.sensing.loop.estimated_loop]; the filter built once per gamma; inf where the DP
    is proved to have no stabilising law (simulation.riccati.NO_SOLUTION) or the filter has no stationary gains and the
    lower bound on E[P] diverges (proved unstable), nan where the DP or the filter fails without such a proof
    (undecided, `no_gains_verdict`), the radius as [`estimated_loop`][packetloss_cvx.sensing.loop.estimated_loop] gives
    it otherwise). The data of the (gamma, mu) figure and of ``region --sensor-grid``. Time O(G (filter) + G M laws
    (2n)^6).

    >>> from packetloss_cvx.model.sensor import Sensor
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[0.0],
    ...            noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], gamma=[1.0]))
    >>> radius, cost = loop_map(s, np.array([0.7, 0.9]), np.array([0.9]), ("dp",))["dp"]
    >>> radius[:, 0] >= 1, bool(np.isinf(cost[0, 0]))      # gamma = 0.7 < 1 - 1/a^2: no stationary filter
    (array([ True, False]), True)
    """
    require_sensor(system)
    sensor, mu0 = system.sensor, system.mu_schedule[0]
    out = {law: (np.full((len(gamma_scales), len(mu_scales)), np.inf),
                 np.full((len(gamma_scales), len(mu_scales)), np.inf)) for law in laws}
    for i, sg in enumerate(gamma_scales):
        s_gamma = system.with_sensor(sensor.with_gamma(np.clip(sg * sensor.gamma / sensor.gamma.max(), 0.0, 1.0)))
        gains = filter_gains(s_gamma)          # the filter at this gamma, shared by every mu of the row
        if gains is None:                      # inf only where proved unbounded; nan (no verdict) between the bounds
            if no_gains_verdict(s_gamma)[0] is None:
                for law in laws:
                    out[law][0][i], out[law][1][i] = np.nan, np.nan
            continue
        for j, sm in enumerate(mu_scales):
            s = s_gamma.with_mu(np.clip(sm * mu0 / mu0.max(), 0.0, 1.0))
            for law in laws:
                if law == "dp":
                    try:
                        gain = dp_riccati(s).gain
                    except NumericalError as err:   # inf only where no law is proved to exist; else no verdict
                        if not str(err).startswith(NO_SOLUTION):
                            out[law][0][i, j], out[law][1][i, j] = np.nan, np.nan
                        continue
                else:
                    gain = closed_form(s, law).gain
                loop = estimated_loop(s, gain, MAP_LAWS[law], law, gains, split=False)
                out[law][0][i, j], out[law][1][i, j] = loop.spectral_radius, loop.average_stage_cost
    return out
