"""Prediction from Markov chains: beliefs, the HMM filter, plug-in schedules, the
second moments ``R = E[v v']`` of the stacked deliveries, and the joint (mode) chain of several channels.

Notation (docs/mathematics.md, "Bursty links"): channel i is a chain with transition matrix ``T_i`` and delivery
probabilities ``d_i`` per state (a Gilbert–Elliott channel: ``T = [[1 - p, p], [r, 1 - r]]``,
``d = (h_good, h_bad)``, ``lambda = 1 - p - r``); its belief ``pi_{i,t}`` is the distribution of its state
given the information, and the predicted delivery probability ``mu_{i,t} = pi_{i,t} . d_i``.

* UDP-like (no acknowledgements): the belief is the prior propagated, ``pi_{t+1} = pi_t T``.
* TCP-like: each acknowledged outcome ``v_t`` updates the belief first (Bayes), then it is
  propagated; for the Gilbert channel (h_good = 1, h_bad = 0) an outcome reveals the state.

Within one channel, for t < s, ``Cov(v_t, v_s) = (pi_t ∘ (d - mu_t)) T^(s-t) d`` (two states:
``lambda^(s-t) b_t (1 - b_t) (h_good - h_bad)^2``), and deliveries of different channels are independent, so R
is block-structured (`channel_covariance`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError, NumericalError
from ..tolerances import DELIVERY_FACTOR_RTOL
from .channel import (
    GilbertElliott,  # noqa: F401 (GilbertElliott: the doctests' constructor)
    MarkovChannel,
)
from .protocols import check_protocol
from .system import CacheKey, System, SystemStore, check_system

#: (Vbar, C) of stacked_moments, kept per system (a SystemStore): it depends on the channel and schedule
MOMENTS_KEY = CacheKey("chain.stacked_moments", ("horizon", "mu_schedule", "channel"))
_MOMENTS = SystemStore(MOMENTS_KEY)

__all__ = [
    "MAX_CHANNELS", "MAX_MODES", "DeliveryFactor", "attach_channel", "chain_matrices", "channel_covariance",
    "delivery_factor", "filter_belief",
    "mode_chain", "mode_start", "plugin_schedule", "plugin_system", "product_chain", "reachable_modes",
    "reachable_states",
    "second_moments",
    "stacked_moments",
]


def chain_matrices(channel: Any) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]:
    """Each channel as a finite-state chain: a tuple of per-channel ``(T, d, pi0)``.

    ``T`` (k×k) is row-stochastic (``T[a, b] = P(S_{t+1} = b | S_t = a)``), ``d`` (k,) the delivery
    probability in each state, ``pi0`` (k,) the distribution of the state at the first planned step.
    The channel answers through its own ``chain_matrices()`` method (a
    [`MarkovChannel`][packetloss_cvx.model.channel.MarkovChannel], or any object that honours this contract; k may
    differ between channels). Time O(m k^2).

    Examples
    --------
    >>> ((T, d, pi0),) = chain_matrices(GilbertElliott(p=[0.1], r=[0.4], belief=[0.75]))
    >>> T.tolist(), d.tolist(), pi0.tolist()
    ([[0.9, 0.1], [0.4, 0.6]], [1.0, 0.0], [0.75, 0.25])
    """
    method = getattr(channel, "chain_matrices", None)
    if method is None:
        raise InputError("channel", f"expected a Markov channel (a MarkovChannel or an object with "
                                    f"chain_matrices()), found {type(channel).__name__}")
    return tuple(method())


#: 2^m modes and 2^m delivery patterns per mode: beyond this many channels the mode chain (and the closed loop's
#: operator over it) is refused.
MAX_CHANNELS = 6
#: The product chain of k-state channels is refused beyond as many modes as MAX_CHANNELS Gilbert–Elliott ones give.
MAX_MODES = 2 ** MAX_CHANNELS


def reachable_states(step: npt.ArrayLike, start: npt.ArrayLike) -> np.ndarray:
    """The states (bool, (S,)) some walk along the nonzero entries of ``step`` (S×S) reaches from the support of
    ``start`` (S,), the support included: ``(start step^i)_s = 0`` for every i outside them, whatever the values
    (any nonnegative matrix with that zero pattern). O(S^3).

    Examples
    --------
    >>> reachable_states([[0.5, 0.5, 0.0], [0.0, 1.0, 0.0], [0.3, 0.0, 0.7]], [1.0, 0.0, 0.0]).tolist()
    [True, True, False]
    """
    M = np.asarray(step)
    seen = np.asarray(start) > 0
    while True:
        wider = seen | np.any(M[seen] != 0, axis=0)
        if np.array_equal(wider, seen):
            return seen
        seen = wider


def reachable_modes(channel: MarkovChannel) -> np.ndarray:
    """Which joint states of `product_chain` (its order) the chain can visit from its start: a boolean (M,), True on
    the closed set reached from the support of the joint start (each channel's initial belief, so its stationary
    distribution when no state or belief is given). The loop that runs never meets the other states, so they decide
    no verdict: `mode_chain` and `mode_start` keep only these. Read from the zero pattern of each channel's own
    transition matrix and start (a Boolean Kronecker product: no product of small probabilities underflows to a
    false zero), searched on the joint chain (`reachable_states`; channels step together: a joint state is reached
    only where every channel is in its state at the same step). Time O(M^3) (M = prod_i k_i).

    Examples
    --------
    >>> reachable_modes(GilbertElliott(p=[0.0], r=[0.3], state=["good"])).tolist()   # good absorbs: bad never met
    [True, False]
    >>> reachable_modes(GilbertElliott(p=[0.1], r=[0.3], state=["good"])).tolist()
    [True, True]
    >>> swap = MarkovChannel(transition=[[[0.0, 1.0], [1.0, 0.0]]] * 2, delivery=[[1.0, 0.0]] * 2, state=[0, 0])
    >>> reachable_modes(swap).tolist()       # both channels flip each step: (good, bad) and (bad, good) never met
    [True, False, False, True]
    """
    step, start = np.ones((1, 1), dtype=np.int64), np.ones(1, dtype=np.int64)
    for Ti, (_, _, pi0) in zip(channel.transition, chain_matrices(channel), strict=True):
        step = np.kron(step, (np.asarray(Ti) > 0).astype(np.int64))
        start = np.kron(start, (np.asarray(pi0) > 0).astype(np.int64))
    return reachable_states(step, start)


def mode_chain(channel: MarkovChannel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(modes, T, h)``: the joint states the chain can visit from its start (`reachable_modes`; every one of
    the prod_i k_i joint states where the start reaches them all), each row the state indices (channel 0 the most
    significant, state 0 first; Gilbert–Elliott channels: 0 = good), their transition matrix (the Kronecker
    product of the channels' chains, restricted to those states: still stochastic, as they form a closed set) and
    per-mode delivery probabilities (M, m). The Markov jump linear system's modes: a state the chain cannot reach
    never enters the loop, so it enters no radius, Riccati solution or certificate. Refused beyond `MAX_MODES`
    joint states. Time O(M^3 + M m).

    Raises
    ------
    InputError
        A product chain beyond `MAX_MODES` modes (more than `MAX_CHANNELS` Gilbert–Elliott channels).

    Examples
    --------
    >>> [a.tolist() for a in mode_chain(GilbertElliott(p=[0.1], r=[0.3]))]      # good, bad: the Gilbert channel
    [[[0], [1]], [[0.9, 0.1], [0.3, 0.7]], [[1.0], [0.0]]]
    >>> [a.tolist() for a in mode_chain(GilbertElliott(p=[0.0], r=[0.3], state=["good"]))]   # bad is never met
    [[[0]], [[1.0]], [[1.0]]]
    """
    return _reachable_chain(channel)[:3]


def _reachable_chain(channel: MarkovChannel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """`product_chain` restricted to `reachable_modes` (`mode_chain` and `mode_start` are its parts), refused
    beyond `MAX_MODES` joint states. O(M^3 + M m)."""
    M = int(np.prod(channel.sizes))
    if M > MAX_MODES:
        raise InputError("channel", f"the MJLS has one mode per joint state, prod k_i = "
                                    f"{' * '.join(map(str, channel.sizes))} = {M}; expected at most {MAX_MODES} "
                                    f"(at most {MAX_CHANNELS} two-state channels)")
    modes, T, h, start = product_chain(channel)
    live = reachable_modes(channel)
    if live.all():
        return modes, T, h, start
    return modes[live], T[np.ix_(live, live)], h[live], start[live]


def product_chain(channel: MarkovChannel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(modes, T, h, start)``: every joint state (all M = prod_i k_i, reachable from the start or not: `mode_chain`
    keeps the reachable ones), the transition matrix and per-mode delivery probabilities, and P(joint state at the
    first step) from each channel's start (the product of the channels' own), with no limit on M (the caller
    prices it). Time O(M^2 + M m).

    Examples
    --------
    >>> modes, T, h, start = product_chain(GilbertElliott(p=[0.1, 0.1], r=[0.3, 0.3], belief=[1.0, 0.25]))
    >>> modes.tolist(), start.tolist()                     # good, good: 0.25
    ([[0, 0], [0, 1], [1, 0], [1, 1]], [0.25, 0.75, 0.0, 0.0])
    """
    m, M = channel.m, int(np.prod(channel.sizes))
    modes = np.array(list(itertools.product(*(range(k) for k in channel.sizes))), dtype=int).reshape(M, m)
    T = np.ones((1, 1))
    for Ti in channel.transition:
        T = np.kron(T, Ti)
    starts = [pi0 for _, _, pi0 in chain_matrices(channel)]
    start = np.prod([starts[i][modes[:, i]] for i in range(m)], axis=0)
    return modes, T, channel.padded_delivery[np.arange(m), modes], start


def mode_start(channel: MarkovChannel) -> np.ndarray:
    """P(mode at the first step) from each channel's start in `chain_matrices`,
    in `mode_chain`'s order (its modes only: the start's support is among them). O(M^3 + M m).

    Examples
    --------
    >>> mode_start(GilbertElliott(p=[0.1, 0.1], r=[0.3, 0.3], belief=[1.0, 0.25])).tolist()   # good, good: 0.25
    [0.25, 0.75, 0.0, 0.0]
    """
    return _reachable_chain(channel)[3]                  # refused beyond MAX_MODES, as the chain it starts


def filter_belief(channel: MarkovChannel, belief: npt.ArrayLike, delivered: npt.ArrayLike) -> np.ndarray:
    """One step of the HMM filter: the state distribution at t+1 given the outcome at t, from the one at t
    (``belief``, (..., m, K)): [`filter`][packetloss_cvx.model.channel.MarkovChannel.filter], the outcomes and the
    belief checked first. Time O(m K^2) per belief; ``belief`` and ``delivered`` may carry leading dimensions
    (one row per run). For the Gilbert channel a delivery gives P(good) ``1 - p`` and a loss ``r`` (the state
    is known).

    Raises
    ------
    InputError
        ``delivered`` of the wrong length, or an outcome the belief gives probability zero.

    Examples
    --------
    >>> ch = GilbertElliott(p=[0.1], r=[0.3])
    >>> [float(filter_belief(ch, [[0.5, 0.5]], [v])[0, 0].round(12)) for v in (True, False)]   # 1 - p, r
    [0.9, 0.3]
    """
    b = np.asarray(belief, dtype=float)
    v = np.asarray(delivered)
    if b.ndim < 2 or b.shape[-2:] != (channel.m, max(channel.sizes)) or v.shape != b.shape[:-1]:
        raise InputError("delivered", f"expected one outcome per channel ({channel.m}) and one distribution over "
                                      f"{max(channel.sizes)} states per channel (leading dimensions alike), found "
                                      f"{v.shape} and {b.shape}")
    if not np.all((b >= 0.0) & (b <= 1.0)):
        raise InputError("belief", "expected state probabilities in [0, 1]")
    if v.dtype != bool and not (np.issubdtype(v.dtype, np.number) and np.all((v == 0) | (v == 1))):
        raise InputError("delivered", "expected outcomes True/False or 1/0 (delivered/lost)")
    return channel.filter(b, v)


def plugin_schedule(channel: MarkovChannel, horizon: int, protocol: str,
                    acknowledged: Sequence[Sequence[bool]] = ()) -> tuple[np.ndarray, np.ndarray]:
    """The predicted delivery probabilities of a plan made after ``len(acknowledged)`` steps.

    ``acknowledged[k][i]`` is the outcome of channel i at step k, counted from the channel's
    initial belief. TCP-like: the belief is filtered by each outcome (`filter_belief`);
    UDP-like: the controller sees none, so the prior is propagated. Returns
    ``(mu, belief)``: the (N, m) schedule ``mu_{i,t}`` and the belief at the plan's first step, (m, K).
    Time O((k + N) m K^2).

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


def attach_channel(system: System, channel: MarkovChannel) -> System:
    """A copy of ``system`` behind the Markov ``channel`` (its mu or mu_schedule replaced by the
    channel's predicted schedule): [`with_channel`][packetloss_cvx.model.system.System.with_channel], which validates
    the channel and the schedule and keeps the system's other, already validated, fields. Time O(N m).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> attach_channel(s, GilbertElliott(p=[0.1], r=[0.3], state=["bad"])).mu_schedule[:, 0].tolist()
    [0.0, 0.3]
    """
    if not isinstance(channel, MarkovChannel):
        raise InputError("channel", f"expected a GilbertElliott or a MarkovChannel, found {type(channel).__name__}")
    return check_system(system).with_channel(channel)


def plugin_system(system: System, protocol: str, acknowledged: Sequence[Sequence[bool]] = ()) -> System:
    """``system`` with its channel's belief moved to the plan's first step (`plugin_schedule`):
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
    """Cov(v_{i,t}, v_{i,s}) for each channel: an (m, N, N) array, read through `chain_matrices`.
    Diagonal ``mu (1 - mu)``; for t < s, ``Cov = sum_a pi_t(a) (d_a - mu_t) (T^(s-t) d)_a`` with
    ``pi_t = pi0 T^t``, ``mu_t = pi_t d`` (E[v_t v_s] = (pi_t ∘ d) T^(s-t) d; two states:
    ``lambda^(s-t) b_t (1 - b_t) (d_0 - d_1)^2``). The vectors T^L d enter centred on their first entry,
    ``e_L = T^L d - (T^L d)_0 1`` (the weights ``pi_t ∘ (d - mu_t)`` sum to zero, so this changes nothing in exact
    arithmetic), and are propagated centred, ``e_L = S^L e_0`` with ``S = T - 1 T[0]`` (the map
    ``e -> T e - (T e)_0 1``, T 1 = 1, whose powers shrink with the chain's memory): they keep their relative accuracy
    (two states: ``e_L = (0, lambda^L (d_1 - d_0))``), where differences of T^L d, which tends to a constant vector,
    would lose it; they are taken by doubling (log2 N batched products with the squares of S). The beliefs
    ``pi_{t+1} = pi_t T`` step by step (products of nonnegative numbers: each entry to its own relative accuracy,
    which a chain that almost never delivers needs). A chain with identical rows (or equal deliveries) gives exact
    zeros. Time O(N^2 m + N m k^2 + m k^3 log N).

    Examples
    --------
    >>> C = channel_covariance(GilbertElliott(p=[0.2], r=[0.2]), 3)     # b = 1/2, lambda = 0.6
    >>> np.round(C[0], 4).tolist()
    [[0.25, 0.15, 0.09], [0.15, 0.25, 0.15], [0.09, 0.15, 0.25]]
    """
    T, d, pi, ahead = _chain_arrays(channel, horizon)
    N, m = horizon, T.shape[0]
    mu = np.einsum("tik,ik->ti", pi, d)
    weights = pi * (d - mu[:, :, None])                 # (N, m, K): pi_t ∘ (d - mu_t)
    index = np.arange(N)
    at = np.minimum.outer(index, index) * N + np.abs(np.subtract.outer(index, index))   # M[min(t, s), |t - s|]
    out = np.empty((m, N, N))
    for i in range(m):
        M = weights[:, i] @ ahead[:, i].T                # (N, N): M[t, L]
        out[i] = M.ravel()[at]
        out[i][np.diag_indices(N)] = mu[:, i] * (1.0 - mu[:, i])
    return out


def _chain_arrays(channel: Any, horizon: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(T, d, pi, ahead)`` of `channel_covariance`: the channels' chains padded to K states (m, K, K) and (m, K), the
    beliefs ``pi_t`` (N, m, K) and the centred ``e_L = T^L d - (T^L d)_0 1`` (N, m, K), L = 0..N-1."""
    chains = chain_matrices(channel)
    MarkovChannel.check_horizon(horizon, len(chains) * horizon if isinstance(horizon, int | np.integer) else 1)
    N, m = horizon, len(chains)
    K = max(np.asarray(d).size for _, d, _ in chains)
    T, d, pi = np.zeros((m, K, K)), np.zeros((m, K)), np.zeros((N, m, K))
    for i, (Ti, di, pi0) in enumerate(chains):        # padded: states past k_i unreachable, absorbing, delivery 0
        k = np.asarray(di).size
        T[i], T[i, :k, :k], d[i, :k], pi[0, i, :k] = np.eye(K), Ti, di, pi0
    ahead = np.empty((N, m, K))                         # e_L = T^L d - (T^L d)_0 1 for L = 0..N-1
    ahead[0] = d - d[:, :1]
    for t in range(1, N):                               # products of nonnegative numbers: every entry to rounding
        pi[t] = np.einsum("ia,iab->ib", pi[t - 1], T)
    S = T - T[:, :1, :]                                 # T less its row 0 in every row: e -> T e - (T e)_0 1
    done = 1
    while done < N:                                     # doubling: steps done..2 done-1 from steps 0..done-1
        size = min(done, N - done)
        ahead[done:done + size] = np.einsum("iab,tib->tia", S, ahead[:size])
        S, done = S @ S, done + size
    return T, d, pi, ahead


def second_moments(channel: MarkovChannel, horizon: int) -> np.ndarray:
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
    time: the read-only pair is kept for the system (a `SystemStore`).

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


@dataclass(frozen=True)
class DeliveryFactor:
    """A factor of the deliveries' covariance over the horizon by the chain's innovations (`delivery_factor`).

    Channel i's deliveries are ``v_t = y_t + n_t``, ``y_t = d_{S_t}`` the delivery probability of the chain's state
    and ``n_t`` the delivery's own coin given it (mean zero, variance ``gamma_t = pi_t . d (1 - d)``, uncorrelated with
    everything else). With ``z_t`` the state's indicator vector, ``z_{t+1} - pi_{t+1} = T'(z_t - pi_t) + w_t``, the
    innovations ``w_t`` uncorrelated of covariance ``diag(pi_{t+1}) - T' diag(pi_t) T`` (``z_0 - pi_0``: ``diag(pi_0)
    - pi_0 pi_0'``), so ``y_t - mu_t = sum_{s<=t} e_{t-s}' (innovation at s)``, ``e_L = T^L d`` centred on its first
    entry (the innovations sum to zero). Hence ``C = F F'`` with ``F[t, (s, b)] = e_{t-s}' G_s[:, b]`` (s <= t) and
    ``F[t, N K + t] = sqrt(gamma_t)``, ``G_s G_s'`` the covariance of the innovation at s: row t of F has no entry in
    the columns of later steps, so its first k rows factor the covariance of the deliveries before step k.

    Attributes
    ----------
    innovation : ndarray (m, N, K, K)
        ``G_s`` per channel and step (the belief's part).
    response : ndarray (m, N, K)
        ``e_L``, L = 0..N-1 (the chain's part: no belief).
    spread : ndarray (m, N)
        ``sqrt(gamma_t)``.

    Examples
    --------
    A Gilbert channel's state is the innovation's only dimension (the first state's column is zero: ``e_L`` is
    centred on it); P(good) = 1/2 at step 0: ``G_0 G_0' = diag(pi_0) - pi_0 pi_0'``, entries ``+-1/4``.

    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[0.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.2], belief=[0.5]))
    >>> f = delivery_factor(s)
    >>> G = f.innovation[0, 0]
    >>> (G @ G.T).round(12).tolist(), f.response[0].round(12).tolist(), f.spread[0].tolist()
    ([[0.25, -0.25], [-0.25, 0.25]], [[0.0, -1.0], [0.0, -0.6]], [0.0, 0.0])
    """

    innovation: np.ndarray
    response: np.ndarray
    spread: np.ndarray

    def matrix(self, channel: int) -> np.ndarray:
        """F (N × N (K + 1)) of ``channel``: ``F F'`` its deliveries' covariance. O(N^2 K^2)."""
        G, e, spread = self.innovation[channel], self.response[channel], self.spread[channel]
        N, K = spread.size, G.shape[1]
        F = np.zeros((N, N * K + N))
        for t in range(N):
            F[t, :(t + 1) * K] = np.einsum("sa,sab->sb", e[t::-1], G[:t + 1]).ravel()
        F[np.arange(N), N * K + np.arange(N)] = spread
        return F


def delivery_factor(system: System) -> DeliveryFactor:
    """The factor of each channel's delivery covariance over the horizon by the chain's innovations
    (`DeliveryFactor`; docs/mathematics.md §7, "Behind a chain"): ``F F' = C``, ``C_ts = Cov(v_t, v_s)`` as
    `stacked_moments` gives it (the chain's covariances, ``mu (1 - mu)`` of the system's schedule on the diagonal),
    the first k rows of F factoring the covariance of the deliveries before step k. Only ``innovation`` and ``spread``
    depend on the belief. The innovations' covariances are factored by their eigen-decompositions (eigenvalues within
    rounding below zero set to zero); the factor is kept only where ``max|F F' - C| <= DELIVERY_FACTOR_RTOL max_t mu_t``
    for every channel (the second moments' scale: ``mu_t (1 - mu_t)`` itself is off by about ``eps mu_t``, relatively
    large where deliveries are almost certain). Time O(m N^2 K^2 + m N K^3).

    Raises
    ------
    NumericalError
        A residual beyond ``DELIVERY_FACTOR_RTOL``.
    InputError
        A system without a Markov channel.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[0.0],
    ...            channel=GilbertElliott(p=[0.2], r=[0.2]))        # b = 1/2, lambda = 0.6: C_ts = 0.6^|t-s| / 4
    >>> F = delivery_factor(s).matrix(0)
    >>> bool(np.allclose(F @ F.T, 0.25 * 0.6 ** np.abs(np.subtract.outer(range(3), range(3)))))
    True
    >>> bool(np.allclose(F[:2] @ F[:2].T, [[0.25, 0.15], [0.15, 0.25]])), F[:2, 4:6].tolist()  # no later step
    (True, [[0.0, 0.0], [0.0, 0.0]])
    """
    if system.channel is None:
        raise InputError("system", "expected a system behind a Markov channel: Bernoulli losses are independent")
    N = system.horizon
    T, d, pi, ahead = _chain_arrays(system.channel, N)
    m, K = d.shape
    previous = np.concatenate([np.zeros((1, m, K)), pi[:-1]])      # pi_{t-1}; the start's row below
    # Cov(w) = diag(pi_s) - T' diag(pi_{s-1}) T for s >= 1, diag(pi_0) - pi_0 pi_0' at s = 0
    cov = np.einsum("sia,ab->siab", pi, np.eye(K)) - np.einsum("iab,sia,iac->sibc", T, previous, T)
    cov[0] -= np.einsum("ia,ib->iab", pi[0], pi[0])
    vals, vecs = np.linalg.eigh(cov)
    G = vecs * np.sqrt(np.maximum(vals, 0.0))[..., None, :]         # (N, m, K, K): G G' = cov
    gamma = np.einsum("tia,ia->ti", pi, d * (1.0 - d))
    out = DeliveryFactor(innovation=G.transpose(1, 0, 2, 3).copy(), response=ahead.transpose(1, 0, 2).copy(),
                         spread=np.sqrt(np.maximum(gamma, 0.0)).T.copy())
    mu, C = stacked_moments(system)
    for i in range(m):
        F, Ci = out.matrix(i), C[i::m, i::m]
        scale = float(np.max(mu[i::m], initial=0.0))
        residual = float(np.abs(F @ F.T - Ci).max(initial=0.0))
        if not residual <= DELIVERY_FACTOR_RTOL * scale:
            raise NumericalError(f"the innovations factor of channel {i}'s delivery covariance over {N} steps is off "
                                 f"by {residual:.2e}, its largest delivery probability {scale:.2e}: not trusted")
    return out


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
