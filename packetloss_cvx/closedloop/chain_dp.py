"""The TCP-like attainable cost behind Markov channels: the finite-horizon DP with acknowledgements over the beliefs
the acknowledgements can produce.

At step t the controller knows x_t and every earlier acknowledgement; channel i's state S_{i,t} is hidden, and its
belief ``pi_{i,t}`` (over the state at t) is a deterministic function of that channel's outcomes so far (the HMM
filter from the channel's start, `MarkovChannel.filter`). The cost-to-go is ``x'P_{t,j}x + c_{t,j}`` at each
reachable belief j, and one backward pass over the beliefs reachable in N steps is the exact optimum of every causal
law (closedloop.riccati.dp_backward_nodes: the input is chosen before the outcome, whose probability and next belief
the node fixes). The beliefs are indexed by the outcomes since the last one that identifies the state (an outcome
only one state can give: a loss where only the bad state loses): finite for a finite horizon, and

* where every outcome identifies the state (deliveries 0 or 1 in each state, the states' outcomes distinct: the
  Gilbert channel, h_good = 1, h_bad = 0) one node per state and step (the start node aside): the coupled Riccati
  recursion over the modes, the mode of step t - 1 known at step t;
* where one outcome identifies it (a channel that never loses in one state, h_good = 1 > h_bad > 0: a loss
  identifies the bad state) the runs since the last identifying outcome: O(N) nodes per step;
* otherwise (hidden state) every history: 2^t nodes at step t per channel, exact for short horizons and refused in
  advance beyond the ``chain_dp_nodes`` budget (budgets.py).

Where the exact pass is refused, `chain_attainable` brackets it (both computed, both labelled): below by the same
pass with the state revealed after each step (``information="state"``: a controller that also observes the
hidden state does at least as well), above by the exact cost under the chain (`chain_law_cost`, a forward pass of
second moments) of the DP law on beliefs filtered over the last W outcomes only (any causal law's cost is an upper
bound on the optimum).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..budgets import OVERRIDE_REACH, check, limit
from ..errors import BudgetError, NumericalError
from ..model.chain import chain_matrices, product_chain
from ..model.system import System
from ..tolerances import SELF_CHECK_RTOL
from .riccati import dp_backward_nodes

__all__ = ["INFORMATION", "ChainAttainable", "ChainDP", "chain_attainable", "chain_dp", "chain_layers",
           "chain_law_cost", "node_outcomes"]

#: What the controller learns after each step: the acknowledgements (TCP-like, the attainable cost) or the channel
#: states themselves (a lower bound on it).
INFORMATION = ("acknowledgements", "state")

Layer = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class ChainDP:
    """The finite-horizon DP over the information nodes: ``cost`` (x0'P_0x0 + noise on the paper's cost),
    ``information`` (`INFORMATION`), ``window`` (None: the exact beliefs; W: beliefs filtered over the last W
    outcomes, a law whose own cost `chain_law_cost` gives), ``nodes`` (J_t, t = 0..N), ``gains[t]`` (J_t, m, n)
    and ``layers[t] = (prob, q, nxt)`` (closedloop.riccati.dp_backward_nodes; behind acknowledgements outcome o of
    a node is the delivery vector whose bits, channel 0 first, spell o)."""

    cost: float
    information: str
    window: int | None
    nodes: tuple[int, ...]
    gains: tuple[np.ndarray, ...]
    layers: tuple[Layer, ...]


@dataclass(frozen=True)
class ChainAttainable:
    """The TCP-like attainable cost behind a chain: ``cost`` where it is exact (else None), ``lower`` and ``upper``
    (equal to cost where exact), ``note`` saying which and why."""

    cost: float | None
    lower: float
    upper: float
    note: str


def _channel_step(T: np.ndarray, d: np.ndarray, keys: list[tuple], beliefs: list[np.ndarray], information: str,
                  window: int | None, stationary: np.ndarray) -> tuple[Layer, list[tuple], list[np.ndarray]]:
    """One channel's outcomes from each of its nodes at a step: ``((prob, q, nxt), next keys, next beliefs)``. A
    key is ``("state", s)`` after an identifying outcome, ``("prior",)`` at the start, extended by each outcome
    that does not identify the state; with ``window``, longer histories keep their last W outcomes (``("window",
    ...)``, filtered from the stationary distribution). O(nodes k^2)."""
    k = d.size
    out_keys: dict[tuple, int] = {}
    out_beliefs: list[np.ndarray] = []
    outcomes = k if information == "state" else 2
    prob = np.zeros((len(keys), outcomes))
    q = np.zeros((len(keys), outcomes))
    nxt = np.zeros((len(keys), outcomes), dtype=int)

    def node(key: tuple, belief_of) -> int:
        if key not in out_keys:
            out_keys[key] = len(out_beliefs)
            out_beliefs.append(belief_of())
        return out_keys[key]

    for j, (key, pi) in enumerate(zip(keys, beliefs, strict=True)):
        for o in range(outcomes):
            if information == "state":
                prob[j, o], q[j, o] = pi[o], d[o]
                if pi[o] > 0:
                    nxt[j, o] = node(("state", o), lambda o=o: T[o].copy())
                continue
            like = d if o == 1 else 1.0 - d
            prob[j, o], q[j, o] = float(pi @ like), float(o)
            if prob[j, o] <= 0:
                continue
            possible = np.flatnonzero(like > 0)
            if possible.size == 1:
                nxt[j, o] = node(("state", int(possible[0])), lambda s=int(possible[0]): T[s].copy())
                continue
            history = key + (o,)
            if window is not None and len(history) - 1 > window:
                history = ("window",) + history[len(history) - window:]
                nxt[j, o] = node(history, lambda h=history: _filtered(T, d, stationary, h[1:]))
            else:
                nxt[j, o] = node(history, lambda pi=pi, like=like, p=prob[j, o]: (pi * like / p) @ T)
    return (prob, q, nxt), list(out_keys), out_beliefs


def _filtered(T: np.ndarray, d: np.ndarray, start: np.ndarray, outcomes: tuple) -> np.ndarray:
    """The belief after ``outcomes`` filtered from ``start`` (the HMM filter; an impossible outcome keeps the
    prediction). O(len k^2)."""
    pi = start
    for v in outcomes:
        joint = pi * (d if v else 1.0 - d)
        total = joint.sum()
        pi = (joint / total if total > 0 else pi) @ T
    return pi


def chain_layers(system: System, information: str = "acknowledgements", window: int | None = None,
                 field: str = "horizon") -> list[Layer]:
    """The information nodes of the system's channel over its horizon, as closedloop.riccati.dp_backward_nodes
    takes them: the product over the channels (independent) of each channel's nodes, channel 0 the most significant
    digit of a joint node and of a joint outcome. Counted step by step against the ``chain_dp_nodes`` budget
    (the sum over the steps of nodes times outcomes) before each step's arrays are built. O(sum_t J_t k (m + k)).

    Raises
    ------
    BudgetError
        More node-outcomes than the ``chain_dp_nodes`` budget (a hidden state over a long horizon: 2^t histories at
        step t), naming ``field``.

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.4]))
    >>> [prob.shape[0] for prob, _, _ in chain_layers(s)]      # the start, then the good and the bad state
    [1, 2, 2]
    >>> [prob.shape[0] for prob, _, _ in chain_layers(s.with_channel(GilbertElliott(p=[0.1], r=[0.4], h_bad=[0.5],
    ...                                                                           h_good=[0.9])))]   # hidden: 2^t
    [1, 2, 4]
    """
    chains = chain_matrices(system.channel)
    needed = node_outcomes(system, information, window)
    check("chain_dp_nodes", needed, field,
          f"the TCP-like DP over the beliefs {information} reach in {system.horizon} steps (up to {needed:.3g} "
          "node-outcomes" + (": the chain's state is hidden)" if information == "acknowledgements" else ")"),
          instead="a shorter horizon, or closedloop.chain_dp.chain_attainable's bounds", reach=OVERRIDE_REACH)
    stationary = system.channel.stationary
    keys = [[("prior",)] for _ in chains]
    beliefs = [[pi0] for _, _, pi0 in chains]
    layers: list[Layer] = []
    for _ in range(system.horizon):
        steps = []
        for i, (T, d, _) in enumerate(chains):
            layer, keys[i], beliefs[i] = _channel_step(T, d, keys[i], beliefs[i], information, window,
                                                       stationary[i, :d.size])
            steps.append(layer)
        layers.append(_joint(steps, [len(k) for k in keys]))
    return layers


def node_outcomes(system: System, information: str = "acknowledgements", window: int | None = None) -> float:
    """An upper bound, from the chain's structure alone, on the work of `chain_layers`: the sum over the steps of
    joint nodes times joint outcomes. Per channel a node has 2 outcomes (k with ``information="state"``); ``a`` of
    them identify the state, so ``J_{t+1} <= (2 - a) J_t + a`` (all k after the first step with the states),
    and with a window W at most ``(k + 1) 2^(W + 1) + 2^W`` nodes. O(N m).

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=4, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.4], h_bad=[0.5]))
    >>> node_outcomes(s)                  # h_good = 1: a loss identifies the bad state; nodes 1, 2, 3, 4
    20.0
    """
    nodes, outcomes, total = [1.0] * system.m, 1.0, 0.0
    grow = []
    for _, d, _ in chain_matrices(system.channel):
        if information == "state":
            grow.append((0.0, float(d.size)))
            outcomes *= d.size
            continue
        a = sum(int(np.count_nonzero(like > 0) == 1) for like in (d, 1.0 - d))
        grow.append((2.0 - a, float(a)))
        outcomes *= 2
    for _ in range(system.horizon):
        total += float(np.prod(nodes)) * outcomes
        nodes = [g * J + a for (g, a), J in zip(grow, nodes, strict=True)]
        if window is not None:
            nodes = [min(J, (d.size + 1) * 2.0 ** (window + 1) + 2.0 ** window)
                     for J, (_, d, _) in zip(nodes, chain_matrices(system.channel), strict=True)]
    return total


def _joint(steps: list[Layer], after: list[int]) -> Layer:
    """The product of the channels' layers: node j and outcome o are mixed-radix numbers over the channels (channel 0
    the most significant), ``after`` the channels' node counts at the next step. O(J k m)."""
    nodes = np.array(list(np.ndindex(*[p.shape[0] for p, _, _ in steps]))).reshape(-1, len(steps))
    outs = np.array(list(np.ndindex(*[p.shape[1] for p, _, _ in steps]))).reshape(-1, len(steps))
    prob = np.ones((nodes.shape[0], outs.shape[0]))
    q = np.empty((*prob.shape, len(steps)))
    nxt = np.zeros(prob.shape, dtype=int)
    stride = 1
    for i in range(len(steps) - 1, -1, -1):
        p_i, q_i, n_i = steps[i]
        at = (nodes[:, i][:, None], outs[:, i][None, :])
        prob *= p_i[at]
        q[..., i] = q_i[at]
        nxt += n_i[at] * stride
        stride *= after[i]
    return prob, q, nxt


def _weights(system: System) -> tuple[np.ndarray, np.ndarray]:
    """The paper's weights: ``Omega[0] = Q`` on x_0, ``Omega[t] = state_weights[t - 1]`` after it (the terminal one
    last), ``psi`` (N, m)."""
    return np.concatenate([system.initial_weight[None], system.state_weights]), system.input_weights


def chain_dp(system: System, information: str = "acknowledgements", window: int | None = None) -> ChainDP:
    """The finite-horizon DP behind the system's chain over the information nodes of `chain_layers`.

    ``information="acknowledgements"`` with ``window=None``: the least expected cost of any TCP-like (acknowledged)
    causal law over the horizon, exact; ``"state"``: the least cost of a controller that also learns each step's
    channel states (a lower bound on it; equal where the acknowledgements reveal the states); ``window=W``: the DP
    on beliefs filtered over the last W outcomes only (its ``cost`` is no bound; the law's own cost is
    `chain_law_cost`). Time O(sum_t J_t k_t (n^3 + m^3)).

    Raises
    ------
    BudgetError
        Beyond the ``chain_dp_nodes`` budget (`chain_layers`).
    NumericalError
        The cost-to-go overflows.

    Examples
    --------
    One step of x' = x + v u behind a Gilbert channel in its stationary law (P(good) = 0.8): as Bernoulli(0.8),
    1 - mu / 2.

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.4]))
    >>> round(chain_dp(s).cost, 12)
    0.6
    """
    if information not in INFORMATION:
        raise ValueError(f"information: expected one of {INFORMATION}, found {information!r}")
    layers = chain_layers(system, information, window)
    Omega, psi = _weights(system)
    gains, P, noise = dp_backward_nodes(system.A, system.B, Omega, psi, system.noise_cov, layers)
    cost = float(system.x0 @ P[0] @ system.x0 + noise[0])
    if not (np.isfinite(cost) and all(np.all(np.isfinite(g)) for g in gains)):
        raise NumericalError("finite-horizon DP behind the chain: the cost-to-go overflows (an unstable plant over a "
                             "long horizon)")
    nodes = tuple(p.shape[0] for p, _, _ in layers) + (int(np.max(layers[-1][2])) + 1 if layers else 1,)
    return ChainDP(cost, information, window, nodes, tuple(gains), tuple(layers))


def chain_law_cost(system: System, law: ChainDP) -> float:
    """The exact expected cost under the system's chain of a law behind acknowledgements (`chain_dp`'s, any
    window), on the paper's cost: the forward pass of ``S_{t,s,j} = E[x_t x_t' 1{mode_t = s, node_t = j}]`` over the
    joint channel state s (hidden) and the node j (what the controller knows), each delivery vector v with its
    probability in s, ``x_{t+1} = (A - B V K_{t,j}) x_t + w_t``: a sum of non-negative terms, free of the backward
    pass's cancellation and of its beliefs (the chain enters through its own transition and delivery probabilities).
    Time O(sum_t M J_t 2^m (n^3 + M n^2)).

    Raises
    ------
    BudgetError
        ``sum_t J_t 2^m M`` beyond the ``chain_dp_nodes`` budget.
    ValueError
        A law on the states (``information="state"``): it needs the states, which no TCP-like controller has.
    NumericalError
        The second moments overflow.

    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.4]))
    >>> round(chain_law_cost(s, chain_dp(s)), 12)
    0.6
    """
    if law.information != "acknowledgements":
        raise ValueError("chain_law_cost: a law on the channel states is not a TCP-like law")
    modes, T, h, start = product_chain(system.channel)
    needed = float(sum(prob.size for prob, _, _ in law.layers)) * T.shape[0]
    check("chain_dp_nodes", needed, "horizon", f"the exact cost of a law behind the chain over its {T.shape[0]} joint "
          f"states ({needed:.3g} node-outcome-states)", instead="fewer channels or a shorter horizon",
          reach=OVERRIDE_REACH)
    Omega, psi = _weights(system)
    n = system.n
    S = np.zeros((T.shape[0], 1, n, n))
    S[:, 0] = start[:, None, None] * np.outer(system.x0, system.x0)
    mass = start[:, None].copy()
    cost = 0.0
    with np.errstate(over="ignore", invalid="ignore"):
        for t, (prob, q, nxt) in enumerate(law.layers):
            K = law.gains[t]
            cost += float(np.einsum("ab,sjba->", Omega[t], S))
            S_next = np.zeros((T.shape[0], law.nodes[t + 1], n, n))
            mass_next = np.zeros((T.shape[0], law.nodes[t + 1]))
            for o in range(prob.shape[1]):
                v = q[0, o]                                                   # the delivery vector of outcome o
                given = np.prod(np.where(v == 1, h, 1.0 - h), axis=1)         # P(v | mode), (M,)
                VK = v[:, None] * K                                           # (J, m, n)
                F = system.A - system.B @ VK
                inputs = np.einsum("jai,a,jak->jik", VK, psi[t], VK)          # K'V Psi V K
                cost += float(np.einsum("s,jik,sjki->", given, inputs, S))
                Y = given[:, None, None, None] * (F @ S @ F.swapaxes(-1, -2))
                Y += (given[:, None] * mass)[..., None, None] * system.noise_cov
                np.add.at(S_next, (slice(None), nxt[:, o]), np.einsum("sb,sjxy->bjxy", T, Y))
                np.add.at(mass_next, (slice(None), nxt[:, o]), T.T @ (given[:, None] * mass))
            S, mass = S_next, mass_next
        cost += float(np.einsum("ab,sjba->", Omega[len(law.layers)], S))
    if not np.isfinite(cost):
        raise NumericalError("the exact cost of the law behind the chain: the second moments overflow")
    return cost


def chain_attainable(system: System) -> ChainAttainable:
    """The TCP-like attainable cost behind the system's chain: exact by `chain_dp` (checked against the forward cost
    of its own law, `chain_law_cost`, within SELF_CHECK_RTOL, the forward one returned) within the
    ``chain_dp_nodes`` budget; beyond it the bounds of the module docstring, each labelled: the lower from the DP
    that also observes the channel states, the upper from the exact cost of the DP law on the largest window of
    outcomes that fits the budget.

    Raises
    ------
    NumericalError
        The DP's cost and its law's forward cost disagree beyond SELF_CHECK_RTOL, or either overflows.

    >>> from packetloss_cvx import load_example
    >>> round(chain_attainable(load_example("pendulum_bursty")).cost, 1)
    10668.7
    """
    try:
        law = chain_dp(system)
    except BudgetError as err:
        return _bounds(system, str(err))
    forward = chain_law_cost(system, law)
    if abs(law.cost - forward) > SELF_CHECK_RTOL * forward:
        raise NumericalError(f"DP behind the chain: its cost {law.cost:.12g} disagrees with the forward cost of its "
                             f"own law {forward:.12g} beyond SELF_CHECK_RTOL (the weights' scales lose digits)")
    return ChainAttainable(forward, forward, forward,
                           f"exact: finite-horizon DP with acknowledgements over the {max(law.nodes)} beliefs a step "
                           "they can reach")


def _bounds(system: System, refused: str) -> ChainAttainable:
    """`chain_attainable` beyond the budget: the two bounds, the window halved from the horizon until it fits."""
    lower = chain_dp(system, "state").cost
    window, states = system.horizon, float(np.prod(system.channel.sizes))
    while window > 0 and node_outcomes(system, window=window) * states > limit("chain_dp_nodes"):
        window -= 1
    law = chain_dp(system, window=window)
    upper = chain_law_cost(system, law)
    return ChainAttainable(None, lower, upper,
                           f"bounds, not exact (the exact DP is refused: {refused}): lower {lower:.10g}, the DP that "
                           f"also observes the channel states; upper {upper:.10g}, the exact cost of the DP law on the "
                           f"last {window} acknowledgements")
