"""Receding-horizon laws run in closed loop behind Markov channels (the chain sampled per run; Gilbert–Elliott or
k-state, whose beliefs are distributions over the states).

At every step each law re-plans from the current state with its belief about the channels:

* ``"tcp"`` information: the belief is filtered by each acknowledged outcome (HMM filter; for the
  Gilbert channel the acknowledgement reveals the state, so the belief is 1 - p or r);
* ``"udp"`` information: no acknowledgements, the prior is propagated (the same for every run).

Laws: ``"plug-in-tcp"`` / ``"plug-in-udp"``, the paper's TCP-like / UDP-like law with the chain's
predicted mu_t ([`packetloss_cvx.lq.costs.closed_form`][packetloss_cvx.lq.costs.closed_form]), and ``"exact-tcp"`` /
``"exact-udp"``, the minimiser of the plan's exact expected cost under correlated losses
([`packetloss_cvx.lq.markov_cost.exact_closed_form`][packetloss_cvx.lq.markov_cost.exact_closed_form]), each with that
protocol's belief. The first input of the plan is applied; a lost packet applies zero. Gains are cached per distinct
belief.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..budgets import BUDGETS, limit, refusal_text
from ..closedloop.chain_dp import ChainDP
from ..errors import InputError, ResourceError
from ..linalg import psd_factor
from ..lq.costs import closed_form
from ..lq.markov_cost import exact_closed_form
from ..model.chain import attach_channel, filter_belief, reachable_modes
from ..model.system import System, check_system, loop_weights
from ..progress import progress_bar
from .channels import sample_noise_paths
from .markov_channels import sample_markov_paths, sample_states, state_delivery

__all__ = ["MARKOV_LAWS", "PLAN_BUDGET", "BeliefGains", "markov_closed_loop_costs", "markov_loop_block", "mode_index",
           "sample_chain_law_costs"]

#: Distinct beliefs (one receding-horizon plan each) a law may meet in one simulation before it is refused: the
#: default of the ``belief_plans`` budget (budgets.py), which ``PACKETLOSS_CVX_BUDGET_BELIEF_PLANS`` raises.
PLAN_BUDGET = int(BUDGETS["belief_plans"].default)

#: The laws :func:`markov_closed_loop_costs` runs: (how the plan is made, whose information).
MARKOV_LAWS = ("plug-in-tcp", "plug-in-udp", "exact-tcp", "exact-udp")


def _gain(system: System, law: str, belief: np.ndarray) -> np.ndarray:
    moved = attach_channel(system, system.channel.with_belief(belief))
    kind, protocol = law.rsplit("-", 1)
    plug_in = moved.with_mu(moved.mu_schedule)   # the paper's law on the predicted mu_t
    sol = closed_form(plug_in, protocol) if kind == "plug-in" else exact_closed_form(moved, "udp")
    return sol.gain


def markov_closed_loop_costs(system: System, laws: Sequence[str] = MARKOV_LAWS, steps: int = 50,
                             samples: int = 1000, rng: np.random.Generator | None = None,
                             progress: bool | None = None) -> np.ndarray:
    """Realised closed-loop costs ``sum_{t<steps} x_t' Omega_1 x_t + (V_t u_t)' Psi_0 (V_t u_t) + x_steps' Omega_1
    x_steps``.

    Every law sees the same sampled channel states, deliveries and noise (common random numbers).
    Returns an array (len(laws), samples). Time O(steps samples (n^2 + n m) + G plan), G the number
    of distinct beliefs met (at most 2^m + 1 for TCP-like information on Gilbert channels, one per
    step for UDP-like), each plan O(N (D^3 + m^3)), D = n (1 + m) (the exact one, the augmented recursion) or less.

    Raises
    ------
    InputError
        No Markov channel, an unknown law, or counts below 1.
    ResourceError
        A law met more distinct beliefs than the ``belief_plans`` budget (one plan each: a law with unboundedly many
        beliefs would plan without end), as [`simulate`][packetloss_cvx.montecarlo.simulate.simulate] refuses them;
        the message offers samples x steps, the most a run can meet, for ``PACKETLOSS_CVX_BUDGET_BELIEF_PLANS``.

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> from packetloss_cvx.closedloop.moments import finite_horizon_costs
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.4], r=[0.6]))          # p + r = 1: Bernoulli(0.6) losses
    >>> c = markov_closed_loop_costs(s, ["plug-in-udp"], steps=4, samples=4000, rng=np.random.default_rng(0))
    >>> twin = s.with_mu([0.6])
    >>> stage, terminal = finite_horizon_costs(twin, closed_form(twin, "udp").gain, 4)
    >>> bool(abs(c[0].mean() - stage.sum() - terminal) < 4 * c[0].std() / 4000 ** 0.5)
    True
    """
    system = check_system(system)
    ch = system.channel
    if ch is None:
        raise InputError("system", "expected a system with a Gilbert-Elliott channel ([channel] model = ...)")
    for law in laws:
        if law not in MARKOV_LAWS:
            raise InputError("laws", f"expected some of {', '.join(MARKOV_LAWS)}, found {law!r}")
    rng = np.random.default_rng() if rng is None else rng
    states = sample_states(ch, steps, samples, rng)                        # validates steps and samples
    delivered = rng.random(states.shape) < state_delivery(ch, states)
    L = psd_factor(system.noise_cov)
    noise = rng.standard_normal((steps, samples, L.shape[0])) @ L if L.shape[0] else None
    W, psi = loop_weights(system)
    out = np.empty((len(laws), samples))
    for k, law in enumerate(progress_bar(laws, total=len(laws), desc="closed loop (Markov)", progress=progress)):
        gains = BeliefGains(system, law[-3:], law=law, most=samples * steps)    # within the belief_plans budget
        belief = np.repeat(ch.initial_belief[None], samples, axis=0)
        X = np.repeat(system.x0[None], samples, axis=0)
        total = np.zeros(samples)
        with np.errstate(over="ignore", invalid="ignore"):
            for t in range(steps):
                K = gains.many(belief)                                                     # (S, m, n)
                applied = delivered[:, t] * -np.einsum("smn,sn->sm", K, X)
                total += np.einsum("si,ij,sj->s", X, W, X) + np.sum(psi * applied * applied, axis=1)
                X = X @ system.A.T + applied @ system.B.T
                if noise is not None:
                    X = X + noise[t]
                belief = (filter_belief(ch, belief, delivered[:, t]) if law.endswith("tcp")
                          else ch.propagate(belief))
            total += np.einsum("si,ij,sj->s", X, W, X)
        out[k] = total
    return out


class BeliefGains:
    """The first block K(b) of a protocol's plug-in receding-horizon law planned at the belief b, cached by
    b rounded to 12 digits (one plan per distinct belief, each O(plan); more than ``budget``, by default the
    ``belief_plans`` budget, is a ResourceError offering ``most``, the most beliefs the run can meet, samples x steps,
    or inf where unknown, as the budget's value that admits the run).

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.4], r=[0.6]))          # p + r = 1: mu_t = 0.6 from any belief
    >>> gains = BeliefGains(s, "tcp", budget=2)
    >>> bool(np.allclose(gains(np.array([[0.6, 0.4]])), closed_form(s.with_mu([0.6]), "tcp").gain))
    True
    >>> K = gains.many(np.array([[[0.6, 0.4]], [[0.6 + 1e-14, 0.4 - 1e-14]], [[0.2, 0.8]]]))   # two distinct after
    >>> K.shape, len(gains.cache)                                                             # rounding
    ((3, 1, 1), 2)
    >>> try:
    ...     gains(np.array([[0.9, 0.1]]))                             # a third plan is over the budget
    ... except ResourceError as err:
    ...     print(str(err)[-42:])                                     # most=None: no bound on the beliefs
    set PACKETLOSS_CVX_BUDGET_BELIEF_PLANS=inf
    """

    def __init__(self, system: System, protocol: str, budget: int | None = None, law: str | None = None,
                 most: float | None = None) -> None:
        # budget None: the belief_plans budget as it is at the call (read then, not frozen at import)
        self.system, self.law = system, law or f"plug-in-{protocol}"     # law: MARKOV_LAWS
        self.budget = limit("belief_plans") if budget is None else budget
        self.most = float("inf") if most is None else float(most)
        self.cache: dict[bytes, np.ndarray] = {}

    def __call__(self, belief: np.ndarray) -> np.ndarray:
        """K (m×n) at one belief (m,)."""
        row = np.round(np.asarray(belief, dtype=float), 12)
        key = row.tobytes()
        if key not in self.cache:
            if len(self.cache) >= self.budget:
                most = max(self.most, len(self.cache) + 1)
                raise ResourceError(refusal_text("belief_plans", most, self.budget,
                                                 f"a plan at each distinct belief the {self.law[-3:].upper()}-like "
                                                 f"law meets (more than {self.budget:.0f} in this run: the "
                                                 "HMM-filtered belief of a channel whose outcome does not reveal its "
                                                 "state takes a new value in almost every run)",
                                                 instead="use fewer samples or steps, or the UDP-like law "
                                                         "(simulate --law udp)"), most, self.budget)
            self.cache[key] = _gain(self.system, self.law, row)
        return self.cache[key]

    def many(self, beliefs: np.ndarray) -> np.ndarray:
        """K (S, m, n) at the beliefs (S, m, K) (a distribution over each chain's states): one plan per distinct row.
        Time O(S m k log S) plus new plans.

        The distinct rows ascending (lexicographically) and each belief's row, as ``np.unique(axis=0,
        return_inverse=True)`` gives them, by a lexsort of the columns (np.unique sorts the rows as one
        structured dtype: 6x slower on 4096 beliefs)."""
        rounded = np.round(beliefs, 12)
        flat = rounded.reshape(len(rounded), -1)           # the belief rows are (m, K)
        order = np.lexsort(flat.T[::-1])                   # column 0 the primary key
        ordered = rounded[order]
        first = np.ones(len(ordered), dtype=bool)           # the first of each run of equal rows
        np.any(flat[order[1:]] != flat[order[:-1]], axis=1, out=first[1:])
        inverse = np.empty(len(ordered), dtype=np.int64)
        inverse[order] = np.cumsum(first) - 1
        return np.stack([self(row) for row in ordered[first]])[inverse]


def mode_index(good: np.ndarray, sizes: Sequence[int] | None = None) -> np.ndarray:
    """The joint state of `packetloss_cvx.model.chain.product_chain` (0 = all good, channel 0 the most significant
    bit, 1 = bad) of good-state indicators (..., m); with ``sizes`` (a MarkovChannel's k_i), of state indices
    (..., m), mixed radix with channel 0 the most significant digit. O(size).

    Examples
    --------
    >>> mode_index(np.array([[True, True], [True, False], [False, True], [False, False]])).tolist()
    [0, 1, 2, 3]
    >>> mode_index(np.array([[0, 0], [0, 2], [1, 0], [1, 2]]), sizes=(2, 3)).tolist()
    [0, 2, 3, 5]
    """
    m = good.shape[-1]
    if sizes is not None:
        place = np.cumprod([1, *sizes[:0:-1]])[::-1]                      # prod_{j > i} k_j
        return (good.astype(np.int64) * place).sum(axis=-1)
    return ((~good).astype(np.int64) << np.arange(m - 1, -1, -1)).sum(axis=-1)


def markov_loop_block(system: System, laws: Sequence[str], tcp: BeliefGains | None, udp: BeliefGains | None,
                      mode_gains: np.ndarray | None, steps: int, samples: int, losses: np.random.Generator,
                      noise: np.random.Generator, keep: int = 0) -> tuple[np.ndarray, ...]:
    """``laws`` (of "tcp", "udp", "dp") run together behind the system's chain on one block of runs.

    "tcp": the plug-in TCP-like law re-planned at the belief filtered by every acknowledged outcome (``tcp``);
    "udp": the plug-in UDP-like law at the prior propagated (``udp``, the same for every run); "dp": the
    mode-dependent law ``u = -mode_gains[mode] x`` with the current channel state known. Chain states and
    deliveries from ``losses`` (`sample_markov_paths`), noise
    from ``noise`` (`sample_noise_paths`): the Bernoulli loop's draws.
    Returns ``(run_cost, norms, stage, states)`` as `closed_loop_block`.
    Time O(laws samples steps n (n + m)) plus one plan per new belief.

    Examples
    --------
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.0], r=[1.0], belief=[0.5]))   # good for ever, or bad once
    >>> rng = np.random.default_rng
    >>> cost, norms, stage, states = markov_loop_block(s, ["dp"], None, None, np.array([[[1.0]], [[0.0]]]), 3, 40,
    ...                                                rng(0), rng(1), keep=1)
    >>> sorted({tuple(row) for row in stage[0].tolist()})   # u = -x: x -> 0 at the first delivery
    [(1.0, 2.0, 0.0), (2.0, 0.0, 0.0)]
    >>> bool(np.allclose(cost, stage.mean(axis=2))), states.shape
    (True, (1, 1, 4, 1))
    """
    ch = system.channel
    chain_states, V = sample_markov_paths(ch, steps, samples, losses)
    W = sample_noise_paths(system, steps, samples, noise)
    live = reachable_modes(ch)
    modes = (np.cumsum(live) - 1)[mode_index(chain_states, ch.sizes)]     # mode_chain's index: reachable states only
    Omega, psi = loop_weights(system)
    L = len(laws)
    X = np.broadcast_to(system.x0, (L, samples, system.n)).copy()
    norms, stage = np.empty((L, samples, steps + 1)), np.empty((L, samples, steps))
    states = np.empty((L, keep, steps + 1, system.n))
    filtered = np.repeat(ch.initial_belief[None], samples, axis=0)
    prior = np.array(ch.initial_belief, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(steps):
            norms[:, :, t] = np.linalg.norm(X, axis=2)
            states[:, :, t] = X[:, :keep]
            for k, law in enumerate(laws):
                if law == "udp":
                    u = -X[k] @ udp(prior).T
                else:
                    K = tcp.many(filtered) if law == "tcp" else mode_gains[modes[:, t]]
                    u = -np.einsum("smn,sn->sm", K, X[k])
                applied = V[:, t] * u
                stage[k, :, t] = np.einsum("si,ij,sj->s", X[k], Omega, X[k]) + applied ** 2 @ psi
                X[k] = X[k] @ system.A.T + applied @ system.B.T
            if W is not None:
                X += W[t]
            if "tcp" in laws:
                filtered = filter_belief(ch, filtered, V[:, t])
            prior = ch.propagate(prior)
        norms[:, :, steps] = np.linalg.norm(X, axis=2)
        states[:, :, steps] = X[:, :keep]
    return stage.mean(axis=2), norms, stage, states


def sample_chain_law_costs(system: System, law: ChainDP, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Realised costs, on the paper's cost (``x_0'Q x_0 + sum_t x_{t+1}'Omega_{t+1} x_{t+1} + (V_t u_t)'Psi_t (V_t
    u_t)``), of a law behind acknowledgements over the information nodes of closedloop.chain_dp (`chain_dp`'s law,
    any window) run over the system's horizon: each run draws its channel states and deliveries
    (`sample_markov_paths`) and its noise, applies ``u_t = -K_{t,j} x_t`` at its node j and moves to the node its
    outcome leads to (outcome o: the delivery bits, channel 0 first). Their mean estimates the law's expected cost
    (`chain_law_cost` is the exact one; `chain_dp`'s cost where the law is the exact DP's). Returns (samples,).
    Time O(samples N (n^2 + n m)).

    Raises
    ------
    InputError
        A law on the channel states (``information="state"``): no TCP-like controller has them.

    Examples
    --------
    >>> from packetloss_cvx.closedloop.chain_dp import chain_dp
    >>> from packetloss_cvx.model.channel import GilbertElliott
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
    ...            channel=GilbertElliott(p=[0.1], r=[0.4]))        # delivered: (1/2)^2 + 2 (1/2)^2; lost: 1
    >>> sorted(set(sample_chain_law_costs(s, chain_dp(s), 50, np.random.default_rng(0)).tolist()))
    [0.5, 1.0]
    """
    if law.information != "acknowledgements":
        raise InputError("law", "expected a law behind acknowledgements, found one on the channel states")
    N, n = system.horizon, system.n
    _, v = sample_markov_paths(system.channel, N, samples, rng)
    noise = sample_noise_paths(system, N, samples, rng)
    weights = 2 ** np.arange(system.m - 1, -1, -1)
    x = np.broadcast_to(system.x0, (samples, n)).copy()
    node = np.zeros(samples, dtype=int)
    cost = np.einsum("si,ij,sj->s", x, system.initial_weight, x)
    for t in range(N):
        _, _, nxt = law.layers[t]
        delivered = v[:, t].astype(float)
        u = -delivered * np.einsum("sij,sj->si", law.gains[t][node], x)
        x = x @ system.A.T + u @ system.B.T
        if noise is not None:
            x += noise[t]
        cost += np.einsum("si,ij,sj->s", x, system.state_weights[t], x) + (u * u) @ system.input_weights[t]
        node = nxt[node, v[:, t].astype(int) @ weights]
    return cost
