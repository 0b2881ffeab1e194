"""Allocation behind Markov chains: the decision is each channel's mean delivery rate, moved along a one-parameter
family of chains that is proved to make the exact cost fall as the rate rises.

Per channel the family (the **k-state rule**, `chain_family`; docs/mathematics.md, "Allocation behind chains"):

* *burstiness held* for a Gilbert channel (two states, delivering always in one and never in the other, burstiness
  ``lambda = 1 - p - r`` in [0, 1)): ``p = (1 - mu)(1 - lambda)``, ``r = mu (1 - lambda)``
  (`bursty_twin`'s family), every mean rate in [0, 1];
* *deliveries scaled* for every other chain (k states, fractional deliveries, lambda < 0): the transition matrix
  held and the delivery vector scaled, ``d(mu) = d mu / mubar`` (mubar the file's mean rate), which reaches the
  mean rates ``[0, mubar / max(d)]``: the link the file describes with an independent erasure added, the loss
  a UDP-like controller can produce itself by withholding packets with a coin of its own.

``allocate`` prices beta'mu and constrains the exact expected cost under the chains,
``J*_chain(mu) = exact_closed_form(chains at mu).cost <= alpha``, with the rows ``mu_i <= mubar_i / max(d_i)`` of
the scaled channels added to the user's.

Why the UDP-like branch and bound stays certified: `J*_chain` is nonincreasing in each mu_i along both families.
Burstiness held: with ``W = Vbar U`` the exact cost is ``C + 2 W'g + W'(Omega_g + Psi) W + sum_i rho_i Q_i(W)``,
``rho_i = (1 - mu_i) / mu_i`` and ``Q_i(W) = W_i'((Omega_g)_ii ∘ L_i + Psi_i) W_i >= 0`` (L_i the Toeplitz matrix
lambda_i^|t - s|, positive semidefinite for |lambda_i| < 1, so the Schur product is): for each W the cost falls as
mu_i grows, so does its minimum over W. Deliveries scaled: for 0 <= s <= 1 the chain with deliveries ``s d`` is the
chain with ``d`` behind an independent coin that passes a packet with probability s, and the realised cost depends
on the plan and the deliveries only through the delivered inputs ``v ∘ U``; so the expected cost of a plan U under
``s d`` is the average, over the coin, of the expected costs under ``d`` of the thinned plans ``c ∘ U``, each at
least `J*(d)`: `J*`(s d) >= `J*(d)`. Neither argument bounds the UDP-like cost by the TCP-like one, so no Theorem-2
floor
is used: it is not established under a chain. The burstiness-held family is not extended to fractional deliveries:
there it is not monotone (docs/mathematics.md gives the counterexample, tested).

The TCP-like cost holds only the marginals mu_t, which a stationary chain keeps at mu: its allocation is the
Bernoulli one at the mean rates, exact for every stationary chain (any number of states), with no family.

Refused with a typed error naming the field: a given state or belief (the mean rate would not be the schedule's).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..lq.markov_cost import exact_closed_form
from ..model.chain import chain_matrices
from ..model.channel import GilbertElliott, MarkovChannel, gilbert_rates
from ..model.system import System

__all__ = ["ChainEvaluator", "ChainFamily", "chain_at", "chain_family", "chain_rates"]


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


@dataclass(frozen=True)
class ChainFamily:
    """Per channel the family of chains the allocation moves along (module docstring).

    ``lam`` (m,): the burstiness held on Gilbert channels, NaN on scaled ones; ``scaled``: per channel
    ``(T, d, mubar)`` (the file's transition, deliveries and mean rate) on scaled channels, None on Gilbert ones;
    ``top`` (m,): the highest mean rate the family reaches (1 on Gilbert channels, ``mubar / max(d)``, 0 for a
    chain that never delivers, on scaled ones).

    Examples
    --------
    >>> fam = ChainFamily.burstiness([0.5])                     # one Gilbert channel, lambda = 0.5 held
    >>> ch = fam.channel_at(np.array([0.8]))
    >>> bool(np.allclose([ch.p[0], ch.r[0], ch.mean_rate[0]], [0.1, 0.4, 0.8]))
    True
    """

    lam: np.ndarray
    scaled: tuple[tuple[np.ndarray, np.ndarray, float] | None, ...]
    top: np.ndarray

    @classmethod
    def burstiness(cls, lam) -> ChainFamily:
        """Gilbert channels with burstiness ``lam`` held (every mean rate in [0, 1]). O(m)."""
        lam = np.array(lam, dtype=float)
        return cls(lam, (None,) * lam.size, np.ones(lam.size))

    @property
    def gilbert(self) -> bool:
        """Whether every channel is a Gilbert channel with its burstiness held."""
        return all(item is None for item in self.scaled)

    def channel_at(self, mu: np.ndarray) -> MarkovChannel:
        """The chains at mean rates ``mu`` (m,), each clipped to [0, top_i]: Gilbert–Elliott channels when every
        channel is Gilbert (the numbers `chain_at` gives, written back as a Gilbert–Elliott table), else
        k-state chains. O(m K^3)."""
        mu = np.clip(np.asarray(mu, dtype=float), 0.0, self.top)
        if self.gilbert:
            p, r = gilbert_rates(mu, self.lam)
            return GilbertElliott(p=p, r=r)
        Ts, ds = [], []
        for i, item in enumerate(self.scaled):
            if item is None:
                p, r = gilbert_rates(mu[i], self.lam[i])
                Ts.append([[1.0 - p, p], [r, 1.0 - r]])
                ds.append([1.0, 0.0])
            else:
                T, d, mubar = item
                Ts.append(T)
                ds.append(np.minimum(d * (mu[i] / mubar if mubar > 0 else 0.0), 1.0))
        return MarkovChannel(transition=Ts, delivery=ds)

    def rows(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The constraints ``mu_i <= top_i`` of the channels whose family stops below 1, as ``(G, h)`` rows. O(m^2)."""
        capped = np.flatnonzero(self.top < 1.0)
        if not capped.size:
            return []
        return [(np.eye(self.top.size)[capped], self.top[capped])]

    def describe(self) -> str:
        """How each channel's chain moves with its mean rate, for the result's method note. O(m)."""
        if self.gilbert:
            return f"behind Gilbert chains, burstiness lambda = {np.round(self.lam, 6).tolist()} held"
        parts = [f"channel {i + 1} burstiness lambda = {round(float(self.lam[i]), 6)} held" if item is None
                 else f"channel {i + 1} deliveries scaled (transition held, mean rate <= {self.top[i]:.6g})"
                 for i, item in enumerate(self.scaled)]
        return "behind the chains: " + "; ".join(parts)


def _gilbert(T: np.ndarray, d: np.ndarray) -> bool:
    """Whether a chain is a Gilbert channel (two states delivering 1 and 0) with burstiness 1 - p - r in [0, 1)."""
    return d.size == 2 and sorted(d.tolist()) == [0.0, 1.0] and 0.0 <= float(T[0, 0] - T[1, 0]) < 1.0


def chain_family(system: System) -> ChainFamily:
    """The family each channel of a system behind a stationary chain moves along with its mean rate: burstiness
    held on Gilbert channels with lambda in [0, 1), deliveries scaled on every other chain (module docstring).
    O(m K^3).

    Raises
    ------
    InputError
        ``channel.state/belief``: a given start.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.02], r=[0.18]))
    >>> chain_family(s).lam.round(12).tolist()
    [0.8]
    >>> three = MarkovChannel(transition=[[[0.8, 0.2, 0.0], [0.1, 0.8, 0.1], [0.0, 0.5, 0.5]]],
    ...                       delivery=[[1.0, 0.5, 0.0]])
    >>> fam = chain_family(s.with_channel(three))         # pi = (5, 10, 2) / 17: mubar = 10/17, top = mubar / 1
    >>> fam.gilbert, bool(np.isclose(fam.top[0], 10 / 17))
    (False, True)
    """
    rates = chain_rates(system)
    burstiness = np.array(system.channel.correlation, dtype=float)     # 1 - p - r as the channel computes it
    lam = np.full(system.m, np.nan)
    scaled: list = []
    top = np.ones(system.m)
    for i, (T, d, _) in enumerate(chain_matrices(system.channel)):
        T, d = np.array(T, dtype=float), np.array(d, dtype=float)
        if _gilbert(T, d):
            lam[i] = burstiness[i]
            scaled.append(None)
            continue
        scaled.append((T, d, float(rates[i])))
        top[i] = float(rates[i]) / float(d.max()) if d.max() > 0 else 0.0
        top[i] = min(top[i], 1.0)
    return ChainFamily(lam, tuple(scaled), top)


def chain_at(system: System, lam: np.ndarray, mu: np.ndarray) -> System:
    """``system`` behind stationary Gilbert channels with mean rates ``mu`` and burstiness ``lam``. O(N m).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0], mu=[0.5])
    >>> ch = chain_at(s, np.array([0.5]), np.array([0.8])).channel
    >>> bool(np.allclose([ch.p[0], ch.r[0], ch.mean_rate[0]], [0.1, 0.4, 0.8]))
    True
    """
    return system.with_channel(ChainFamily.burstiness(lam).channel_at(mu))


class ChainEvaluator:
    """``mu -> J*_chain(mu)``, the exact UDP-like minimum with each channel's chain at mean rate mu_i along its
    family (`ChainFamily`, or an array of burstiness for Gilbert channels), with the interface the branch and
    bound uses (`cost`, `line`). Rates above a family's top are evaluated at the top (the function
    stays nonincreasing; the allocation's rows keep its answers below). Every value is self-checked by
    [`exact_closed_form`][packetloss_cvx.lq.markov_cost.exact_closed_form] (``checked`` is accepted and ignored: nothing
    is skipped). Per point the cost of ``exact_closed_form`` at the system's horizon.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0], mu=[0.5])
    >>> ev = ChainEvaluator(s, np.array([0.5]))
    >>> round(ev.cost(np.array([0.5])), 12)            # one step: no correlation to feel, J* = 1 - mu / 2
    0.75
    """

    def __init__(self, system: System, family) -> None:
        self.system = system
        self.family = family if isinstance(family, ChainFamily) else ChainFamily.burstiness(family)

    @property
    def lam(self) -> np.ndarray:
        """The burstiness held per channel (NaN on channels whose deliveries are scaled)."""
        return self.family.lam

    def cost(self, mu: np.ndarray, checked: bool = True) -> float:
        """J*_chain at the mean rates ``mu`` (m,)."""
        return float(exact_closed_form(self.system.with_channel(self.family.channel_at(mu)), "udp").cost)

    def line(self, mu: np.ndarray, i: int, checked: bool = True) -> Callable[[float], float]:
        """``s -> J*_chain(mu with mu_i = s)``."""
        base = np.array(mu, dtype=float)

        def at(value: float) -> float:
            point = base.copy()
            point[i] = value
            return self.cost(point)

        return at
