"""Bursty twins of a system: the same average delivery rates behind Gilbert channels of a given burstiness
lambda = 1 - p - r, for every channel (`bursty_twin`) or one (`channel_twin`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from .chain import attach_channel, chain_matrices
from .channel import GilbertElliott, MarkovChannel, gilbert_rates
from .system import System, check_system
from .validation import channel_range

__all__ = ["bursty_twin", "channel_twin", "gilbert_family"]


def gilbert_family(rate: npt.ArrayLike, correlation: float) -> tuple[np.ndarray, np.ndarray]:
    """``(p, r)`` of the Gilbert channels (h_good = 1, h_bad = 0) with long-run delivery rate ``rate`` and
    burstiness ``lambda = 1 - p - r = correlation``: ``p = (1 - mu)(1 - lambda)``, ``r = mu (1 - lambda)``
    (r / (p + r) = mu), for the sweeps (`bursty_twin`, `channel_twin`). O(size of ``rate``).

    Raises
    ------
    InputError
        ``correlation`` not a finite number below 1 (field ``correlation``); a negative one that needs p or r
        above 1 at some rate (field ``correlation``, naming the rates).

    Examples
    --------
    >>> p, r = gilbert_family([0.8], 0.5)
    >>> bool(np.allclose([p[0], r[0]], [0.1, 0.4]))
    True
    """
    lam = float(correlation)
    if not (np.isfinite(lam) and lam < 1.0):
        raise InputError("correlation", f"expected lambda = 1 - p - r < 1, found {correlation!r}")
    mu = np.clip(np.asarray(rate, dtype=float), 0.0, 1.0)
    p, r = gilbert_rates(mu, lam)
    if np.any(p > 1.0) or np.any(r > 1.0):
        raise InputError("correlation", f"lambda = {lam:g} needs p or r above 1 for the average rates "
                                        f"{np.round(mu, 6).tolist()}")
    return p, r


def bursty_twin(system: System, correlation: float) -> System:
    """``system`` behind Gilbert channels (h_good = 1, h_bad = 0) started in their stationary
    distribution, with the same average delivery rates (the time average of ``mu_schedule`` per
    channel) and ``lambda = 1 - p - r = correlation``: ``p = (1 - mu)(1 - lambda)``, ``r = mu (1 - lambda)``
    (`gilbert_family`).

    ``correlation`` must lie in [0, 1) (bursty, memoryless at 0), or be negative down to the value that
    keeps p, r <= 1. Time O(size of the system).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.8], x0=[1.0])
    >>> ch = bursty_twin(s, 0.5).channel
    >>> bool(np.allclose([ch.p[0], ch.r[0], ch.mean_rate[0]], [0.1, 0.4, 0.8]))
    True
    """
    p, r = gilbert_family(system.mu_schedule.mean(axis=0), correlation)
    return attach_channel(system, GilbertElliott(p=p, r=r))


def channel_twin(system: System, channel: int, rate: float, correlation: float) -> System:
    """``system`` with channel ``channel`` (0-based) behind the stationary Gilbert channel of long-run rate
    ``rate`` and burstiness ``correlation`` (`gilbert_family`), every other channel as the system has it:
    its own chain and start where the system has a Markov channel (read through
    `chain_matrices`), else independent losses at its time-averaged rate (a
    one-state chain, as `bursty_twin` at lambda = 0). The result carries a
    [`MarkovChannel`][packetloss_cvx.model.channel.MarkovChannel] (k_i states per channel). Time O(N m k^2).

    Raises
    ------
    InputError
        ``channel`` outside 0..m-1 (field ``channel``), ``rate`` outside [0, 1] (field ``rate``), or a
        ``correlation`` `gilbert_family` refuses.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0, 1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0, 1.0],
    ...            mu=[0.8, 0.6], x0=[1.0])
    >>> twin = channel_twin(s, 0, 0.5, 0.9)          # channel 0: p = r = 0.05; channel 1: i.i.d. at 0.6
    >>> twin.channel.sizes, twin.mu_schedule[0].tolist()
    ((2, 1), [0.5, 0.6])
    """
    system = check_system(system)
    if isinstance(channel, bool) or not isinstance(channel, int | np.integer) or not 0 <= channel < system.m:
        raise InputError("channel", f"expected {channel_range(system.m)}, found {channel!r}")
    mu = float(rate)
    if not 0.0 <= mu <= 1.0:
        raise InputError("rate", f"expected a mean delivery rate in [0, 1], found {rate!r}")
    (p,), (r,) = gilbert_family([mu], correlation)
    if system.channel is not None:
        chains = list(chain_matrices(system.channel))
    else:
        chains = [(np.ones((1, 1)), np.array([np.clip(a, 0.0, 1.0)]), np.ones(1))
                  for a in system.mu_schedule.mean(axis=0)]
    stationary = np.array([r, p]) / (p + r)                  # p + r = 1 - lambda > 0
    chains[channel] = (np.array([[1.0 - p, p], [r, 1.0 - r]]), np.array([1.0, 0.0]), stationary)
    twin = MarkovChannel(transition=[T for T, _, _ in chains], delivery=[d for _, d, _ in chains],
                         belief=[b for _, _, b in chains], prefix="channel.")
    return attach_channel(system, twin)
