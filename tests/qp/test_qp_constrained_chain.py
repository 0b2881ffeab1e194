"""Chance rows behind a Markov channel (qp/constrained.py, model/chain.delivery_factor; docs/mathematics.md §7,
"Behind a chain"): posed with the covariance of the delivery indicators under the chain, the cost the plug-in one.

References, none taken from the code under test: the two-state chain's covariance by hand
(``lambda^(l-j) b_j (1 - b_j)`` off the diagonal); the deliveries' moments and the state's law by enumerating every
delivery path with its exact probability under the chain (a forward pass over the hidden states); the probability of
a row's violation as the sum over paths of the Gaussian tail of the noise (or of the path's indicator without
noise); the Bernoulli program where the chain has no memory."""

import itertools

import numpy as np
import pytest
from scipy.stats import norm

from packetloss_cvx.errors import InputError
from packetloss_cvx.model.chain import delivery_factor
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo.mpc import simulate_mpc
from packetloss_cvx.qp.constrained import CHAIN_ROWS, ConstrainedQP
from packetloss_cvx.tolerances import CONSTRAINED_ACTIVE_RTOL, CONSTRAINED_AGREEMENT_RTOL, CONSTRAINED_KKT_RTOL


def _paths(T, d, pi0, k):
    """Every delivery path of length k of one chain (transition T, delivery d per state, start pi0) with its exact
    probability: the hidden state summed out step by step."""
    out = []
    for v in itertools.product((0, 1), repeat=k):
        b = np.asarray(pi0, dtype=float)
        for x in v:
            b = (b * (d if x else 1.0 - d)) @ T
        out.append((np.array(v, dtype=float), float(b.sum())))
    return out


def _joint_paths(chains, k):
    """Delivery paths (k, m) of independent channels and their probabilities (products of each channel's)."""
    per = [_paths(T, d, pi0, k) for T, d, pi0 in chains]
    for combo in itertools.product(*per):
        yield np.stack([v for v, _ in combo], axis=1), float(np.prod([p for _, p in combo]))


def _enumerated_covariance(T, d, pi0, k):
    paths = _paths(T, d, pi0, k)
    mean = sum(p * v for v, p in paths)
    second = sum(p * np.outer(v, v) for v, p in paths)
    return second - np.outer(mean, mean)


def _row_law(A, B, x0, W, U, a, chains, k):
    """(probabilities, path means of a'x_k, noise variance of a'x_k) over every joint delivery path to step k."""
    n = A.shape[0]
    noise, P = 0.0, np.eye(n)
    for _ in range(k):
        noise += a @ P @ W @ P.T @ a
        P = A @ P
    probs, means = [], []
    for v, p in _joint_paths(chains, k):
        x = np.asarray(x0, dtype=float)
        for t in range(k):
            x = A @ x + B @ (v[t] * U[t])
        probs.append(p)
        means.append(a @ x)
    return np.array(probs), np.array(means), noise


def _violation(system, U, a, b, chains):
    """P(a'x_k > b), k = 1..N, under the chain: the Gaussian tail of the noise summed over the delivery paths (the
    path's indicator, beyond a rounding margin, without noise)."""
    out = []
    for k in range(1, system.horizon + 1):
        probs, means, noise = _row_law(system.A, system.B, system.x0, system.noise_cov, U, a, chains, k)
        if noise > 0:
            tail = norm.sf((b - means) / np.sqrt(noise))
        else:
            tail = (means - b > 1e-9 * max(1.0, abs(b))).astype(float)
        out.append(float(probs @ tail))
    return np.array(out)


def _cantelli(system, U, a, eps, chains):
    """a'E[x_k] + sqrt((1 - eps)/eps) std(a'x_k), k = 1..N, the moments enumerated under the chain."""
    out = []
    for k in range(1, system.horizon + 1):
        probs, means, noise = _row_law(system.A, system.B, system.x0, system.noise_cov, U, a, chains, k)
        mean = probs @ means
        out.append(mean + np.sqrt((1 - eps) / eps * (probs @ (means - mean) ** 2 + noise)))
    return np.array(out)


def _gilbert(p, r, belief):
    return np.array([[1 - p, p], [r, 1 - r]]), np.array([1.0, 0.0]), np.array([belief, 1 - belief])


def test_the_delivery_covariance_of_a_gilbert_chain_is_the_hand_value():
    """p = 0.1, r = 0.3 (lambda = 0.6), P(good) = 0.5 at step 0, then 0.6 and 0.66: variances b (1 - b), covariances
    lambda^(l-j) b_j (1 - b_j); the first k rows of F give the covariance of the deliveries before step k, having no
    entry in the columns of later steps."""
    s = System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=GilbertElliott(p=[0.1], r=[0.3], belief=[0.5]))
    hand = np.array([[0.25, 0.15, 0.09], [0.15, 0.24, 0.144], [0.09, 0.144, 0.66 * 0.34]])
    F = delivery_factor(s).matrix(0)                    # columns: 3 steps x 2 states, then 3 delivery coins
    for k in (1, 2, 3):
        assert np.allclose(F[:k] @ F[:k].T, hand[:k, :k], rtol=0, atol=1e-15)
        later = [c for c in range(F.shape[1]) if (c < 6 and c // 2 >= k) or (c >= 6 and c - 6 >= k)]
        assert not np.any(F[:k, later])


@pytest.mark.parametrize("case", ["gilbert-noisy", "three-state", "known-bad"])
def test_the_delivery_covariance_is_the_enumerated_one(case):
    """Against E[v v'] - E[v] E[v]' over the 2^8 delivery paths with their probabilities under the chain: a Gilbert
    channel delivering within each state with probability 0.95 and 0.1, a three-state chain, and a chain known to
    be bad at step 0 (no delivery: a zero variance, a zero pivot)."""
    N = 8
    if case == "gilbert-noisy":
        channel = GilbertElliott(p=[0.2], r=[0.1], h_good=[0.95], h_bad=[0.1], belief=[0.3])
        T, d, pi0 = np.array([[0.8, 0.2], [0.1, 0.9]]), np.array([0.95, 0.1]), np.array([0.3, 0.7])
    elif case == "three-state":
        T = np.array([[0.7, 0.2, 0.1], [0.3, 0.6, 0.1], [0.05, 0.15, 0.8]])
        d, pi0 = np.array([1.0, 0.6, 0.0]), np.array([0.2, 0.5, 0.3])
        channel = MarkovChannel(transition=[T], delivery=[d], belief=[pi0])
    else:
        channel = GilbertElliott(p=[0.05], r=[0.2], state=["bad"])
        T, d, pi0 = np.array([[0.95, 0.05], [0.2, 0.8]]), np.array([1.0, 0.0]), np.array([0.0, 1.0])
    s = System(A=[[1.0]], B=[[1.0]], horizon=N, state_weight=[1.0], input_weight=[1.0], x0=[1.0], channel=channel)
    F = delivery_factor(s).matrix(0)
    reference = _enumerated_covariance(T, d, pi0, N)
    assert np.allclose(F @ F.T, reference, rtol=0, atol=1e-14)
    for k in (1, 2, 5):                              # the rows at step k see the deliveries before k
        assert np.allclose(F[:k] @ F[:k].T, _enumerated_covariance(T, d, pi0, k), rtol=0, atol=1e-14)


def _bursty(noise, p=0.05, r=0.15):
    """x' = x + v u from x0 = -2, N = 6, Q = 1, R = 0.1: the cost drives x up to 0, the row P(x_k <= -0.5) >= 0.7
    holds it back. A Gilbert channel with lambda = 0.8 (bursts of 1/r steps), P(good) = 1/2 at the plan's start."""
    kw = {"noise_cov": [[noise]]} if noise else {}
    s = System(A=[[1.0]], B=[[1.0]], horizon=6, state_weight=[1.0], input_weight=[0.1], x0=[-2.0],
               channel=GilbertElliott(p=[p], r=[r], belief=[0.5]), **kw)
    return s, Constraints(u_min=[-3.0], u_max=[3.0], chance=[[[1.0], -0.5, 0.3]]), [_gilbert(p, r, 0.5)]


@pytest.mark.parametrize(("protocol", "noise"), [("tcp", 0.0), ("udp", 0.0), ("udp", 1e-4)])
def test_the_exact_rows_hold_under_the_chain_where_the_plug_in_rows_do_not(protocol, noise):
    """The plan of the exact program keeps P(x_k > b) <= eps at every k under the chain (enumerated: every delivery
    path's Gaussian tail, or its indicator without noise); the plug-in program's plan (the losses taken as
    independent) breaks the row: with the first inputs delivered in a burst the state overshoots, P = 0.43 > 0.3."""
    s, c, chains = _bursty(noise)
    exact = ConstrainedQP(s, protocol, c).solve()
    plug_in = ConstrainedQP(s.with_mu(s.mu_schedule), protocol, c).solve()
    assert exact.chance_rows == CHAIN_ROWS
    assert plug_in.chance_rows == ""
    assert any(label.startswith("chance[0]") for label in exact.binding)
    held = _violation(s, exact.inputs, np.array([1.0]), -0.5, chains)
    broken = _violation(s, plug_in.inputs, np.array([1.0]), -0.5, chains)
    assert held.max() <= 0.3
    assert broken.max() > 0.4
    # the exact program's rows are Cantelli's inequality on the enumerated moments, tight where they bind
    kappa_rows = _cantelli(s, exact.inputs, np.array([1.0]), 0.3, chains)
    assert np.all(kappa_rows <= -0.5 + CONSTRAINED_ACTIVE_RTOL)
    bound = [int(label.split("k=")[1]) - 1 for label in exact.binding if label.startswith("chance[0]")]
    assert np.allclose(kappa_rows[bound], -0.5, rtol=0, atol=CONSTRAINED_ACTIVE_RTOL)
    assert _cantelli(s, plug_in.inputs, np.array([1.0]), 0.3, chains).max() > -0.5 + 0.1
    # the cost stays the plug-in one: the exact program's plan priced by the plug-in program's cost
    assert exact.cost >= plug_in.cost


def test_two_independent_channels_add_their_own_terms():
    """Two Gilbert channels of different memory, one row on both states: at the plan, a'E[x_k] + kappa std(a'x_k)
    with the moments enumerated over the 2^(2k) joint delivery paths is at most b, equal where the row binds."""
    chains = [_gilbert(0.05, 0.15, 0.6), _gilbert(0.1, 0.1, 0.3)]
    s = System(A=[[1.0, 0.1], [0.0, 0.9]], B=[[1.0, 0.0], [0.2, 1.0]], horizon=4, state_weight=[1.0, 1.0],
               input_weight=[0.1, 0.1], x0=[-2.0, -1.5], noise_cov=[[1e-3, 0.0], [0.0, 1e-3]],
               channel=GilbertElliott(p=[0.05, 0.1], r=[0.15, 0.1], belief=[0.6, 0.3]))
    a, b, eps = np.array([1.0, 1.0]), -1.5, 0.3
    c = Constraints(u_min=[-3.0, -3.0], u_max=[3.0, 3.0], chance=[[a.tolist(), b, eps]])
    for protocol in ("tcp", "udp"):
        sol = ConstrainedQP(s, protocol, c).solve()
        rows = _cantelli(s, sol.inputs, a, eps, chains)
        bound = [int(label.split("k=")[1]) - 1 for label in sol.binding if label.startswith("chance[0]")]
        assert bound
        assert np.all(rows <= b + CONSTRAINED_ACTIVE_RTOL)
        assert np.allclose(rows[bound], b, rtol=0, atol=CONSTRAINED_ACTIVE_RTOL)


def test_a_memoryless_chain_gives_the_bernoulli_program():
    """lambda = 1 - p - r = 0: the deliveries are independent (the chain's rows are equal, up to the rounding of
    1 - 0.7), the covariance is diagonal to rounding, and the exact program's plan and cost are the Bernoulli
    program's at the same mu_t."""
    s = System(A=[[1.2, 0.1], [0.0, 0.8]], B=[[1.0, 0.0], [0.3, 1.0]], horizon=6, state_weight=[1.0, 2.0],
               input_weight=[0.2, 0.1], x0=[-2.0, 1.0], noise_cov=[[1e-3, 0.0], [0.0, 2e-3]],
               channel=GilbertElliott(p=[0.3, 0.6], r=[0.7, 0.4], belief=[0.2, 0.9]))
    for i in range(2):
        C = delivery_factor(s).matrix(i) @ delivery_factor(s).matrix(i).T
        assert np.abs(C - np.diag(np.diag(C))).max() <= 4 * np.finfo(float).eps * np.diag(C).max()
    c = Constraints(u_min=[-3.0, -3.0], u_max=[3.0, 3.0], chance=[[[1.0, 0.5], -0.8, 0.2]])
    for protocol in ("tcp", "udp"):
        exact = ConstrainedQP(s, protocol, c).solve()
        bernoulli = ConstrainedQP(s.with_mu(s.mu_schedule), protocol, c).solve()
        assert any(label.startswith("chance[0]") for label in exact.binding)
        assert exact.binding == bernoulli.binding
        scale = float(np.abs(bernoulli.inputs).max())
        assert np.abs(exact.inputs - bernoulli.inputs).max() <= 1e-12 * scale
        assert exact.cost == pytest.approx(bernoulli.cost, rel=1e-13)


def test_a_new_belief_re_solves_as_a_program_built_for_it():
    """The Parameters (the covariance factors and mu_t) follow the belief: each re-solve is the program built from
    scratch for that belief, the first plan's factor not kept."""
    s, c, _ = _bursty(1e-4)
    qp = ConstrainedQP(s, "udp", c)
    for b in (0.5, 0.95, 0.1, 0.5):
        belief = [[b, 1 - b]]
        again = qp.solve(belief=belief)
        fresh = ConstrainedQP(s.with_channel(s.channel.with_belief(belief)), "udp", c).solve()
        assert np.abs(again.inputs - fresh.inputs).max() <= CONSTRAINED_AGREEMENT_RTOL * np.abs(fresh.inputs).max()
        assert again.cost == pytest.approx(fresh.cost, rel=CONSTRAINED_AGREEMENT_RTOL)


def test_a_chain_takes_a_belief_and_bernoulli_losses_a_mu():
    s, c, _ = _bursty(0.0)
    with pytest.raises(InputError, match="belief"):
        ConstrainedQP(s, "tcp", c).solve(mu=[0.5])
    with pytest.raises(InputError, match="give mu"):
        ConstrainedQP(s.with_mu(s.mu_schedule), "tcp", c).solve(belief=[[0.5, 0.5]])


def test_the_loop_plans_behind_a_chain_with_the_exact_rows():
    """The expected-cost controller's first command behind a chain is the exact program's first input at the
    channel's belief (the loop starts there), not the plug-in program's."""
    s, c, _ = _bursty(1e-4)
    sim = simulate_mpc(s, c, samples=2, steps=1, seed=0, protocols=["udp"], controllers=["expected-cost"], keep=2,
                       progress=False)
    first = sim.runs["udp"]["expected-cost"].inputs[:, 0]
    exact = ConstrainedQP(s, "udp", c, u_prev=True).solve().inputs[0]
    plug_in = ConstrainedQP(s.with_mu(s.mu_schedule), "udp", c, u_prev=True).solve().inputs[0]
    assert np.allclose(first, exact, rtol=CONSTRAINED_AGREEMENT_RTOL, atol=0)
    assert not np.allclose(first, plug_in, rtol=1e-3, atol=0)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_rows_held_at_their_kink_pass_the_kkt_check_behind_a_chain(protocol):
    """x0 on the bound, no noise, every mu_t below 1 - eps: no input may act on the row (the spread it adds exceeds
    the mean it moves), so the rows hold at the norm's kink, where the KKT check takes the subgradient of the ball
    {kappa F_k z} (F_k F_k' = Q_k, a full matrix behind a chain) that best cancels the rest."""
    s = System(A=[[1.0]], B=[[1.0]], horizon=4, state_weight=[1.0], input_weight=[0.1], x0=[-0.5],
               channel=GilbertElliott(p=[0.05], r=[0.15], belief=[0.5]))
    assert s.mu_schedule.max() < 0.7
    sol = ConstrainedQP(s, protocol, Constraints(u_min=[-3.0], u_max=[3.0], chance=[[[1.0], -0.5, 0.3]])).solve()
    assert np.abs(sol.inputs).max() <= 1e-8
    assert sol.binding == tuple(f"chance[0] at k={k}" for k in range(1, 5))
    assert sol.kkt_residual <= CONSTRAINED_KKT_RTOL


def test_the_programs_rows_are_cantellis_on_the_enumerated_moments():
    """The cones the solver sees, evaluated at random plans (not at the optimum, which the polish refines on the
    moments, so a wrong cone with the right active set would go unseen there): a'E[x_k] + kappa ||F_k'(h_k ∘ u); s_k||
    is a'E[x_k] + kappa std(a'x_k) with the moments enumerated over the joint delivery paths of two channels of
    different memory, one of them with three states."""
    G2, d2, pi2 = np.array([[0.95, 0.05], [0.15, 0.85]]), np.array([1.0, 0.1]), np.array([0.6, 0.4])
    T3 = np.array([[0.7, 0.2, 0.1], [0.3, 0.6, 0.1], [0.05, 0.15, 0.8]])
    d3, pi3 = np.array([1.0, 0.6, 0.0]), np.array([0.2, 0.5, 0.3])
    channel = MarkovChannel(transition=[G2, T3], delivery=[d2, d3], belief=[pi2, pi3])
    s = System(A=[[1.0, 0.1], [0.0, 0.9]], B=[[1.0, 0.0], [0.2, 1.0]], horizon=4, state_weight=[1.0, 1.0],
               input_weight=[0.1, 0.1], x0=[-2.0, -1.5], noise_cov=[[1e-3, 0.0], [0.0, 1e-3]], channel=channel)
    a, eps = np.array([1.0, 1.0]), 0.3
    qp = ConstrainedQP(s, "tcp", Constraints(chance=[[a.tolist(), -1.5, eps]]), formulation="condensed")
    qp.solve()                                                  # sets the Parameters from the channel's belief
    rows = [con for con in qp.problem.constraints if "delivery_innovation" in str(con)]
    assert len(rows) == s.horizon
    for U in np.random.default_rng(5).normal(size=(3, 4, 2)):
        qp.U.value = U
        lhs = np.array([con.args[0].value for con in rows]).ravel()
        assert np.allclose(lhs, _cantelli(s, U, a, eps, [(G2, d2, pi2), (T3, d3, pi3)]), rtol=1e-12, atol=1e-12)
