"""Prediction from Gilbert–Elliott chains: beliefs, the HMM filter, plug-in schedules, and the
second moments ``R = E[v v']`` of the stacked deliveries.

Notation (docs/design.md, "Bursty links"): channel i has ``lambda_i = 1 - p_i - r_i``, belief
``b_{i,t} = P(S_{i,t} = good | information)``, predicted delivery probability
``mu_{i,t} = h_bad + (h_good - h_bad) b_{i,t}``.

* UDP-like (no acknowledgements): the belief is the prior propagated, ``b_{t+1} = r + lambda b_t``.
* TCP-like: each acknowledged outcome ``v_t`` updates the belief first (Bayes), then it is
  propagated; for the Gilbert channel (h_good = 1, h_bad = 0) an outcome reveals the state.

Within one channel, for t != s and d = |t - s| (P^d = 1 pi' + lambda^d (I - 1 pi') for two states):

    Cov(v_t, v_s) = lambda^d b_u (1 - b_u) (h_good - h_bad)^2,   u = min(t, s),

and deliveries of different channels are independent, so R is block-structured. A k-state
:class:`~packetloss_cvx.model.markov_channel.MarkovChannel` has a distribution over its states as belief, propagated
by its transition matrix (``pi_{t+1} = pi_t T``) and filtered by Bayes' rule alike; its covariance is
``(pi_s ∘ (d - mu_s)) T^|t-s| d`` (:func:`channel_covariance`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from .channel import GilbertElliott
from .markov_channel import MarkovChannel
from .protocols import check_protocol
from .system import CacheKey, System, SystemStore, check_system

#: (Vbar, C) of stacked_moments, kept per system (a SystemStore): it depends on the channel and schedule
MOMENTS_KEY = CacheKey("chain.stacked_moments", ("horizon", "mu_schedule", "channel"))
_MOMENTS = SystemStore(MOMENTS_KEY)

__all__ = [
    "attach_channel", "chain_matrices", "channel_covariance", "filter_belief", "plugin_schedule", "plugin_system",
    "second_moments", "stacked_moments",
]


def chain_matrices(channel: Any) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]:
    """Each channel as a finite-state chain: a tuple of per-channel ``(T, d, pi0)``.

    ``T`` (k×k) is row-stochastic (``T[a, b] = P(S_{t+1} = b | S_t = a)``), ``d`` (k,) the delivery
    probability in each state, ``pi0`` (k,) the distribution of the state at the first planned step.
    A :class:`~packetloss_cvx.model.channel.GilbertElliott` channel is built here, states ordered (good, bad):
    ``T = [[1 - p, p], [r, 1 - r]]``, ``d = (h_good, h_bad)``, ``pi0 = (b, 1 - b)`` with ``b`` its
    ``initial_belief`` (the given belief or state; from the stationary start ``(r, p) / (p + r)``, the bits
    of its two-state MarkovChannel twin). Any other
    channel object answers for itself through its own ``chain_matrices()`` method, which honours this
    contract (k may differ between channels). Time O(m k^2).

    Examples
    --------
    >>> ((T, d, pi0),) = chain_matrices(GilbertElliott(p=[0.1], r=[0.4], belief=[0.75]))
    >>> T.tolist(), d.tolist(), pi0.tolist()
    ([[0.9, 0.1], [0.4, 0.6]], [1.0, 0.0], [0.75, 0.25])
    """
    if not isinstance(channel, GilbertElliott):
        method = getattr(channel, "chain_matrices", None)
        if method is None:
            raise InputError("channel", f"expected a Markov channel (GilbertElliott or an object with "
                                        f"chain_matrices()), found {type(channel).__name__}")
        return tuple(method())
    b = channel.initial_belief
    bad = 1.0 - b if channel.belief is not None else channel.p / (channel.p + channel.r)   # (r, p) / (p + r)
    return tuple((np.array([[1.0 - channel.p[i], channel.p[i]], [channel.r[i], 1.0 - channel.r[i]]]),
                  np.array([channel.h_good[i], channel.h_bad[i]]), np.array([b[i], bad[i]]))
                 for i in range(channel.m))


def filter_belief(channel: GilbertElliott | MarkovChannel, belief: npt.ArrayLike,
                  delivered: npt.ArrayLike) -> np.ndarray:
    """One step of the HMM filter: P(good at t+1 | outcome at t), from P(good at t) = ``belief``.

    .. math:: b^+ = \\frac{b\\,h_g^v (1-h_g)^{1-v}}{b\\,h_g^v (1-h_g)^{1-v} + (1-b)\\,h_b^v (1-h_b)^{1-v}},
              \\qquad b_{t+1} = r + (1 - p - r)\\,b^+

    Time O(m) per belief; ``belief`` and ``delivered`` may carry leading dimensions (one row per run).
    For the Gilbert channel a delivery gives ``1 - p`` and a loss ``r`` (the state is known). A
    :class:`~packetloss_cvx.model.markov_channel.MarkovChannel`'s belief is a distribution over its states, (..., m, K):
    :meth:`~packetloss_cvx.model.markov_channel.MarkovChannel.filter`, O(m K^2) per belief.

    Raises
    ------
    InputError
        ``delivered`` of the wrong length, or an outcome the belief gives probability zero.

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.1], r=[0.3])
    >>> bool(np.allclose([filter_belief(ch, [0.5], [True]), filter_belief(ch, [0.5], [False])], [[0.9], [0.3]]))
    True
    """
    b = np.asarray(belief, dtype=float)
    v = np.asarray(delivered)
    if isinstance(channel, MarkovChannel):
        if b.ndim < 2 or b.shape[-2:] != (channel.m, max(channel.sizes)) or v.shape != b.shape[:-1]:
            raise InputError("delivered", f"expected one outcome per channel ({channel.m}) and one distribution over "
                                          f"{max(channel.sizes)} states per channel (leading dimensions alike), found "
                                          f"{v.shape} and {b.shape}")
        if not np.all((b >= 0.0) & (b <= 1.0)):
            raise InputError("belief", "expected state probabilities in [0, 1]")
        if v.dtype != bool and not (np.issubdtype(v.dtype, np.number) and np.all((v == 0) | (v == 1))):
            raise InputError("delivered", "expected outcomes True/False or 1/0 (delivered/lost)")
        return channel.filter(b, v)
    if v.shape != b.shape or b.ndim < 1 or b.shape[-1] != channel.m:
        raise InputError("delivered", f"expected one outcome and one belief per channel ({channel.m}; leading "
                                      f"dimensions alike), found {v.shape} and {b.shape}")
    if not np.all((b >= 0.0) & (b <= 1.0)):
        raise InputError("belief", "expected probabilities P(good) in [0, 1]")
    if v.dtype != bool and not (np.issubdtype(v.dtype, np.number) and np.all((v == 0) | (v == 1))):
        raise InputError("delivered", "expected outcomes True/False or 1/0 (delivered/lost)")
    v = v.astype(bool)
    like_good = np.where(v, channel.h_good, 1.0 - channel.h_good)
    like_bad = np.where(v, channel.h_bad, 1.0 - channel.h_bad)
    total = b * like_good + (1.0 - b) * like_bad
    if np.any(total <= 0.0):
        i = int(np.argwhere(total <= 0.0)[0][-1])
        raise InputError("delivered", f"channel {i}: outcome {'delivered' if v[total <= 0.0][0] else 'lost'} has "
                                      "probability 0 under the belief and the channel")
    posterior = b * like_good / total
    return np.clip(channel.r + channel.correlation * posterior, 0.0, 1.0)   # a probability, rounding aside


def plugin_schedule(channel: GilbertElliott | MarkovChannel, horizon: int, protocol: str,
                    acknowledged: Sequence[Sequence[bool]] = ()) -> tuple[np.ndarray, np.ndarray]:
    """The predicted delivery probabilities of a plan made after ``len(acknowledged)`` steps.

    ``acknowledged[k][i]`` is the outcome of channel i at step k, counted from the channel's
    initial belief. TCP-like: the belief is filtered by each outcome (:func:`filter_belief`);
    UDP-like: the controller sees none, so the prior is propagated. Returns
    ``(mu, belief)``: the (N, m) schedule ``mu_{i,t}`` and the belief at the plan's first step.
    Time O((k + N) m).

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.1], r=[0.3], belief=[0.5])      # lambda = 0.6
    >>> bool(np.allclose(plugin_schedule(ch, 2, "tcp", [[False]])[0][:, 0], [0.3, 0.3 + 0.6 * 0.3]))
    True
    >>> bool(np.allclose(plugin_schedule(ch, 1, "udp", [[False]])[0][:, 0], [0.3 + 0.6 * 0.5]))
    True
    """
    protocol = check_protocol(protocol)
    if isinstance(horizon, bool) or not isinstance(horizon, int | np.integer) or horizon < 1:
        raise InputError("horizon", f"expected an integer >= 1, found {horizon!r}")
    b = np.array(channel.initial_belief, dtype=float)
    for outcome in acknowledged:
        b = filter_belief(channel, b, outcome) if protocol == "tcp" else np.clip(channel.propagate(b), 0.0, 1.0)
    return channel.delivery_schedule(int(horizon), b), b


def attach_channel(system: System, channel: GilbertElliott | MarkovChannel) -> System:
    """A copy of ``system`` behind the Markov ``channel`` (its mu or mu_schedule replaced by the
    channel's predicted schedule): :meth:`~packetloss_cvx.model.system.System.with_channel`, which validates the
    channel and the schedule and keeps the system's other, already validated, fields. Time O(N m).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> attach_channel(s, GilbertElliott(p=[0.1], r=[0.3], state=["bad"])).mu_schedule[:, 0].tolist()
    [0.0, 0.3]
    """
    if not isinstance(channel, GilbertElliott | MarkovChannel):
        raise InputError("channel", f"expected a GilbertElliott or a MarkovChannel, found {type(channel).__name__}")
    return check_system(system).with_channel(channel)


def plugin_system(system: System, protocol: str, acknowledged: Sequence[Sequence[bool]] = ()) -> System:
    """``system`` with its channel's belief moved to the plan's first step (:func:`plugin_schedule`):
    its ``mu_schedule`` is the plug-in schedule, so the paper's laws on it are the plug-in laws.
    Time O(size of the system).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[0.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.3], belief=[0.5]))
    >>> # a loss seen (TCP-like) leaves the belief at r = 0.3, then 0.3 + (1 - p - r) 0.3
    >>> bool(np.allclose(plugin_system(s, "tcp", [[False]]).mu_schedule[:, 0], [0.3, 0.48]))
    True
    """
    if system.channel is None:
        raise InputError("system", "expected a system with a Gilbert-Elliott channel ([channel] model = ...)")
    _, b = plugin_schedule(system.channel, system.horizon, protocol, acknowledged)
    return attach_channel(system, system.channel.with_belief(b))


def channel_covariance(channel: Any, horizon: int) -> np.ndarray:
    """Cov(v_{i,t}, v_{i,s}) for each channel: an (m, N, N) array. Diagonal mu (1 - mu); off the
    diagonal, for a Gilbert–Elliott channel and every two-state channel of a MarkovChannel (one formula, so that
    a channel and its twin give the same bits), lambda^|t-s| b_u (1 - b_u) (d_0 - d_1)^2 with u = min(t, s).
    Any other channel (a k-state :class:`~packetloss_cvx.model.markov_channel.MarkovChannel`, or any object with
    ``chain_matrices()``) is read through :func:`chain_matrices`: for t < s,
    ``Cov = sum_a pi_t(a) (d_a - mu_t) (T^(s-t) d)_a`` with ``pi_t = pi0 T^t``, ``mu_t = pi_t d``
    (E[v_t v_s] = (pi_t ∘ d) T^(s-t) d), which lets the dense route and the QP twin serve k-state chains too;
    a chain with identical rows gives exact zeros. Time O(N^2 m) (plus O(N m k^2)).

    Examples
    --------
    >>> C = channel_covariance(GilbertElliott(p=[0.2], r=[0.2]), 3)     # b = 1/2, lambda = 0.6
    >>> np.round(C[0], 4).tolist()
    [[0.25, 0.15, 0.09], [0.15, 0.25, 0.15], [0.09, 0.15, 0.25]]
    """
    if not isinstance(channel, GilbertElliott):
        return _chain_covariance(channel, chain_matrices(channel), horizon)
    channel.check_horizon(horizon, channel.m * horizon if isinstance(horizon, int | np.integer) else 1)
    out = np.empty((channel.m, horizon, horizon))
    b, mu = channel.beliefs(horizon), channel.delivery_schedule(horizon)
    for i in range(channel.m):
        out[i] = _two_state_covariance(b[:, i], channel.correlation[i], channel.h_good[i] - channel.h_bad[i], mu[:, i])
    return out


def _two_state_covariance(b: np.ndarray, lam: float, spread: float, mu: np.ndarray) -> np.ndarray:
    """One two-state channel's covariance (N, N): ``lambda^|t-s| b_u (1 - b_u) (d_0 - d_1)^2`` (u = min(t, s)) off
    the diagonal, ``mu (1 - mu)`` on it, from ``P^j = 1 pi' + lambda^j (I - 1 pi')``; ``b`` (N,) the probability
    of state 0. The one formula for a Gilbert–Elliott channel and a two-state chain alike, so that a channel and
    its two-state twin give the same bits. O(N^2)."""
    N = b.size
    lag = np.abs(np.arange(N)[:, None] - np.arange(N)[None, :])
    first = np.minimum(np.arange(N)[:, None], np.arange(N)[None, :])
    with np.errstate(under="ignore"):
        powers = lam ** np.arange(N, dtype=float)                  # 0^0 = 1: the diagonal is replaced below
    out = powers[lag] * (b * (1.0 - b) * spread ** 2)[first]
    out[np.diag_indices(N)] = mu * (1.0 - mu)
    return out


def _chain_covariance(channel: Any, chains: tuple, horizon: int) -> np.ndarray:
    """channel_covariance from per-channel (T, d, pi0): M[t, L] = c_t . (T^L d) with c_t = pi_t o (d - mu_t),
    placed at (t, t + L) and mirrored. The vectors T^L d are centred on their first entry (the weights c_t sum
    to zero, so this changes nothing in exact arithmetic), so a chain with identical rows gives exact zeros.
    A two-state channel of a :class:`~packetloss_cvx.model.markov_channel.MarkovChannel` takes the two-state formula
    on the channel's own beliefs and schedule instead (what a Gilbert–Elliott channel takes: its twin gives the
    same bits). O(N^2 m + N m k^2)."""
    GilbertElliott.check_horizon(horizon, len(chains) * horizon if isinstance(horizon, int | np.integer) else 1)
    N = horizon
    rows, cols = np.triu_indices(N)
    out = np.empty((len(chains), N, N))
    own = isinstance(channel, MarkovChannel) and 2 in channel.sizes
    beliefs, schedule = (channel.beliefs(N), channel.delivery_schedule(N)) if own else (None, None)
    for i, (T, d, pi0) in enumerate(chains):
        T, d = np.asarray(T, dtype=float), np.asarray(d, dtype=float)
        if own and d.size == 2:
            out[i] = _two_state_covariance(beliefs[:, i, 0], float(T[0, 0] - T[1, 0]), float(d[0] - d[1]),
                                           schedule[:, i])
            continue
        pi = np.empty((N, d.size))
        ahead = np.empty((N, d.size))                   # T^L d for L = 0..N-1
        pi[0], ahead[0] = pi0, d
        for t in range(1, N):
            pi[t] = pi[t - 1] @ T
            ahead[t] = T @ ahead[t - 1]
        mu = pi @ d
        M = (pi * (d - mu[:, None])) @ (ahead - ahead[:, :1]).T          # (N, N): M[t, L]
        out[i][rows, cols] = M[rows, cols - rows]
        out[i][cols, rows] = out[i][rows, cols]
        out[i][np.diag_indices(N)] = mu * (1.0 - mu)
    return out


def second_moments(channel: GilbertElliott | MarkovChannel, horizon: int) -> np.ndarray:
    """E[v_{i,t} v_{i,s}] for each channel, (m, N, N): mu_t mu_s + Cov, with mu_t on the diagonal
    (v is 0 or 1). Time O(N^2 m).

    Examples
    --------
    >>> # b = 1/2, lambda = 1 - p - r = 0.6: E[v_1 v_2] = 1/4 + 0.6 / 4, E[v_t^2] = E[v_t] = 1/2
    >>> bool(np.allclose(second_moments(GilbertElliott(p=[0.2], r=[0.2]), 2)[0], [[0.5, 0.4], [0.4, 0.5]]))
    True
    """
    mu = channel.delivery_schedule(horizon)
    R = mu.T[:, :, None] * mu.T[:, None, :] + channel_covariance(channel, horizon)
    for i in range(channel.m):
        R[i][np.diag_indices(horizon)] = mu[:, i]
    return R


def stacked_moments(system: System) -> tuple[np.ndarray, np.ndarray]:
    """``(Vbar, C)``: the mean and the covariance of the stacked deliveries, step-major (entry
    ``t m + i`` is channel i at step t), C of shape (N m, N m). Without a Markov channel the
    deliveries are independent Bernoulli(mu_schedule): C = diag(Vbar (1 - Vbar)).
    ``R = Vbar Vbar' + C``. Time O((N m)^2) (the N^2 m non-zero entries, placed in the dense C), the first
    time: the read-only pair is kept for the system (a :class:`~packetloss_cvx.model.system.SystemStore`).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[0.0])
    >>> Vbar, C = stacked_moments(s)                    # Bernoulli: independent, variance mu (1 - mu)
    >>> Vbar.tolist(), C.tolist()
    ([0.5, 0.5], [[0.25, 0.0], [0.0, 0.25]])
    """
    N, m = system.horizon, system.m
    kept = _MOMENTS.get(system)
    if kept is None:
        kept = _MOMENTS.put(system, _moments(system), nbytes=8 * (N * m) ** 2)
    return kept


def _moments(system: System) -> tuple[np.ndarray, np.ndarray]:
    N, m = system.horizon, system.m
    v = system.mu_schedule.reshape(-1)
    if system.channel is None:
        C = np.diag(v * (1.0 - v))
    else:
        blocks = channel_covariance(system.channel, N)
        C = np.zeros((N * m, N * m))          # owns its data: the read-only C has no writable base
        blocked = C.reshape(N, m, N, m)
        for i in range(m):
            blocked[:, i, :, i] = blocks[i]
        C[np.diag_indices(N * m)] = v * (1.0 - v)       # the System's own (validated) schedule on the diagonal
    C.setflags(write=False)
    return v, C
