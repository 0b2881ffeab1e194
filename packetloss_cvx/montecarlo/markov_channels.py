"""Markov channels sampled: state paths of the chains, the deliveries they produce, and
the realised cost of an open-loop plan under them (the Monte Carlo reference for the exact cost).

The chains of different channels are independent; each starts from the channel's initial belief
(given, or the stationary distribution) and moves by its transition matrix: states are indices, int, drawn by
inverting the cumulative distribution of the current row with one uniform number, so state 0 iff
u < P(state 0) (Gilbert–Elliott: good iff u < 1 - p from good, u < r from bad).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..linalg import psd_factor
from ..lq.costs import check_inputs
from ..model.channel import (
    GilbertElliott,  # noqa: F401 (GilbertElliott: the doctests' constructor)
    MarkovChannel,
)
from ..model.system import System

__all__ = [
    "reveals_state", "sample_markov_deliveries", "sample_markov_paths", "sample_markov_plan_costs", "sample_states",
    "state_delivery",
]


def _count(value: int, field: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InputError(field, f"expected an integer >= 1, found {value!r}")
    return int(value)


def state_delivery(channel: MarkovChannel, states: np.ndarray) -> np.ndarray:
    """The delivery probability ``d_i[state]`` of each sampled state index; same shape (..., m). O(size).

    Examples
    --------
    >>> state_delivery(GilbertElliott(p=[0.1], r=[0.5], h_bad=[0.2]), np.array([[0], [1]])).tolist()   # good, bad
    [[1.0], [0.2]]
    """
    return channel.padded_delivery[np.arange(channel.m), states]


def sample_states(channel: MarkovChannel, horizon: int, samples: int,
                  rng: np.random.Generator) -> np.ndarray:
    """State indices S_{i,t} of ``samples`` independent paths: int (samples, N, m; ``channel.state_dtype``), one
    uniform array (samples, m)
    drawn per step (the start, then each move). Time and memory O(samples N m K).

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.0], r=[1.0], state=["bad"])
    >>> sample_states(ch, 3, 1, np.random.default_rng(0))[0, :, 0].tolist()     # bad, then good for ever
    [1, 0, 0]
    """
    N, S = _count(horizon, "horizon"), _count(samples, "samples")
    out = np.empty((S, N, channel.m), dtype=channel.state_dtype)
    state = channel.draw_start(rng.random((S, channel.m)))
    for t in range(N):
        out[:, t] = state
        state = channel.draw_next(state, rng.random((S, channel.m)))
    return out


def reveals_state(channel: MarkovChannel) -> bool:
    """True when every channel's outcome reveals its state (deliveries 0 and 1, distinct: k <= 2; {h_good, h_bad}
    = {0, 1}, e.g. the Gilbert channel): then the TCP-like filtered belief is a function of the last outcome:
    [`reveals_state`][packetloss_cvx.model.channel.MarkovChannel.reveals_state]. O(m K).

    Examples
    --------
    >>> reveals_state(GilbertElliott(p=[0.1], r=[0.5]))   # the Gilbert channel: h_good = 1, h_bad = 0
    True
    >>> reveals_state(GilbertElliott(p=[0.1, 0.1], r=[0.5, 0.5], h_bad=[0.0, 0.2]))   # channel 1 may deliver when bad
    False
    """
    return channel.reveals_state()


def sample_markov_paths(channel: MarkovChannel, steps: int, samples: int,
                        rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """State indices (int) and deliveries (bool) of ``samples`` runs over ``steps`` steps, (samples, steps, m)
    each, drawn in the Bernoulli samplers' order.

    One uniform array ``u`` (samples, steps, m) is drawn first (the same call, hence the same numbers, as
    `sample_delivery_paths` and, flattened,
    `sample_deliveries`): ``S_0`` and ``S_t`` the inverse of the
    cumulative distribution of the initial belief and of the row ``T[S_{t-1}]`` at ``u_t`` (state 0 iff
    ``u_t < T[S_{t-1}, 0]``; Gilbert–Elliott: good iff ``u_t < (1 - p if good before else r)``, from
    ``u_0 < b_0``). When every outcome reveals the state (`reveals_state`)
    the delivery is the state's h (no more draws); otherwise a second uniform array gives
    ``v_t = u'_t < h(S_t)``. So a memoryless Gilbert chain (p + r = 1, h_good = 1, h_bad = 0) draws exactly
    the Bernoulli(r) deliveries of the same stream, run by run (the first runs do not depend on ``samples``).
    Time and memory O(samples steps m K). The arrays are (samples, steps, m) views of time-major
    (steps, samples, m) data: a consumer stepping in time (`plan_costs`, the
    closed loops) reads one contiguous slice a step and its time-major copy is no copy at all.

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.3], r=[0.7])
    >>> states, v = sample_markov_paths(ch, 5, 2, np.random.default_rng(1))
    >>> bern = np.random.default_rng(1).random((2, 5, 1)) < 0.7
    >>> bool(np.array_equal(v, bern) and np.array_equal(states == 0, v))
    True
    """
    steps, samples = _count(steps, "steps"), _count(samples, "samples")
    # the chain steps in time: walk it time-major, (steps, samples, m) contiguous per step (a step of the (samples,
    # steps, m) layout strides over whole runs, ~3x slower at 1000 steps), and hand back (samples, steps, m) views of
    # the time-major arrays (the deliveries too: the consumers step in time); the same numbers
    u = np.ascontiguousarray(rng.random((samples, steps, channel.m)).swapaxes(0, 1))
    states = np.empty((steps, samples, channel.m), dtype=channel.state_dtype)
    states[0] = channel.draw_start(u[0])
    for t in range(1, steps):
        states[t] = channel.draw_next(states[t - 1], u[t])
    h = state_delivery(channel, states)
    v = h == 1 if reveals_state(channel) else rng.random((samples, steps, channel.m)).swapaxes(0, 1) < h
    return states.swapaxes(0, 1), v.swapaxes(0, 1)


def sample_markov_deliveries(channel: MarkovChannel, horizon: int, samples: int,
                             rng: np.random.Generator) -> np.ndarray:
    """Deliveries v_{i,t} (True = the packet arrived): bool (samples, N, m), with P(v = 1 | state)
    = d_i[state] (h_good or h_bad). Time O(samples N m K).

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.0], r=[1.0], state=["bad"])          # bad, then good for ever
    >>> sample_markov_deliveries(ch, 3, 2, np.random.default_rng(0))[:, :, 0].tolist()
    [[False, True, True], [False, True, True]]
    >>> v = sample_markov_deliveries(GilbertElliott(p=[0.2], r=[0.6]), 2, 4000, np.random.default_rng(0))[:, :, 0]
    >>> bool(abs(v.mean() - 0.6 / 0.8) < 0.03), bool(abs(v[v[:, 0], 1].mean() - 0.8) < 0.03)   # r/(p+r); 1 - p
    (True, True)
    """
    states = sample_states(channel, horizon, samples, rng)
    return rng.random(states.shape) < state_delivery(channel, states)


def sample_markov_plan_costs(system: System, inputs: npt.ArrayLike, samples: int,
                             rng: np.random.Generator) -> np.ndarray:
    """Realised costs ``x'Qx + sum_t X_t' Omega_t X_t + sum_t (V_t u_t)' Psi_t (V_t u_t)`` of the
    open-loop plan ``inputs`` (N×m) with losses drawn from the system's Gilbert–Elliott channel.

    Their mean estimates E[cost | belief], which [`packetloss_cvx.lq.markov_cost`][packetloss_cvx.lq.markov_cost]
    computes. Time O(samples N (n^2 + n m)), memory O(samples N m).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.0], r=[1.0], belief=[0.5]))
    >>> c = sample_markov_plan_costs(s, [[-1.0], [-1.0]], 50, np.random.default_rng(0))
    >>> sorted(set(c.tolist()))   # start bad: 0 + 1 then 1 + 0 (x: 1, 1, 0); start good: 1 + 0 then 1 + 1 (x: 1, 0, -1)
    [2.0, 3.0]
    >>> from packetloss_cvx.lq.markov_cost import exact_cost
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.3]))
    >>> c = sample_markov_plan_costs(s, [[-1.0], [-0.5]], 4000, np.random.default_rng(0))
    >>> bool(abs(c.mean() - exact_cost(s, [[-1.0], [-0.5]])) < 4 * c.std() / 4000 ** 0.5)
    True
    """
    if system.channel is None:
        raise InputError("system", "expected a system with a Gilbert-Elliott channel ([channel] model = ...)")
    U = check_inputs(system, inputs)
    S = _count(samples, "samples")
    delivered = sample_markov_deliveries(system.channel, system.horizon, S, rng)
    x0 = system.x0
    X = np.repeat(x0[None, :], S, axis=0)
    total = np.full(S, float(x0 @ system.initial_weight @ x0))
    L = psd_factor(system.noise_cov)  # W_t = L' z, z ~ N(0, I)
    for t in range(system.horizon):
        applied = delivered[:, t] * U[t]
        total += np.sum(system.input_weights[t] * applied * applied, axis=1)
        X = X @ system.A.T + applied @ system.B.T
        if L.shape[0]:
            X = X + rng.standard_normal((S, L.shape[0])) @ L
        total += np.einsum("si,ij,sj->s", X, system.state_weights[t], X)
    return total
