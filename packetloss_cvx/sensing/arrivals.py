"""The sensor channels' arrival process as one finite-state chain: Bernoulli channels are a chain of one state,
Gilbert–Elliott channels (``[sensor] model = "gilbert-elliott"``) the product of their two-state chains.

With ``S_k`` the joint state (``2^g`` states for g Gilbert–Elliott channels, ordered as ``itertools.product``
over (good, bad), channel 0 most significant), the arrival pattern ``a_k`` of step k is drawn from
``emission[S_k]`` (channel j delivers with ``h_good_j`` in its good state, ``h_bad_j`` in its bad one,
independently), and then ``S_{k+1} ~ transition[S_k]``; ``S_0 ~ initial`` (the file's belief or state, else the
stationary distribution: `packetloss_cvx.model.chain.chain_matrices`). Given ``S_k``, ``a_k`` is
independent of the past and of ``S_{k+1}``: the two facts the expected covariance's recursions
([`.kalman.expected_covariance`][packetloss_cvx.sensing.kalman.expected_covariance]) and the Markov bounds
([`.markov_bounds`][packetloss_cvx.sensing.markov_bounds]) rest on.

The sampler draws each Gilbert–Elliott channel's state and arrival per run (Monte Carlo); Bernoulli runs keep
their own draws (``rng.random((samples, g)) < gamma``) in [`.montecarlo`][packetloss_cvx.sensing.montecarlo], so seeded
results do not move.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..closedloop.mjls import product_chain
from ..errors import InputError
from ..model.sensor import Sensor

__all__ = ["PATTERN_MAX_CHANNELS", "Arrivals", "ChainSampler", "arrival_patterns", "sensor_arrivals"]

#: More sensor channels than this are refused by the pattern enumeration (2^g patterns per step).
PATTERN_MAX_CHANNELS = 10


def arrival_patterns(gamma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All ``2^g`` arrival patterns (bool, (2^g, g), row k the binary digits of k) and their probabilities
    ``prod_j gamma_j^a_j (1 - gamma_j)^(1 - a_j)``. Time O(2^g g).

    >>> arrived, prob = arrival_patterns(np.array([0.9, 0.5]))
    >>> arrived.astype(int).tolist(), np.round(prob, 12).tolist()
    ([[0, 0], [0, 1], [1, 0], [1, 1]], [0.05, 0.05, 0.45, 0.45])
    """
    g = gamma.size
    if g > PATTERN_MAX_CHANNELS:
        raise InputError("sensor.groups", f"expected at most {PATTERN_MAX_CHANNELS} sensor channels (2^g arrival "
                                          f"patterns are enumerated), found {g}")
    arrived = np.array(list(itertools.product((False, True), repeat=g)), dtype=bool).reshape(-1, g)
    prob = np.prod(np.where(arrived, gamma, 1.0 - gamma), axis=1)
    return arrived, prob


@dataclass(frozen=True)
class Arrivals:
    """The arrival chain of a sensor (module docstring).

    ``patterns`` (2^g, g) bool, as [`arrival_patterns`][packetloss_cvx.sensing.arrivals.arrival_patterns] (row 0: every
    channel lost); ``initial`` (S,) the distribution of ``S_0``; ``transition`` (S, S) row-stochastic; ``emission`` (S,
    2^g) ``P(a_k = pattern | S_k = s)``; ``limit`` (S,) the limit of the state distribution, None when it has none
    (a channel with p = r = 1 alternates for ever)."""

    patterns: np.ndarray
    initial: np.ndarray
    transition: np.ndarray
    emission: np.ndarray
    limit: np.ndarray | None

    @property
    def states(self) -> int:
        """Number of joint states S."""
        return self.initial.size

    def distributions(self, steps: int) -> np.ndarray:
        """The state distributions of steps 0..steps-1, (steps, S). O(steps S^2)."""
        out = np.empty((steps, self.states))
        pi = self.initial
        for k in range(steps):
            out[k] = pi
            pi = pi @ self.transition
        return out

    def loss_matrix(self) -> np.ndarray:
        """``Lambda = diag(P(all lost | s)) T``: ``pi Lambda^i 1`` is the probability of i losses of every channel
        in a row from ``S ~ pi``. O(S^2)."""
        return self.emission[:, 0][:, None] * self.transition


def sensor_arrivals(sensor: Sensor) -> Arrivals:
    """The arrival chain of ``sensor``: one state for Bernoulli channels (``emission`` = the pattern
    probabilities of [`arrival_patterns`][packetloss_cvx.sensing.arrivals.arrival_patterns]), the product chain for
    Gilbert–Elliott ones. Time O(4^g g).

    Examples
    --------
    >>> ch = {"model": "gilbert-elliott", "p": [0.1], "r": [0.4], "h_good": [0.9], "h_bad": [0.2]}
    >>> arr = sensor_arrivals(Sensor(C=[[1.0]], channel=ch))
    >>> arr.transition.tolist(), arr.emission.round(12).tolist(), arr.initial.round(12).tolist()
    ([[0.9, 0.1], [0.4, 0.6]], [[0.1, 0.9], [0.8, 0.2]], [0.8, 0.2])
    >>> sensor_arrivals(Sensor(C=[[1.0]], gamma=[0.7])).emission.round(12).tolist()
    [[0.3, 0.7]]
    """
    patterns, prob = arrival_patterns(sensor.gamma)
    if sensor.channel is None:
        one = np.ones(1)
        return Arrivals(patterns, one, np.ones((1, 1)), prob[None, :], one)
    _, T, deliver, initial = product_chain(sensor.channel)      # joint states (good, bad per channel), (S, g)
    emission = np.prod(np.where(patterns[None, :, :], deliver[:, None, :], 1.0 - deliver[:, None, :]), axis=2)
    ch = sensor.channel
    lam = 1.0 - ch.p - ch.r
    limit = None
    if not np.any(lam == -1.0):
        good = np.where(lam == 1.0, ch.initial_belief[:, 0], ch.stationary[:, 0])     # p = r = 0: it keeps its state
        limit = np.ones(1)
        for b in good:
            limit = np.kron(limit, np.array([b, 1.0 - b]))
    return Arrivals(patterns, initial, T, emission, limit)


class ChainSampler:
    """Gilbert–Elliott arrivals for ``samples`` independent runs: `step` returns each run's arrivals
    (samples, g) of this step and moves every channel's state. O(samples g) per step.

    >>> ch = {"model": "gilbert-elliott", "p": [0.0], "r": [0.0], "state": ["bad"]}
    >>> s = ChainSampler(Sensor(C=[[1.0]], channel=ch), np.random.default_rng(0), 3)
    >>> s.step().ravel().tolist()          # h_bad = 0 and the chain never leaves the bad state
    [False, False, False]
    """

    def __init__(self, sensor: Sensor, rng: np.random.Generator, samples: int) -> None:
        ch = sensor.channel
        self._ch, self._rng = ch, rng
        self.states = ch.draw_start(rng.random((samples, ch.m)))

    def step(self) -> np.ndarray:
        ch, rng = self._ch, self._rng
        arrived = rng.random(self.states.shape) < ch.padded_delivery[np.arange(ch.m), self.states]
        self.states = ch.draw_next(self.states, rng.random(self.states.shape))
        return arrived
