"""Sweep the burstiness of the channels at fixed average delivery rates.

For each lambda = 1 - p - r the system is put behind stationary Gilbert channels with its own
time-averaged rates mu (:func:`~packetloss_cvx.markov.bursty_twin`: p = (1 - mu)(1 - lambda),
r = mu (1 - lambda)), and both protocols' plug-in laws and exact minima are evaluated.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..budgets import burstiness_work, check, estimated_seconds
from ..costs import closed_form
from ..errors import InputError
from ..model import System, check_system
from ..progress import progress_bar
from ..protocols import PROTOCOLS
from ..results import BurstinessSweep
from .compare import bursty_twin
from .exact_cost import exact_closed_form, exact_cost

__all__ = ["DEFAULT_CORRELATIONS", "burstiness_sweep"]

#: lambda from memoryless (0) to long bursts (0.95: a bad spell lasts 1 / r = 20 / mu steps on average).
DEFAULT_CORRELATIONS = (0.0, 0.25, 0.5, 0.75, 0.9, 0.95)


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
    :func:`~packetloss_cvx.budgets.burstiness_work`).

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
    try:
        values = None if isinstance(correlations, str) else np.atleast_1d(np.asarray(correlations, dtype=float))
    except (TypeError, ValueError):
        values = None
    if values is None or values.ndim != 1 or values.size < 1 or not np.all(np.isfinite(values)) or np.any(values >= 1):
        shown = repr(correlations)[:60] if values is None else np.array2string(values, separator=", ", threshold=8)
        raise InputError("correlations", f"expected a list of finite lambda = 1 - p - r < 1, found {shown}")
    check("sweep_points", values.size, "correlations", f"{values.size} values")      # before any is evaluated
    cost = burstiness_work(values.size, system.horizon, system.m, len(PROTOCOLS), n=system.n)
    check("sweep_work", cost, "correlations",
          f"{values.size} values at N = {system.horizon}, m = {system.m}")
    plugin = {p: np.empty(values.size) for p in PROTOCOLS}
    exact = {p: np.empty(values.size) for p in PROTOCOLS}
    for k, lam in enumerate(progress_bar(values, total=values.size, desc="burstiness", progress=progress,
                                                 estimate=estimated_seconds("sweep_work", cost))):
        twin = bursty_twin(system, float(lam))
        for protocol in PROTOCOLS:
            exact[protocol][k] = exact_closed_form(twin, protocol).cost
            plugin[protocol][k] = exact_cost(twin, closed_form(twin.with_mu(twin.mu_schedule), protocol).inputs,
                                              protocol)
    mu = system.mu_schedule      # a stationary channel's rate as given (a mean of N equal rows rounds)
    rate = mu[0] if np.all(mu == mu[0]) else np.clip(mu.mean(axis=0), 0.0, 1.0)
    return BurstinessSweep(correlation=values, rate=rate,
                           plugin=plugin, exact=exact)
