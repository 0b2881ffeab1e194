"""Gilbert–Elliott channels sampled: state paths of the chains, the deliveries they produce, and
the realised cost of an open-loop plan under them (the Monte Carlo reference for the exact cost).

The chains of different channels are independent; each starts from the channel's initial belief
(given, or the stationary distribution) and moves with P(good -> bad) = p, P(bad -> good) = r.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..channel import GilbertElliott
from ..costs import check_inputs
from ..errors import InputError
from ..linalg import psd_factor
from ..model import System

__all__ = ["sample_markov_deliveries", "sample_markov_plan_costs", "sample_states"]


def _count(value: int, field: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InputError(field, f"expected an integer >= 1, found {value!r}")
    return int(value)


def sample_states(channel: GilbertElliott, horizon: int, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Good-state indicators S_{i,t} of ``samples`` independent paths: bool (samples, N, m).

    Time and memory O(samples N m).

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.0], r=[1.0], state=["bad"])
    >>> sample_states(ch, 3, 1, np.random.default_rng(0))[0, :, 0].tolist()
    [False, True, True]
    """
    N, S = _count(horizon, "horizon"), _count(samples, "samples")
    out = np.empty((S, N, channel.m), dtype=bool)
    good = rng.random((S, channel.m)) < channel.initial_belief
    for t in range(N):
        out[:, t] = good
        u = rng.random((S, channel.m))
        good = np.where(good, u >= channel.p, u < channel.r)
    return out


def sample_markov_deliveries(channel: GilbertElliott, horizon: int, samples: int,
                             rng: np.random.Generator) -> np.ndarray:
    """Deliveries v_{i,t} (True = the packet arrived): bool (samples, N, m), with P(v = 1 | state)
    = h_good or h_bad. Time O(samples N m)."""
    good = sample_states(channel, horizon, samples, rng)
    return rng.random(good.shape) < np.where(good, channel.h_good, channel.h_bad)


def sample_markov_plan_costs(system: System, inputs: npt.ArrayLike, samples: int,
                             rng: np.random.Generator) -> np.ndarray:
    """Realised costs ``x'Qx + sum_t X_t' Omega_t X_t + sum_t (V_t u_t)' Psi_t (V_t u_t)`` of the
    open-loop plan ``inputs`` (N×m) with losses drawn from the system's Gilbert–Elliott channel.

    Their mean estimates E[cost | belief], which :func:`packetloss_cvx.markov.exact_cost` computes.
    Time O(samples N (n^2 + n m)), memory O(samples N m).
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
