"""Sweep the burstiness of the channels at fixed average delivery rates, and map one channel over its mean
rate and burstiness.

For each lambda = 1 - p - r the system is put behind stationary Gilbert channels with its own
time-averaged rates mu (`bursty_twin`: p = (1 - mu)(1 - lambda),
r = mu (1 - lambda)), and both protocols' plug-in laws and exact minima are evaluated
(`burstiness_sweep`). `burstiness_map` does the same over a (mean rate × lambda) grid of one
channel, the others as the system has them (`channel_twin`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..budgets import burstiness_work, check, estimated_seconds
from ..errors import InputError
from ..lq.costs import closed_form
from ..lq.markov_cost import exact_closed_form, exact_cost
from ..model.protocols import PROTOCOLS
from ..model.system import System, check_system
from ..model.twins import bursty_twin, channel_twin, gilbert_family
from ..model.validation import channel_range
from ..progress import progress_bar
from ..results import BurstinessMap, BurstinessSweep

__all__ = ["DEFAULT_CORRELATIONS", "DEFAULT_RATES", "burstiness_map", "burstiness_sweep"]

#: lambda from memoryless (0) to long bursts (0.95: a bad spell lasts 1 / r = 20 / mu steps on average).
DEFAULT_CORRELATIONS = (0.0, 0.25, 0.5, 0.75, 0.9, 0.95)

#: mean delivery rates of a map, from rare to reliable delivery
DEFAULT_RATES = (0.5, 0.6, 0.7, 0.8, 0.9, 0.95)


def _evaluate(twin: System, plugin: dict[str, np.ndarray], exact: dict[str, np.ndarray], at: tuple) -> None:
    """Both protocols at one twin into ``plugin[p][at]`` and ``exact[p][at]``: the exact minimum
    ([`exact_closed_form`][packetloss_cvx.lq.markov_cost.exact_closed_form]: the dense route up to N m = 400, the
    augmented recursion beyond) and the exact cost of the plug-in plan (the paper's law on the twin's ``mu_schedule``).
    Time O(N (D^3 + m^3)) at most."""
    for protocol in PROTOCOLS:
        exact[protocol][at] = exact_closed_form(twin, protocol).cost
        plugin[protocol][at] = exact_cost(twin, closed_form(twin.with_mu(twin.mu_schedule), protocol).inputs,
                                          protocol)


def _correlations(correlations: Sequence[float]) -> np.ndarray:
    """``correlations`` as a 1-D array of finite lambda < 1; InputError naming ``correlations``. O(K)."""
    try:
        values = None if isinstance(correlations, str) else np.atleast_1d(np.asarray(correlations, dtype=float))
    except (TypeError, ValueError):
        values = None
    if values is None or values.ndim != 1 or values.size < 1 or not np.all(np.isfinite(values)) or np.any(values >= 1):
        shown = repr(correlations)[:60] if values is None else np.array2string(values, separator=", ", threshold=8)
        raise InputError("correlations", f"expected a list of finite lambda = 1 - p - r < 1, found {shown}")
    return values


def burstiness_sweep(system: System, correlations: Sequence[float] = DEFAULT_CORRELATIONS,
                     progress: bool | None = None) -> BurstinessSweep:
    """Both protocols' plug-in costs and exact minima over ``correlations`` at the system's average rates.

    Parameters
    ----------
    system : System
        Its time-averaged ``mu_schedule`` is the rate r / (p + r) held fixed.
    correlations : sequence of float
        lambda = 1 - p - r per point, each < 1 (and >= the value that keeps p, r <= 1 when negative).
    progress : bool, optional
        A progress bar on stderr (default: when stderr is a terminal).

    Returns
    -------
    BurstinessSweep
        ``plugin[protocol][k]``: the protocol's exact expected cost of its plug-in plan at
        ``correlation[k]``; ``exact[protocol][k]``: its exact minimum.

    Notes
    -----
    Time O(K N (D^3 + m^3)) for K points, D = n (1 + m) (the augmented recursion: any horizon; budgeted by
    `burstiness_work`).

    Examples
    --------
    >>> s = System(A=[[1.1]], B=[[1.0]], horizon=4, state_weight=[1.0], input_weight=[1.0], mu=[0.7], x0=[1.0])
    >>> sweep = burstiness_sweep(s, [0.0, 0.9], progress=False)
    >>> bool(np.isclose(sweep.plugin["udp"][0], sweep.exact["udp"][0]))       # memoryless: the plug-in law is exact
    True
    >>> bool(sweep.plugin["udp"][1] > sweep.exact["udp"][1])                   # bursty: it is not
    True
    """
    system = check_system(system)
    values = _correlations(correlations)
    check("sweep_points", values.size, "correlations", f"{values.size} values")      # before any is evaluated
    cost = burstiness_work(values.size, system.horizon, system.m, len(PROTOCOLS), n=system.n)
    check("sweep_work", cost, "correlations",
          f"{values.size} values at N = {system.horizon}, m = {system.m}")
    plugin = {p: np.empty(values.size) for p in PROTOCOLS}
    exact = {p: np.empty(values.size) for p in PROTOCOLS}
    for k, lam in enumerate(progress_bar(values, total=values.size, desc="burstiness", progress=progress,
                                                 estimate=estimated_seconds("sweep_work", cost))):
        _evaluate(bursty_twin(system, float(lam)), plugin, exact, k)
    mu = system.mu_schedule      # a stationary channel's rate as given (a mean of N equal rows rounds)
    rate = mu[0] if np.all(mu == mu[0]) else np.clip(mu.mean(axis=0), 0.0, 1.0)
    return BurstinessSweep(correlation=values, rate=rate,
                           plugin=plugin, exact=exact)


def burstiness_map(system: System, rates: Sequence[float] = DEFAULT_RATES,
                   correlations: Sequence[float] = DEFAULT_CORRELATIONS, channel: int = 0,
                   progress: bool | None = None) -> BurstinessMap:
    """Both protocols' plug-in costs and exact minima over a (mean rate × burstiness) grid of one channel.

    At each grid point channel ``channel`` is the stationary Gilbert channel (h_good = 1, h_bad = 0) of long-run
    delivery rate mu = ``rates[a]`` and lambda = 1 - p - r = ``correlations[b]`` (p = (1 - mu)(1 - lambda),
    r = mu (1 - lambda)); every other channel is as the system has it (its chain and start, or independent losses
    at its time-averaged rate: `channel_twin`).

    Parameters
    ----------
    system : System
    rates : sequence of float
        Mean delivery rates in [0, 1].
    correlations : sequence of float
        lambda per column, each < 1; a negative one must keep p, r <= 1 at every rate.
    channel : int
        The mapped channel, 0-based.
    progress : bool, optional
        A progress bar on stderr (default: when stderr is a terminal).

    Returns
    -------
    BurstinessMap
        ``exact[protocol][a, b]`` the exact minimum, ``plugin[protocol][a, b]`` the protocol's exact cost of its
        plug-in plan; ``relative_loss(protocol)`` the plug-in law's loss. At lambda = 0 the exact UDP-like minimum
        is the paper's J*_udp at the mean rate; the TCP-like plug-in law is exact everywhere.

    Raises
    ------
    InputError
        A channel outside 0..m-1, rates or correlations out of range (naming ``rates``/``correlations``); a
        grid beyond the ``sweep_points`` or ``sweep_work`` budget (BudgetError, before any point is evaluated).
    NumericalError
        As [`exact_closed_form`][packetloss_cvx.lq.markov_cost.exact_closed_form] (an exact cost beyond the double
        range).

    Notes
    -----
    Time O(R L N (D^3 + m^3)) for R rates and L values of lambda, D = n (1 + sum_i (k_i - 1)) (the augmented
    recursion per point; budgeted by `burstiness_work`), memory O(N m D).

    Examples
    --------
    >>> s = System(A=[[1.1]], B=[[1.0]], horizon=4, state_weight=[1.0], input_weight=[1.0], mu=[0.7], x0=[1.0])
    >>> grid = burstiness_map(s, rates=[0.5, 0.9], correlations=[0.0, 0.8], progress=False)
    >>> loss = grid.relative_loss("udp")           # memoryless: none; bursty: the plug-in law loses
    >>> bool(np.all(np.abs(loss[:, 0]) < 1e-12) and np.all(loss[:, 1] > 0))
    True
    """
    system = check_system(system)
    if isinstance(channel, bool) or not isinstance(channel, int | np.integer) or not 0 <= channel < system.m:
        raise InputError("channel", f"expected {channel_range(system.m)}, found {channel!r}")
    values = _correlations(correlations)
    try:
        mus = None if isinstance(rates, str) else np.atleast_1d(np.asarray(rates, dtype=float))
    except (TypeError, ValueError):
        mus = None
    if mus is None or mus.ndim != 1 or mus.size < 1 or not np.all((mus >= 0) & (mus <= 1)):
        shown = repr(rates)[:60] if mus is None else np.array2string(mus, separator=", ", threshold=8)
        raise InputError("rates", f"expected a list of mean delivery rates in [0, 1], found {shown}")
    for lam in values:          # every pair a chain: refused before any point is evaluated
        try:
            gilbert_family(mus, lam)
        except InputError as err:
            raise err.renamed("correlations") from None
    points = mus.size * values.size
    check("sweep_points", points, "rates", f"{mus.size} x {values.size} points")
    states = sum(k - 1 for k in channel_twin(system, int(channel), float(mus[0]), float(values[0])).channel.sizes)
    cost = burstiness_work(points, system.horizon, system.m, len(PROTOCOLS), n=system.n, states=states)
    check("sweep_work", cost, "rates", f"{mus.size} x {values.size} points at N = {system.horizon}, m = {system.m}")
    plugin = {p: np.empty((mus.size, values.size)) for p in PROTOCOLS}
    exact = {p: np.empty((mus.size, values.size)) for p in PROTOCOLS}
    grid = [(a, b) for a in range(mus.size) for b in range(values.size)]
    for a, b in progress_bar(grid, total=points, desc="burstiness map", progress=progress,
                             estimate=estimated_seconds("sweep_work", cost)):
        _evaluate(channel_twin(system, int(channel), float(mus[a]), float(values[b])), plugin, exact, (a, b))
    return BurstinessMap(channel=int(channel), rate=mus, correlation=values, plugin=plugin, exact=exact,
                         name=system.name)
