"""Monte Carlo of a law ``u = -K xhat`` on an estimated state: the plant, the lossy actuator and sensor links,
and the filter (sensing.kalman) run together, every step one array operation over the runs.

``filter="kalman"``: the time-varying filter with intermittent observations (each run its own P_k; the
UDP-like prediction adds the actuation covariance of its own u). ``filter="stationary"``: the fixed pattern gains
of sensing.loop, whose exact stationary cost the run is checked against. The stage cost
``x'Omega x + (V u)'Psi (V u)`` is averaged over the second half of the steps (the first half is the transient),
the standard error from the runs' means (independent runs).
"""

from __future__ import annotations

import numpy as np

from ..budgets import check, simulate_work
from ..errors import InputError
from ..linalg import psd_factor
from ..model import System
from ..results.sensing import EstimatedRun
from ..simulation.moments import stationary_channel
from .kalman import actuation_covariance, arrival_patterns, measurement_update, pattern_rows
from .loop import estimated_loop, filter_gains, require_sensor

__all__ = ["FILTERS", "simulate_estimated"]

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

    Returns the mean stage cost over the second half and its standard error, the exact stationary cost
    (the "stationary" filter: sensing.loop; the "kalman" filter: nan with the reason), whether the loop is proved
    stable (the fixed-gain loop's radius; for the Kalman filter None: no exact verdict for a time-varying gain),
    and the mean of the filter's own covariance P_k over the kept steps (Kalman only; nan otherwise).
    Time O(samples steps (2^g + n (n^2 + p^2))).

    Raises
    ------
    InputError
        No Bernoulli sensor, an unknown filter or protocol, steps < 2.
    BudgetError
        Beyond the ``simulate_work`` budget.
    """
    require_sensor(system)
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
    Omega, psi = system.state_weights[0], system.input_weights[0]
    arrived, _ = arrival_patterns(sensor.gamma)
    rows = [pattern_rows(sensor, a) for a in arrived]
    digits = 2 ** np.arange(sensor.g - 1, -1, -1)        # itertools.product order: channel 0 most significant
    exact, reason, stable = float("nan"), "the time-varying filter has no exact stationary cost: Monte Carlo", None
    if filter == "stationary":
        fixed = filter_gains(system)
        if fixed is None:
            raise InputError("sensor.gamma", "the filter has no stationary gains at this gamma (the expected Riccati "
                                             "iteration diverges): use filter='kalman'")
        gains = fixed[1]
        loop = estimated_loop(system, K, protocol, law)
        exact, reason, stable = loop.average_stage_cost, loop.reason, loop.stable
    R_factor, W_factor = psd_factor(R), psd_factor(Sigma_W)
    rng = np.random.default_rng(seed)
    x = system.x0 + _noise(rng, psd_factor(sensor.P0), samples)
    xm = np.broadcast_to(system.x0, (samples, n)).copy()
    Pm = np.broadcast_to(sensor.P0, (samples, n, n)).copy()
    keep = steps // 2
    total = np.zeros(samples)
    covariance = np.zeros((n, n))
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(steps):
            a = rng.random((samples, sensor.g)) < sensor.gamma
            y = x @ C.T + _noise(rng, R_factor, samples)
            pattern = a @ digits
            if filter == "kalman":
                # a run that received nothing keeps P = P^-, L = 0 (the update's own answer, without the call); a
                # pattern most runs share is computed for every run and kept where it arrived (each run's update
                # is its own: the same floats), cheaper than gathering and scattering most of the stack
                P = Pm.copy()
                L = np.zeros((samples, n, sensor.p))
                for j, r in enumerate(rows):
                    if r.size == 0:
                        continue
                    sel = pattern == j
                    if 2 * np.count_nonzero(sel) >= samples:
                        Pj, Lj = measurement_update(Pm, C, R, r)
                        P, L = np.where(sel[:, None, None], Pj, P), np.where(sel[:, None, None], Lj, L)
                    elif np.any(sel):
                        P[sel], L[sel] = measurement_update(Pm[sel], C, R, r)
            else:
                L = gains[pattern]
            xhat = xm + np.einsum("sij,sj->si", L, y - xm @ C.T)
            u = -xhat @ K.T
            v = rng.random((samples, m)) < mu
            applied = v * u
            stage = np.einsum("si,ij,sj->s", x, Omega, x) + (applied * applied) @ psi
            if k >= steps - keep:
                total += stage
                if filter == "kalman":
                    covariance += P.sum(axis=0)
            x = x @ A.T + applied @ B.T + _noise(rng, W_factor, samples)
            xm = xhat @ A.T + (applied if protocol == "tcp" else mu * u) @ B.T
            if filter == "kalman":
                # A P_s A' for every run: the stacked A @ P, then one (samples n) x n product by A' in place of
                # samples small ones (the same floats, tested; 2-3x faster at n = 2-4)
                Pm = (np.matmul(A, P).reshape(-1, n) @ A.T).reshape(P.shape) + Sigma_W
                if protocol == "udp":
                    Pm += actuation_covariance(B, mu, u)
    means = total / keep
    mean = float(means.mean())
    stderr = float(means.std(ddof=1) / np.sqrt(samples))
    covariance = covariance / (keep * samples) if filter == "kalman" else np.full((n, n), np.nan)
    return EstimatedRun(law, protocol, filter, mean, stderr, exact, stable, covariance, samples, steps, reason)
