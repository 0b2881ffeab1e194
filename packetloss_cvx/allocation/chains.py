"""Allocation behind Markov chains: the decision is each channel's mean delivery rate, its burstiness held fixed.

A Gilbert channel (two states, delivering always in one and never in the other) started in its stationary
distribution is fixed by its mean rate mu and its burstiness ``lambda = 1 - p - r``: ``p = (1 - mu)(1 - lambda)``,
``r = mu (1 - lambda)`` (:func:`~packetloss_cvx.markov.bursty_twin`'s family). ``allocate`` chooses mu with
lambda held at the file's value; its price is beta'mu and its constraint the exact expected cost under the chain,
``J*_chain(mu) = exact_closed_form(chain at mu).cost <= alpha``.

Why the UDP-like branch and bound stays certified (docs/design.md, "Allocation behind chains"): with
``W = Vbar U`` the exact cost is ``C + 2 W'g + W'(Omega_g + Psi) W + sum_i rho_i Q_i(W)``, with
``rho_i = (1 - mu_i) / mu_i`` and ``Q_i(W) = W_i'((Omega_g)_ii ∘ L_i + Psi_i) W_i >= 0`` (L_i the Toeplitz
matrix lambda_i^|t - s|, positive semidefinite for |lambda_i| < 1, so the Schur product is). For each W the cost
falls as any mu_i grows, so does its minimum over W: J*_chain is nonincreasing in each mu_i, the monotonicity
(Theorem 3's role) that the branch and bound's proofs rest on. The TCP-like relaxation (Theorem 2) is not used as a
bound: it is not established under a chain.

The TCP-like cost holds only the marginals mu_t, which a stationary chain keeps at mu: its allocation is the
Bernoulli one at the mean rates, exact for every stationary chain (any number of states).

Refused with a typed error naming the field: a given state or belief (the mean rate would not be the schedule's),
for UDP-like: more or fewer than two states, deliveries other than 1 and 0 (with ``h_bad > 0`` the covariance per
mu^2 can rise with mu: no monotonicity), and lambda < 0 (not every mean rate has such a chain).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..channel import GilbertElliott
from ..errors import InputError
from ..markov import exact_closed_form
from ..markov_channel import MarkovChannel
from ..model import System

__all__ = ["ChainEvaluator", "chain_at", "chain_burstiness", "chain_rates"]


def chain_rates(system: System) -> np.ndarray:
    """The mean delivery rates of a system's chain, after checking it starts stationary. O(m K^3).

    Raises
    ------
    InputError
        ``channel.state/belief``: the chain does not start in its stationary distribution.
    """
    ch = system.channel
    if ch.belief is not None:
        raise InputError("channel.state/belief", "allocation over a chain chooses its long-run mean rates, which a "
                                                 "given state or belief moves away from: give neither (the "
                                                 "stationary start)")
    return np.array(ch.mean_rate, dtype=float)


def chain_burstiness(system: System) -> np.ndarray:
    """lambda = 1 - p - r per channel of a system behind stationary Gilbert channels (h = 1 and 0, a two-state
    ``markov`` twin alike), in [0, 1). O(m).

    Raises
    ------
    InputError
        Naming the field: not two states, deliveries other than 1 and 0, lambda < 0, or a given start.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.02], r=[0.18]))
    >>> chain_burstiness(s).round(12).tolist()
    [0.8]
    """
    chain_rates(system)
    ch = system.channel
    if isinstance(ch, MarkovChannel):
        field = "channel.delivery"
        if any(k != 2 for k in ch.sizes):
            raise InputError("channel.transition", f"UDP-like allocation over a chain needs two-state (Gilbert) "
                                                   f"channels, found {list(ch.sizes)} states: mean rate and "
                                                   "burstiness fix only a two-state chain (TCP-like allocation "
                                                   "takes any stationary chain)")
        gilbert = all(sorted(d.tolist()) == [0.0, 1.0] for d in ch.delivery)
    else:
        field = "channel.h_good/h_bad"
        gilbert = bool(np.all((ch.h_good == 1) & (ch.h_bad == 0)))
    if not gilbert:
        raise InputError(field, "UDP-like allocation over a chain needs Gilbert channels (delivery 1 in one state, "
                                "0 in the other): otherwise the exact cost need not fall as a mean rate rises, and "
                                "the branch and bound's certificate rests on that")
    lam = np.array(ch.correlation, dtype=float)
    if np.any(lam < 0) or np.any(lam >= 1):
        raise InputError("channel.p" if isinstance(ch, GilbertElliott) else "channel.transition",
                         f"UDP-like allocation over a chain needs burstiness lambda = 1 - p - r in [0, 1), found "
                         f"{np.round(lam, 6).tolist()}: with lambda < 0 not every mean rate has such a chain")
    return lam


def chain_at(system: System, lam: np.ndarray, mu: np.ndarray) -> System:
    """``system`` behind stationary Gilbert channels with mean rates ``mu`` and burstiness ``lam``. O(N m).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0], mu=[0.5])
    >>> ch = chain_at(s, np.array([0.5]), np.array([0.8])).channel
    >>> bool(np.allclose([ch.p[0], ch.r[0], ch.mean_rate[0]], [0.1, 0.4, 0.8]))
    True
    """
    mu = np.clip(np.asarray(mu, dtype=float), 0.0, 1.0)
    return system.with_channel(GilbertElliott(p=(1.0 - mu) * (1.0 - lam), r=mu * (1.0 - lam)))


class ChainEvaluator:
    """``mu -> J*_chain(mu)``, the exact UDP-like minimum under Gilbert channels with burstiness ``lam`` held, with
    the interface the branch and bound uses (:meth:`cost`, :meth:`line`). Every value is self-checked by
    :func:`~packetloss_cvx.markov.exact_closed_form` (``checked`` is accepted and ignored: nothing is skipped).
    Per point the cost of ``exact_closed_form`` at the system's horizon.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0], mu=[0.5])
    >>> ev = ChainEvaluator(s, np.array([0.5]))
    >>> round(ev.cost(np.array([0.5])), 12)            # one step: no correlation to feel, J* = 1 - mu / 2
    0.75
    """

    def __init__(self, system: System, lam: np.ndarray) -> None:
        self.system, self.lam = system, np.asarray(lam, dtype=float)

    def cost(self, mu: np.ndarray, checked: bool = True) -> float:
        """J*_chain at the mean rates ``mu`` (m,)."""
        return float(exact_closed_form(chain_at(self.system, self.lam, mu), "udp").cost)

    def line(self, mu: np.ndarray, i: int, checked: bool = True) -> Callable[[float], float]:
        """``s -> J*_chain(mu with mu_i = s)``."""
        base = np.array(mu, dtype=float)

        def at(value: float) -> float:
            point = base.copy()
            point[i] = value
            return self.cost(point)

        return at
