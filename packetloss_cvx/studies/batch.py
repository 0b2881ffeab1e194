"""The costs of many channel points of one system, one protocol: the evaluator a sweep calls.

:class:`PointEvaluator` has the contract of the batched evaluator (``CostEvaluator(system,
protocol)``, ``.costs(mus)`` with ``mus`` of shape (P, m) or (P, N, m) -> (P,)). Until that
evaluator is in the package it evaluates the points one by one with
:func:`packetloss_cvx.closed_form`, whose every cost passed its own checks; swapping it for the
batched one is the one assignment :data:`Evaluator` below.
"""

from __future__ import annotations

import numpy as np

from ..costs import closed_form
from ..errors import InputError
from ..model import System
from ..protocols import check_protocol

__all__ = ["Evaluator", "PointEvaluator"]


class PointEvaluator:
    """J*(mu) at many points of one system and protocol, one closed form per point.

    Parameters
    ----------
    system : System
        Everything but the channel is taken from it.
    protocol : {"tcp", "udp"}

    Examples
    --------
    >>> from packetloss_cvx.io import load_example
    >>> ev = PointEvaluator(load_example("two_actuator"), "tcp")
    >>> costs = ev.costs([[0.9, 0.5], [1.0, 1.0]])
    >>> bool(costs[1] < costs[0])      # Theorem 3: a better channel costs less
    True
    """

    def __init__(self, system: System, protocol: str) -> None:
        self.system = system
        self.protocol = check_protocol(protocol)

    def cost(self, mu) -> float:
        """J* at one channel (an m-vector or an N×m schedule). O(N (n^3 + m^3))."""
        return closed_form(self.system.with_mu(mu), self.protocol).cost

    def costs(self, mus) -> np.ndarray:
        """J* at each of P channels: ``mus`` of shape (P, m) or (P, N, m) -> shape (P,).

        O(P N (n^3 + m^3)).
        """
        arr = np.asarray(mus, dtype=float)
        if arr.ndim not in (2, 3):
            raise InputError("mus", f"expected shape (P, m) or (P, N, m), found {arr.shape}")
        return np.array([self.cost(mu) for mu in arr], dtype=float).reshape(arr.shape[0])


#: The evaluator sweeps use (the batched one replaces it here, with the same contract).
Evaluator = PointEvaluator
