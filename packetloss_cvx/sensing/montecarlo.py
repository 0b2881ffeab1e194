"""Monte Carlo of a law ``u = -K xhat`` on an estimated state: the plant, the lossy actuator and sensor links,
and the filter (sensing.kalman) run together, every step one array operation over the runs.

``filter="kalman"``: the time-varying filter with intermittent observations (each run its own P_k; the
UDP-like prediction adds the actuation covariance of its own u). ``filter="stationary"``: the fixed pattern gains
of sensing.loop, whose exact stationary cost the run is checked against. The stage cost
``x'Omega x + (V u)'Psi (V u)`` is averaged over the second half of the steps (the first half is the transient),
the standard error from the runs' means (independent runs). Arrivals are Bernoulli draws or, behind
Gilbert–Elliott sensor links, sampled from the chains (sensing.arrivals.ChainSampler). ``sampled_covariance``
samples the filter's covariances alone (no loop): E[P_k] with standard errors past the exact enumeration.
"""

from __future__ import annotations

import numpy as np

from ..budgets import check, simulate_work
from ..closedloop.moments import stationary_channel
from ..closedloop.tails import error_bar_reason
from ..errors import InputError
from ..linalg import psd_factor
from ..model.sensor import Sensor
from ..model.system import System, loop_weights
from ..montecarlo.runs import z_score
from ..results.sensing import EstimatedRun, SampledCovariance
from .arrivals import ChainSampler, arrival_patterns
from .kalman import actuation_covariance, measurement_update, pattern_rows, predict
from .loop import LOOP_MAX_N, estimated_loop, filter_gains, loop_error_bar_reason, require_sensor, window_costs

__all__ = ["FILTERS", "pattern_update", "sampled_covariance", "simulate_estimated"]

#: The filters a run can use.
FILTERS = ("kalman", "stationary")


def _noise(rng: np.random.Generator, factor: np.ndarray, samples: int) -> np.ndarray:
    """``samples`` draws of N(0, F'F) for the factor ``F = psd_factor(cov)`` (factored once per run, not per step)."""
    if factor.shape[0] == 0:
        return np.zeros((samples, factor.shape[1]))
    return rng.standard_normal((samples, factor.shape[0])) @ factor


def simulate_estimated(system: System, gain: np.ndarray, protocol: str, filter: str = "kalman",  # noqa: A002
                       samples: int = 2000, steps: int = 200, seed: int = 0, law: str = "") -> EstimatedRun:
    """``samples`` runs of ``steps`` steps of ``u = -K xhat`` from ``x_0 ~ N(x0, P0)`` (module docstring).

    Returns the mean stage cost over the second half and its standard error (nan with ``stderr_reason`` where the
    loop's fourth moments grow or are not proved bounded: `_error_bar_reason`), the exact expectation of that same
    average and the sample's z-score against it (the "stationary" filter: sensing.loop.window_costs, up to n =
    LOOP_MAX_N; nan otherwise), the exact stationary cost (the law run for ever: not the sample's window)
    (the "stationary" filter: sensing.loop; the "kalman" filter: nan with the reason), whether the loop is proved
    stable (the fixed-gain loop's radius; for the Kalman filter None: no exact verdict for a time-varying gain),
    and the mean of the filter's own covariance P_k over the kept steps with its per-entry standard error and the
    standard error of its trace (each from the runs' own means over the kept steps, the runs independent; Kalman
    only; nan otherwise). Gilbert–Elliott sensor links: the Kalman filter only, arrivals sampled from the chains.
    Time O(samples steps (2^g + n (n^2 + p^2))).

    Raises
    ------
    InputError
        No sensor, an unknown filter or protocol, steps < 2; the stationary filter behind Gilbert–Elliott links.
    BudgetError
        Beyond the ``simulate_work`` budget.
    """
    require_sensor(system, chains=True)
    if filter not in FILTERS:
        raise InputError("filter", f"expected one of {', '.join(FILTERS)}, found {filter!r}")
    if protocol not in ("tcp", "udp"):
        raise InputError("protocol", f"expected tcp or udp, found {protocol!r}")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 2:
        raise InputError("steps", f"expected an integer >= 2, found {steps!r}")
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 2:
        raise InputError("samples", f"expected an integer >= 2, found {samples!r}")
    n, m = system.n, system.m
    check("simulate_work", simulate_work(samples, steps, 1, n + system.sensor.p, m, plans=0, laws=n), "samples",
          f"{samples} runs of {steps} steps with a filter")
    mu = stationary_channel(system)
    sensor = system.sensor
    K = np.asarray(gain, dtype=float)
    A, B, C, Sigma_W, R = system.A, system.B, sensor.C, system.noise_cov, sensor.noise_cov
    Omega, psi = loop_weights(system)
    arrived, _ = arrival_patterns(sensor.gamma)
    rows = [pattern_rows(sensor, a) for a in arrived]
    digits = 2 ** np.arange(sensor.g - 1, -1, -1)        # itertools.product order: channel 0 most significant
    exact, reason, stable = float("nan"), "the time-varying filter has no exact stationary cost: Monte Carlo", None
    window = float("nan")
    if sensor.channel is not None and filter == "stationary":
        raise InputError("sensor.model", "stationary filter gains behind Gilbert-Elliott sensor links are not derived "
                                         "(the loop would be a Markov jump system): use filter='kalman'")
    if filter == "stationary":
        fixed = filter_gains(system)
        if fixed is None:
            raise InputError("sensor.gamma", "the filter has no stationary gains at this gamma (the expected Riccati "
                                             "iteration diverges): use filter='kalman'")
        gains = fixed[1]
        loop = estimated_loop(system, K, protocol, law)
        exact, reason, stable = loop.average_stage_cost, loop.reason, loop.stable
        # the exact expectation of the sample's own average (the kept steps from x0), where the moments are formed
        window = (float(window_costs(system, K, protocol, steps, fixed)[steps - steps // 2:].mean())
                  if n <= LOOP_MAX_N else float("nan"))
    R_factor, W_factor = psd_factor(R), psd_factor(Sigma_W)
    rng = np.random.default_rng(seed)
    x = system.x0 + _noise(rng, psd_factor(sensor.P0), samples)
    xm = np.broadcast_to(system.x0, (samples, n)).copy()
    Pm = np.broadcast_to(sensor.P0, (samples, n, n)).copy()
    keep = steps // 2
    total = np.zeros(samples)
    covariance = np.zeros((n, n))
    per_run = np.zeros((samples, n, n))              # each run's sum of P_k over the kept steps: the standard error
    sampler = None if sensor.channel is None else ChainSampler(sensor, rng, samples)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(steps):
            a = rng.random((samples, sensor.g)) < sensor.gamma if sampler is None else sampler.step()
            y = x @ C.T + _noise(rng, R_factor, samples)
            pattern = a @ digits
            if filter == "kalman":
                P, L = pattern_update(Pm, pattern, rows, C, R)
            else:
                L = gains[pattern]
            xhat = xm + np.einsum("sij,sj->si", L, y - xm @ C.T)
            u = -xhat @ K.T
            v = rng.random((samples, m)) < mu
            applied = v * u
            if k >= steps - keep:           # the stage cost of the kept half only (the transient's is never read)
                total += np.einsum("si,ij,sj->s", x, Omega, x) + (applied * applied) @ psi
                if filter == "kalman":
                    covariance += P.sum(axis=0)
                    per_run += P
            x = x @ A.T + applied @ B.T + _noise(rng, W_factor, samples)
            xm = xhat @ A.T + (applied if protocol == "tcp" else mu * u) @ B.T
            if filter == "kalman":
                # A P_s A' for every run: the stacked A @ P, then one (samples n) x n product by A' in place of
                # samples small ones (the same products in another order, tested to ROUNDING_ORDER_RTOL; fewer
                # calls at n = 2-4)
                Pm = (np.matmul(A, P).reshape(-1, n) @ A.T).reshape(P.shape) + Sigma_W
                if protocol == "udp":
                    Pm += actuation_covariance(B, mu, u)
    means = total / keep
    mean = float(means.mean())
    no_bar = _error_bar_reason(system, K, protocol, None if filter == "kalman" else fixed)
    with np.errstate(over="ignore"):        # squares beyond a float: stderr inf, which callers refuse (no z)
        stderr = float("nan") if no_bar else float(means.std(ddof=1) / np.sqrt(samples))
    if filter == "kalman":
        covariance = covariance / (keep * samples)
        run_means = per_run / keep
        cov_stderr = run_means.std(axis=0, ddof=1) / np.sqrt(samples)
        trace_stderr = float(np.trace(run_means, axis1=1, axis2=2).std(ddof=1) / np.sqrt(samples))
    else:
        covariance = cov_stderr = np.full((n, n), np.nan)
        trace_stderr = float("nan")
    z = float("nan") if no_bar else z_score(mean, stderr, window)
    return EstimatedRun(law, protocol, filter, mean, stderr, exact, stable, covariance, samples, steps, reason,
                        cov_stderr, trace_stderr, no_bar, window, z)


#: Why the time-varying filter's run has no error bar where the law's full-state loop has none.
KALMAN_NO_BAR = ("no error bar: the state's own loop x+ = (A - B V K) x + B V K e + w holds the law's full-state loop "
                 "over the actuator links; in that loop {}")


def _error_bar_reason(system: System, gain: np.ndarray, protocol: str,
                      gains: tuple[np.ndarray, np.ndarray, np.ndarray] | None) -> str:
    """Why the sample gets no error bar ("" when it gets one). The stationary filter (``gains``): the fourth moments
    of its exact loop (xhat, e) (sensing.loop.loop_error_bar_reason). The time-varying filter (None): those of the
    law's full-state loop, which the state's loop contains (``x+ = (A - BVK) x + BVK e + w`` with V independent of
    x and e): where they grow the state's do; where they are bounded the filter's error moments are not derived
    and the spread is kept as the error bar. O(tails.fourth_moment_radius)."""
    if gains is not None:
        return loop_error_bar_reason(system, gain, protocol, gains)
    why = error_bar_reason(system.A, system.B, gain, stationary_channel(system))
    return KALMAN_NO_BAR.format(why.removeprefix("no error bar: ")) if why else ""


def pattern_update(Pm: np.ndarray, pattern: np.ndarray, rows: list[np.ndarray], C: np.ndarray,
                   R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The measurement update of each run (``Pm`` (samples, n, n)) with the rows of its arrival ``pattern``
    (indices into ``rows``, the pattern's rows), one
    [`.kalman.measurement_update`][packetloss_cvx.sensing.kalman.measurement_update] per pattern present. Returns P
    (samples, n, n) and the gains (samples, n, p). O(samples (n^2 p + p^3))."""
    samples = Pm.shape[0]
    # a run that received nothing keeps P = P^-, L = 0 (the update's own answer, without the call); a pattern most
    # runs share is computed for every run and kept where it arrived (each run's update is its own: a gathered
    # update's values, to rounding), cheaper than gathering and scattering most of the stack: the fresh update takes
    # the other runs' values in place (the first such pattern; two can hold half the runs each: the second is then
    # scattered)
    counts = np.bincount(pattern, minlength=len(rows))
    major = next((j for j, r in enumerate(rows) if r.size and 2 * counts[j] >= samples), None)
    if major is None:
        P, L = Pm.copy(), np.zeros((*Pm.shape[:-1], C.shape[0]))
    else:
        P, L = measurement_update(Pm, C, R, rows[major])
        other = (pattern != major)[:, None, None]
        np.copyto(P, Pm, where=other)
        np.copyto(L, 0.0, where=other)
    for j, r in enumerate(rows):
        if r.size and j != major and counts[j]:
            sel = pattern == j
            P[sel], L[sel] = measurement_update(Pm[sel], C, R, r)
    return P, L


def sampled_covariance(A: np.ndarray, Sigma_W: np.ndarray, sensor: Sensor, steps: int, samples: int = 2000,
                       seed: int = 0) -> SampledCovariance:
    """E[P^-_k] and E[P_k] (TCP-like filter, k = 0..steps) by sampling ``samples`` arrival paths of the sensor
    (Bernoulli draws as [`simulate_estimated`][packetloss_cvx.sensing.montecarlo.simulate_estimated]'s, or
    Gilbert–Elliott chains, `.arrivals.ChainSampler`) with the per-entry standard error of each mean (independent
    paths): the Monte Carlo counterpart of
    [`.kalman.expected_covariance`][packetloss_cvx.sensing.kalman.expected_covariance] for horizons past its
    enumeration. Time O(samples steps (n^3 + p^3)).

    Raises
    ------
    InputError
        ``steps`` or ``samples`` not an integer >= 1 (>= 2 for samples).
    BudgetError
        Beyond the ``simulate_work`` budget.

    Examples
    --------
    >>> s = Sensor(C=[[1.0]], gamma=[1.0], noise_cov=[[1.0]], P0=[[1.0]])      # every packet arrives: no spread
    >>> out = sampled_covariance(np.array([[1.0]]), np.array([[1.0]]), s, 1, samples=4)
    >>> float(out.filtered[0, 0, 0]), float(out.filtered_stderr[0, 0, 0])    # 1 / (1 + 1)
    (0.5, 0.0)
    """
    if isinstance(steps, bool) or not isinstance(steps, int | np.integer) or steps < 1:
        raise InputError("steps", f"expected an integer >= 1, found {steps!r}")
    if isinstance(samples, bool) or not isinstance(samples, int | np.integer) or samples < 2:
        raise InputError("samples", f"expected an integer >= 2, found {samples!r}")
    n = A.shape[0]
    check("simulate_work", simulate_work(samples, steps, 1, n + sensor.p, 1, plans=0, laws=n), "samples",
          f"{samples} filter paths of {steps} steps")
    rng = np.random.default_rng(seed)
    arrived, _ = arrival_patterns(sensor.gamma)
    rows = [pattern_rows(sensor, a) for a in arrived]
    digits = 2 ** np.arange(sensor.g - 1, -1, -1)
    sampler = None if sensor.channel is None else ChainSampler(sensor, rng, samples)
    Pm = np.broadcast_to(sensor.P0, (samples, n, n)).copy()
    predicted, filtered = [Pm], []
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(steps):
            a = rng.random((samples, sensor.g)) < sensor.gamma if sampler is None else sampler.step()
            P, _ = pattern_update(Pm, a @ digits, rows, sensor.C, sensor.noise_cov)
            Pm = predict(P, A, Sigma_W)
            filtered.append(P)
            predicted.append(Pm)

    def stats(stack: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        arr = np.stack(stack)                               # (steps, samples, n, n)
        return arr.mean(axis=1), arr.std(axis=1, ddof=1) / np.sqrt(samples)

    (pm, pse), (fm, fse) = stats(predicted), stats(filtered)
    return SampledCovariance(pm, pse, fm, fse, int(samples))
