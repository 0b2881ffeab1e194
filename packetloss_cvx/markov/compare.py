"""Plug-in laws against the exact minimiser under a Gilbert–Elliott channel, per protocol.

The plug-in law is the paper's law (Theorem 1, eq:opt-law-1 / eq:opt-law-2) with the chain's
predicted mu_t, which is the ``mu_schedule`` a System with a channel carries. Its loss is measured
in the protocol's exact expected cost (:func:`~packetloss_cvx.markov.exact_cost`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..costs import closed_form
from ..errors import InputError
from ..markov_channel import GilbertElliott, MarkovChannel, gilbert_rates
from ..model import System, check_system
from ..protocols import check_protocol
from ..results import MarkovSolution
from .chain import attach_channel, chain_matrices
from .exact_cost import exact_closed_form, exact_cost

__all__ = ["bursty_twin", "channel_twin", "gilbert_family", "markov_solution"]


def markov_solution(system: System, protocol: str, qp: bool = True) -> MarkovSolution:
    """The exact minimiser of ``protocol``'s expected cost (with its QP twin when ``qp``), and how
    much the plug-in law loses against it.

    Time O(N (D^3 + m^3)), D = n (1 + m) (the augmented recursion), plus one Clarabel solve with ``qp``
    (O((N m)^3 + (N n)^2 N m): the QP twin is dense).

    Raises
    ------
    CrossCheckError
        The QP and the closed form disagree.
    NumericalError, ResourceError
        As :func:`~packetloss_cvx.markov.exact_closed_form` and :func:`~packetloss_cvx.markov.exact_qp`.

    Examples
    --------
    >>> s = System(A=[[1.1]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.1]))
    >>> res = markov_solution(s, "udp", qp=False)
    >>> bool(res.relative_loss > 0 and res.exact.cost <= res.plugin_cost)
    True
    """
    system = check_system(system)
    protocol = check_protocol(protocol)
    exact = exact_closed_form(system, protocol)
    twin = None
    if qp:
        from .qp import exact_qp  # cvxpy (1.5 s to import) only where a QP is asked for

        twin = exact_qp(system, protocol, reference=exact)
    plugin = closed_form(system.with_mu(system.mu_schedule), protocol)
    plugin_cost = exact_cost(system, plugin.inputs, protocol)
    loss = plugin_cost / exact.cost - 1.0 if exact.cost > 0 else 0.0
    return MarkovSolution(protocol=protocol, exact=exact, qp=twin, plugin_cost=plugin_cost, relative_loss=loss,
                          plan_expected_cost=exact_cost(system, plugin.inputs, "udp"))


def gilbert_family(rate: npt.ArrayLike, correlation: float) -> tuple[np.ndarray, np.ndarray]:
    """``(p, r)`` of the Gilbert channels (h_good = 1, h_bad = 0) with long-run delivery rate ``rate`` and
    burstiness ``lambda = 1 - p - r = correlation``: ``p = (1 - mu)(1 - lambda)``, ``r = mu (1 - lambda)``
    (r / (p + r) = mu), for the sweeps (:func:`bursty_twin`, :func:`channel_twin`). O(size of ``rate``).

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
    (:func:`gilbert_family`).

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
    ``rate`` and burstiness ``correlation`` (:func:`gilbert_family`), every other channel as the system has it:
    its own chain and start where the system has a Markov channel (read through
    :func:`~packetloss_cvx.markov.chain.chain_matrices`), else independent losses at its time-averaged rate (a
    one-state chain, as :func:`bursty_twin` at lambda = 0). The result carries a
    :class:`~packetloss_cvx.markov_channel.MarkovChannel` (k_i states per channel). Time O(N m k^2).

    Raises
    ------
    InputError
        ``channel`` outside 0..m-1 (field ``channel``), ``rate`` outside [0, 1] (field ``rate``), or a
        ``correlation`` :func:`gilbert_family` refuses.

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
        raise InputError("channel", f"expected a channel index 0..{system.m - 1}, found {channel!r}")
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
