"""Receding-horizon laws in closed loop behind sampled Gilbert–Elliott chains: the simulator against
the exact second moments of the switched loop (constant gain), and the information patterns."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.closedloop.mjls import mode_chain, second_moment_operator
from packetloss_cvx.errors import BudgetError, ResourceError
from packetloss_cvx.model.chain import attach_channel
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.twins import bursty_twin
from packetloss_cvx.montecarlo.markov_loop import PLAN_BUDGET, markov_closed_loop_costs


def exact_loop_cost(system, K, steps):
    """E[sum_t x'Wx + (Vu)'Psi(Vu) + x_T'Wx_T] for u = -K x in every mode, from the second moments."""
    ch = system.channel
    modes, _, h = mode_chain(ch)
    b0 = ch.initial_belief[:, 0]                                   # P(good); mode entries 0 = good
    pi0 = np.prod(np.where(modes == 0, b0, 1 - b0), axis=1)
    op = second_moment_operator(system.A, system.B, ch, K)
    n, W, psi = system.n, system.state_weights[0], np.diag(system.input_weights[0])
    Q = np.concatenate([w * np.outer(system.x0, system.x0).ravel() for w in pi0])
    total = 0.0
    for t in range(steps + 1):
        for a in range(len(modes)):
            Qa = Q[a * n * n:(a + 1) * n * n].reshape(n, n)
            total += np.trace(W @ Qa)
            if t < steps:
                Hd = np.diag(h[a])            # Gilbert: v = h in mode a
                total += np.trace(K.T @ Hd @ psi @ Hd @ K @ Qa)
        Q = op @ Q
    return total


@pytest.mark.parametrize("seed", [0, 1])
def test_simulated_loop_matches_exact_second_moments(seed):
    rng = np.random.default_rng(seed)
    base = pl.System(A=[[1.05, 0.2], [0.0, 0.9]], B=[[1.0, 0.0], [0.3, 1.0]], horizon=5, state_weight=[1.0, 0.5],
                     input_weight=[0.5, 1.0], mu=[0.8, 0.6], x0=[1.0, -1.0])
    s = bursty_twin(base, rng.uniform(0.3, 0.9))                 # stationary start: the UDP-like gain is constant
    K = pl.closed_form(s.with_mu(s.mu_schedule), "udp").gain
    steps = 30
    costs = markov_closed_loop_costs(s, ["plug-in-udp"], steps=steps, samples=20_000, rng=rng, progress=False)[0]
    se = costs.std(ddof=1) / np.sqrt(costs.size)
    assert abs(costs.mean() - exact_loop_cost(s, K, steps)) <= 4 * se


def test_information_patterns():
    s = pl.load_example("two_actuator")
    memoryless = attach_channel(s, GilbertElliott(p=[0.1, 0.5], r=[0.9, 0.5]))
    c = markov_closed_loop_costs(memoryless, ["exact-tcp", "exact-udp"], steps=10, samples=500,
                                 rng=np.random.default_rng(0), progress=False)
    np.testing.assert_array_equal(c[0], c[1])                  # acknowledgements say nothing about the future
    bursty = bursty_twin(s, 0.9)
    c = markov_closed_loop_costs(bursty, ["exact-tcp", "exact-udp"], steps=10, samples=500,
                                 rng=np.random.default_rng(0), progress=False)
    assert not np.array_equal(c[0], c[1])
    with pytest.raises(pl.InputError, match="laws"):
        markov_closed_loop_costs(bursty, ["dp"], steps=3, samples=3)
    with pytest.raises(pl.InputError, match="Gilbert-Elliott"):
        markov_closed_loop_costs(s, steps=3, samples=3)


def test_the_older_closed_loop_api_keeps_the_plan_budget(monkeypatch):
    """h strictly between 0 and 1: the filtered belief takes a new value in almost every run, one plan each, so
    the law is refused once it meets more than the belief_plans budget (2000 by default, PLAN_BUDGET; read from
    its variable when the law is built: lowered to 60 it is met after 60 plans, not 2000, 5 s). The message names
    the variable and the most beliefs the run can meet, 3000 runs x 20 steps = 6e4 (it is no BudgetError: the count
    is met during the work, not refused before it)."""
    assert PLAN_BUDGET == 2000
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_BELIEF_PLANS", "60")
    s = pl.load_example("pendulum_bursty")
    hidden = s.with_channel(GilbertElliott(p=[0.1], r=[0.3], h_good=[0.9], h_bad=[0.2]))
    with pytest.raises(ResourceError, match=r"^a plan at each distinct belief the TCP-like law meets \(more than 60 in "
                                            r"this run: .* to run it on purpose set "
                                            r"PACKETLOSS_CVX_BUDGET_BELIEF_PLANS=6e\+04$") as err:
        markov_closed_loop_costs(hidden, ["plug-in-tcp"], steps=20, samples=3000, rng=np.random.default_rng(0),
                                 progress=False)
    assert not isinstance(err.value, BudgetError)
    assert (err.value.needed_bytes, err.value.budget_bytes) == (60000, 60)


def test_belief_gains_of_many_beliefs_are_the_gains_of_each():
    """simulation.markov_loop.BeliefGains.many (distinct rows by a lexsort) gives, belief by belief, the gain of
    that belief alone: rows equal in one column and not the other, equal after rounding to 12 digits, repeated."""
    from packetloss_cvx.montecarlo.markov_loop import BeliefGains
    s = pl.System(A=[[1.1, 0.2], [0.0, 0.9]], B=[[1.0, 0.0], [0.3, 1.0]], horizon=3, state_weight=[1.0, 1.0],
                  input_weight=[1.0, 1.0], x0=[1.0, 0.0], channel=GilbertElliott(p=[0.2, 0.3], r=[0.5, 0.6]))
    rng = np.random.default_rng(4)
    levels = np.array([0.3, 0.55, 0.8])
    good = levels[rng.integers(0, 3, size=(60, 2))]
    good[::7] += 1e-14                                              # the same plan after rounding
    beliefs = np.stack([good, 1.0 - good], axis=2)                  # (60, m, 2): P(good), P(bad)
    many = BeliefGains(s, "tcp").many(beliefs)
    one = BeliefGains(s, "tcp")
    np.testing.assert_array_equal(many, np.stack([one(b) for b in beliefs]))
