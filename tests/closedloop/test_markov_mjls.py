"""The switched loop as a Markov jump linear system: coupled Riccati equations against a hand-derived
two-mode scalar case, policy evaluation and Monte Carlo; the mean-square radius against a hand 2×2
operator and against simulated second moments (a stable and an unstable loop); the memoryless
reduction to the Bernoulli TCP-like Riccati equation."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.closedloop.law_stability import loop_stability
from packetloss_cvx.closedloop.mjls import coupled_riccati, mean_square_radius, mode_chain, second_moment_operator
from packetloss_cvx.errors import NumericalError
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.twins import bursty_twin
from packetloss_cvx.montecarlo.markov_channels import sample_markov_deliveries, sample_states

PHI = (1 + 5**0.5) / 2


def scalar(p, r, a=1.0, h_good=1.0, h_bad=0.0, state=None):
    return pl.System(A=[[a]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                     channel=GilbertElliott(p=[p], r=[r], h_good=[h_good], h_bad=[h_bad], state=state))


def test_hand_derived_two_mode_scalar():
    # a = b = q = psi = 1, p = 0 (good is absorbing): P_g = 1 + P_g - P_g^2 / (P_g + 1), so P_g^2 = P_g + 1,
    # P_g = phi; P_b = 1 + r P_g + (1 - r) P_b, so P_b = (1 + r phi) / r; K_g = P_g / (P_g + 1) = 1 / phi. The bad
    # mode never delivers: its gain is the input it would best send were the packet to arrive, E_b / (E_b + 1) with
    # E_b = r P_g + (1 - r) P_b = 1 + phi = phi^2 (the limit of its optimal gain as h_bad -> 0+). The chain starts
    # bad, so both modes are met (from the stationary law, good for ever, only the good one: the next test).
    res = coupled_riccati(scalar(0.0, 0.5, state=["bad"]))
    np.testing.assert_allclose(res.cost_matrices.ravel(), [PHI, (1 + 0.5 * PHI) / 0.5], rtol=1e-12)
    np.testing.assert_allclose(res.gains.ravel(), [1 / PHI, PHI**2 / (PHI**2 + 1)], rtol=1e-12)
    # closed loop: good mode x+ = (1 - 1/phi) x forever after the first good step; bad mode x+ = x.
    # Operator [[g (1-p), b r], [g p, b (1-r)]] with g = (1 - 1/phi)^2, b = 1: radius max(g, 1 - r) = 0.5
    assert res.spectral_radius == pytest.approx(0.5, rel=1e-12)


@pytest.mark.parametrize("start", [{}, {"state": ["good"]}])
def test_a_start_that_never_meets_the_bad_state_leaves_it_out(start):
    """p = 0 from good (given, or the stationary law): the bad mode is never met, so the loop is the deterministic
    one x+ = (a - K) x, whatever the bad state would do. a = 1.2: the scalar DARE P = 1 + a^2 P / (P + 1), K = a P /
    (P + 1), radius (a - K)^2; a fixed gain K: (a - K)^2, while the bad mode alone (no delivery, kept with
    probability 1 - r = 0.7) would give a^2 0.7 = 1.008."""
    a = 1.2
    s = pl.System(A=[[a]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                  channel=GilbertElliott(p=[0.0], r=[0.3], **start))
    P = (a * a + np.sqrt(a**4 + 4)) / 2                      # P^2 - a^2 P - 1 = 0
    res = coupled_riccati(s)
    np.testing.assert_allclose([res.cost_matrices.ravel()[0], res.gains.ravel()[0]], [P, a * P / (P + 1)], rtol=1e-12)
    assert res.modes.tolist() == [[0]]
    assert res.spectral_radius == pytest.approx((a - a * P / (P + 1)) ** 2, rel=1e-12)
    k = 0.793369
    assert mean_square_radius(s.A, s.B, s.channel, np.array([[k]])) == pytest.approx((a - k) ** 2, rel=1e-12)
    assert loop_stability(s, [[k]]).stable
    assert mean_square_radius(s.A, s.B, s.channel.with_belief([[0.5, 0.5]]), np.array([[k]])) > 1.0


@pytest.mark.parametrize(("p", "r", "a", "k"), [(0.2, 0.3, 1.5, 1.2), (0.05, 0.1, 1.2, 1.0), (0.6, 0.7, 0.9, -0.4)])
def test_radius_matches_the_hand_two_by_two_operator(p, r, a, k):
    g, b = (a - k) ** 2, a**2
    tr, det = (1 - p) * g + (1 - r) * b, (1 - p - r) * g * b
    hand = (tr + np.sqrt(tr * tr - 4 * det)) / 2
    ch = GilbertElliott(p=[p], r=[r])
    assert mean_square_radius(np.array([[a]]), np.array([[1.0]]), ch, np.array([[k]])) == pytest.approx(hand, rel=1e-12)


def simulated_second_moments(system, gains, steps, samples, seed):
    """E||x_k||^2 by sampling the chain and its deliveries; returns (means, standard errors) per step."""
    ch = system.channel
    rng = np.random.default_rng(seed)
    states = sample_states(ch, steps, samples, rng)                      # (S, T, m): 0 = good, 1 = bad
    good = states == 0
    # mode index: product of state indices, channel 0 the most significant bit (1 = bad)
    index = np.sum(states * 2 ** np.arange(ch.m - 1, -1, -1), axis=2)
    # the deliveries given the states (h_good = 1, h_bad = 0 here: v = good)
    X = np.repeat(system.x0[None], samples, axis=0)
    out = []
    for t in range(steps):
        K = gains[index[:, t]]                                           # (S, m, n)
        v = good[:, t].astype(float)
        u = -np.einsum("smn,sn->sm", K, X) * v
        X = X @ system.A.T + u @ system.B.T
        sq = np.sum(X * X, axis=1)
        out.append((sq.mean(), sq.std(ddof=1) / np.sqrt(samples)))
    return np.array(out)


def exact_second_moments(system, gains, steps):
    """E||x_k||^2 by iterating the second-moment operator from Q_a(0) = pi0_a x0 x0'."""
    ch = system.channel
    modes, _, _ = mode_chain(ch)
    b0 = ch.initial_belief[:, 0]                                   # P(good); mode entries 0 = good
    pi0 = np.prod(np.where(modes == 0, b0, 1 - b0), axis=1)
    op = second_moment_operator(system.A, system.B, ch, gains)
    n = system.n
    Q = np.concatenate([w * np.outer(system.x0, system.x0).ravel() for w in pi0])
    out = []
    for _ in range(steps):
        Q = op @ Q
        out.append(sum(np.trace(Q[a * n * n:(a + 1) * n * n].reshape(n, n)) for a in range(len(modes))))
    return np.array(out)


@pytest.mark.parametrize(("a", "k", "stable"), [(1.2, 0.6, True), (1.2, 0.2, False)])
def test_radius_against_simulation(a, k, stable):
    s = pl.System(A=[[a, 0.1], [0.0, 0.8]], B=[[1.0], [0.5]], horizon=1, state_weight=[1, 1], input_weight=[1.0],
                  x0=[1.0, 1.0], channel=GilbertElliott(p=[0.1], r=[0.4]))
    modes, _, _ = mode_chain(s.channel)
    gains = np.array([[[k, 0.0]] for _ in modes])
    radius = mean_square_radius(s.A, s.B, s.channel, gains)
    assert (radius < 1) == stable
    steps = 25
    exact = exact_second_moments(s, gains, steps)
    sim = simulated_second_moments(s, gains, steps, 40_000, seed=3)
    for t in (4, 12, 24):
        assert abs(sim[t, 0] - exact[t]) <= 4 * sim[t, 1]
    assert (exact[-1] < exact[9]) == stable
    growth = (exact[-1] / exact[-6]) ** (1 / 5)                          # the asymptotic rate is the radius
    assert growth == pytest.approx(radius, rel=0.05)


def policy_cost(system, gains, iterations=20000):
    """The cost matrices of a fixed mode-dependent law by coupled Lyapunov iteration (policy evaluation)."""
    modes, T, h = mode_chain(system.channel)
    A, B, W, psi = system.A, system.B, system.state_weights[0], np.diag(system.input_weights[0])
    Z = np.zeros((len(modes), system.n, system.n))
    for _ in range(iterations):
        E = np.einsum("ab,bij->aij", T, Z)
        new = np.empty_like(Z)
        for a in range(len(modes)):
            v = h[a]                                                     # 0/1 for the Gilbert channel
            G = A - B @ (v[:, None] * gains[a])
            Ka = v[:, None] * gains[a]
            new[a] = W + Ka.T @ psi @ Ka + G.T @ E[a] @ G
        if np.max(np.abs(new - Z)) <= 1e-13 * np.max(np.abs(new)):
            return new
        Z = new
    raise AssertionError("policy evaluation did not converge")


def test_gains_are_optimal_by_policy_evaluation():
    s = bursty_twin(pl.load_example("two_actuator"), 0.8)
    res = coupled_riccati(s)
    Z = policy_cost(s, res.gains)
    np.testing.assert_allclose(Z, res.cost_matrices, rtol=1e-8)
    rng = np.random.default_rng(0)
    x = np.array([1.0, -0.5])
    for _ in range(5):                                                   # any other stabilising law costs more
        other = res.gains + 0.05 * rng.normal(size=res.gains.shape)
        if mean_square_radius(s.A, s.B, s.channel, other) < 1:
            assert np.all(np.einsum("i,aij,j->a", x, policy_cost(s, other), x)
                          > np.einsum("i,aij,j->a", x, res.cost_matrices, x))


def test_memoryless_chain_gives_the_bernoulli_riccati():
    s = bursty_twin(pl.load_example("pendulum"), 0.0)                    # p = 0.1, r = 0.9: Bernoulli(0.9)
    res = coupled_riccati(s)
    pi = s.channel.stationary[0, 0]
    P = pi * res.cost_matrices[0] + (1 - pi) * res.cost_matrices[1]
    A, B, W, psi = s.A, s.B, s.state_weights[0], s.input_weights[0]
    G = B.T @ P @ B + psi
    rhs = W + A.T @ P @ A - 0.9 * A.T @ P @ B @ np.linalg.solve(G, B.T @ P @ A)
    assert np.max(np.abs(rhs - P)) <= 1e-8 * np.max(np.abs(P))
    np.testing.assert_allclose(res.gains[0], np.linalg.solve(G, B.T @ P @ A), rtol=1e-8)
    # the mode that never delivers: its gain is the delivered mode's (one input, the same E, G = B'PB + psi)
    np.testing.assert_allclose(res.gains[1], np.linalg.solve(G, B.T @ P @ A), rtol=1e-8)


def test_general_delivery_probabilities_and_errors():
    # h_bad > 0: the bad mode still gets a gain; h_good = h_bad makes the modes identical
    same = coupled_riccati(scalar(0.2, 0.3, a=1.1, h_good=0.6, h_bad=0.6))
    np.testing.assert_allclose(same.cost_matrices[0], same.cost_matrices[1], rtol=1e-12)
    with pytest.raises(pl.InputError, match="Gilbert-Elliott"):
        coupled_riccati(pl.load_example("pendulum"))
    with pytest.raises(pl.NumericalError, match="not mean-square stabilisable"):
        coupled_riccati(scalar(0.5, 0.05, a=3.0), max_iter=2000)
    delivered = sample_markov_deliveries(GilbertElliott(p=[0.5], r=[0.5], h_good=[0.6], h_bad=[0.6]), 4, 20_000,
                                         np.random.default_rng(1))
    assert abs(delivered.mean() - 0.6) <= 4 * np.sqrt(0.24 / delivered.size)


def test_coupled_riccati_without_stabilising_gains_is_a_numerical_error():
    """two_actuator behind Gilbert channels with lambda = 0.95: the coupled iteration diverged, and
    its overflowing S made np.linalg.solve raise LinAlgError ('unexpected LinAlgError' in simulate)."""
    system = bursty_twin(pl.load_example("two_actuator"), 0.95)
    with pytest.raises(NumericalError, match="not mean-square stabilisable"):
        coupled_riccati(system)


# ---------------------------------------------------------------- fractional delivery probabilities
# (with h not 0 or 1 the coupled equations gain the loss-variance term h (1 - h) and the delivered input's weight
# M Psi; the references below are a hand root and an enumeration of the delivery patterns, neither written with the
# module's algebra)

def test_equal_fractional_h_is_the_scalar_modified_riccati_by_hand():
    # h_good = h_bad = 0.6: deliveries are Bernoulli(0.6) whatever the mode. Scalar a = 1.1, b = q = psi = 1:
    # E[(a - v k)^2] P + q + 0.6 k^2 is least at k = a P / (P + 1) (the variance 0.24 k^2 P included), and
    # P = 1 + a^2 P - 0.6 a^2 P^2 / (P + 1), i.e. 0.516 P^2 - 1.21 P - 1 = 0
    res = coupled_riccati(scalar(0.2, 0.3, a=1.1, h_good=0.6, h_bad=0.6))
    P = (1.21 + np.sqrt(1.21**2 + 4 * 0.516)) / (2 * 0.516)
    assert P == pytest.approx(2.992562, abs=1e-6)
    np.testing.assert_allclose(res.cost_matrices.ravel(), [P, P], rtol=1e-10)
    np.testing.assert_allclose(res.gains.ravel(), [1.1 * P / (P + 1)] * 2, rtol=1e-10)


def enumerated_bellman(s, P):
    """The right-hand side of the coupled equations with the expectation over deliveries taken by enumerating
    the 2^m patterns of each mode: min_u sum_v p(v | a) [(A x + B V u)' E_a (A x + B V u) + (V u)' Psi (V u)]. The
    gain row of an actuator i that cannot deliver in mode a is the minimiser given v_i = 1 (the other inputs at the
    law's, their patterns enumerated), the limit of the optimal row as h_{a,i} -> 0+."""
    import itertools

    modes, T, h = mode_chain(s.channel)
    A, B, W, Psi = s.A, s.B, s.state_weights[0], np.diag(s.input_weights[0])
    out, gains = np.empty_like(P), np.zeros((len(modes), s.m, s.n))
    for a in range(len(modes)):
        E = sum(T[a, b] * P[b] for b in range(len(modes)))
        H, L = np.zeros((s.m, s.m)), np.zeros((s.m, s.n))
        for v in itertools.product([0, 1], repeat=s.m):
            V = np.diag(v).astype(float)
            prob = np.prod([h[a, i] if v[i] else 1 - h[a, i] for i in range(s.m)])
            H += prob * V @ (B.T @ E @ B + Psi) @ V
            L += prob * V @ B.T @ E @ A
        on = h[a] > 0
        K = np.linalg.solve(H[np.ix_(on, on)], L[on])
        gains[a][on] = K
        out[a] = W + A.T @ E @ A - L[on].T @ K
        for i in np.flatnonzero(~on):
            Hi, Li = np.zeros(s.m), np.zeros(s.n)
            for v in itertools.product([0, 1], repeat=s.m):
                if not v[i]:
                    continue
                V = np.diag(v).astype(float)
                prob = np.prod([(h[a, j] if v[j] else 1 - h[a, j]) for j in range(s.m) if j != i])
                Hi += prob * (V @ (B.T @ E @ B + Psi) @ V)[i]
                Li += prob * (V @ B.T @ E @ A)[i]
            gains[a][i] = (Li - Hi[on] @ K) / Hi[i]
    return out, gains


@pytest.mark.parametrize("seed", range(6))
def test_fractional_h_coupled_riccati_solves_the_enumerated_bellman_equation(seed):
    rng = np.random.default_rng(seed)
    n, m = 2, 2
    A = rng.normal(size=(n, n))
    A *= 1.05 / max(abs(np.linalg.eigvals(A)))
    hg, hb = rng.uniform(0.55, 0.95, m), rng.uniform(0.05, 0.5, m)
    if seed == 0:
        hb[1] = 0.0                                                  # a mode in which one actuator cannot deliver
    s = pl.System(A=A, B=rng.normal(size=(n, m)), horizon=2, state_weight=rng.uniform(0.5, 2, n),
                  input_weight=rng.uniform(0.5, 2, m), x0=[1.0, 0.0],
                  channel=GilbertElliott(p=rng.uniform(0.05, 0.4, m), r=rng.uniform(0.2, 0.8, m), h_good=hg,
                                         h_bad=hb))
    res = coupled_riccati(s)
    rhs, gains = enumerated_bellman(s, res.cost_matrices)
    np.testing.assert_allclose(rhs, res.cost_matrices, rtol=1e-12, atol=1e-12 * np.max(np.abs(rhs)))
    np.testing.assert_allclose(res.gains, gains, rtol=1e-10, atol=1e-12)


def test_fractional_h_jump_law_stage_costs_by_hand_and_by_the_bernoulli_moments():
    from packetloss_cvx.closedloop.mjls import jump_law_stage_costs
    from packetloss_cvx.closedloop.moments import finite_horizon_costs

    # t = 0 by hand: x0 = 1, u = -k x0 delivered with probability 0.6: E[x0^2 + psi (v u)^2] = 1 + 0.6 * 2 * k^2
    s = pl.System(A=[[1.1]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[2.0], x0=[1.0],
                  channel=GilbertElliott(p=[0.2], r=[0.3], h_good=[0.6], h_bad=[0.6]))
    k = 0.7
    costs = jump_law_stage_costs(s, np.full((2, 1, 1), k), 6)
    assert costs[0] == pytest.approx(1 + 0.6 * 2 * k**2, rel=1e-14)
    # every step: equal h makes the deliveries Bernoulli(0.6), the moments of simulation.moments
    bernoulli = pl.System(A=[[1.1]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[2.0], x0=[1.0], mu=[0.6])
    stage, _ = finite_horizon_costs(bernoulli, [[k]], 6)
    np.testing.assert_allclose(costs, stage, rtol=1e-12)
    # two channels, fractional and unequal h: t = 0 averaged over the initial belief's modes by hand
    ch = GilbertElliott(p=[0.2, 0.1], r=[0.3, 0.5], h_good=[0.9, 0.8], h_bad=[0.3, 0.1], belief=[0.7, 0.4])
    s2 = pl.System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[2.0, 3.0],
                   x0=[1.0, -2.0], channel=ch)
    K = np.array([[0.5, 0.0], [0.0, 0.25]])                                  # u = (-0.5, 0.5)
    mu0 = 0.7 * 0.9 + 0.3 * 0.3, 0.4 * 0.8 + 0.6 * 0.1                      # P(delivered) at t = 0 per channel
    first = jump_law_stage_costs(s2, np.broadcast_to(K, (4, 2, 2)), 1)[0]
    assert first == pytest.approx(5.0 + 2.0 * mu0[0] * 0.25 + 3.0 * mu0[1] * 0.25, rel=1e-14)


@pytest.mark.parametrize("delivery", ["current", "next"])
def test_jump_law_stage_costs_decay_with_the_loop_over_a_long_horizon(delivery):
    """A mean-square stable loop's costs decay at its radius for ever: the moment recursion is linear in Q, the
    rounding's non-symmetric part included. Reference: vec(Q) powered by the dense operator (Kronecker products),
    the stage cost sum_a tr(W_a Q_a) with W_a built by hand; for "next" the decay rate against the radius. (A
    recursion that read Q' for Q in one term grew its rounding's skew part by 1.3 a step: two_actuator's costs
    rose from 4e-13 back to 4e39 at t = 500.)"""
    from packetloss_cvx.closedloop.mjls import jump_law_stage_costs, mode_start

    ch = GilbertElliott(p=[0.1, 0.2], r=[0.4, 0.5], h_good=[0.95, 0.9], h_bad=[0.1, 0.2])
    s = pl.load_example("two_actuator").with_channel(ch)
    res = coupled_riccati(s)
    steps = 400
    costs = jump_law_stage_costs(s, res.gains, steps, delivery, first_gain=res.gains[0])
    radius = mean_square_radius(s.A, s.B, ch, res.gains, delivery)
    assert radius < 0.7
    assert np.all(costs > 0)
    if delivery == "current":
        h = mode_chain(ch)[2]
        op = second_moment_operator(s.A, s.B, ch, res.gains)
        q = (mode_start(ch)[:, None, None] * np.outer(s.x0, s.x0)).ravel()
        W = [s.state_weights[0] + sum(s.input_weights[0][i] * h[a, i] * np.outer(res.gains[a, i], res.gains[a, i])
                                      for i in range(2)) for a in range(4)]
        reference = []
        for _ in range(steps):
            Q = q.reshape(4, 2, 2)
            reference.append(sum(float(np.sum(W[a] * Q[a])) for a in range(4)))
            q = op @ q
        np.testing.assert_allclose(costs, reference, rtol=1e-9)
    decay = (costs[-1] / costs[steps // 2]) ** (1 / (steps - 1 - steps // 2))
    assert decay == pytest.approx(radius, rel=0.05)


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_coupled_riccati_residual_check_refuses_3_and_keeps_0_3_times_moment_residual_rtol(monkeypatch, factor, kept):
    """The check after the iteration, one more step from the answer P, sees a residual ||step(P) - P|| / ||P||
    (Frobenius over the modes) of factor MOMENT_RESIDUAL_RTOL (planted on that step's largest entry; the iterations
    stop at RICCATI_RTOL, 1000 times below): NumericalError at 3, the answer (the hand values of
    test_hand_derived_two_mode_scalar) at 0.3."""
    import packetloss_cvx.closedloop.riccati as riccati_module
    from packetloss_cvx.tolerances import MOMENT_RESIDUAL_RTOL

    s = scalar(0.0, 0.5, state=["bad"])
    answer = coupled_riccati(s).cost_matrices.copy()
    real = riccati_module.dp_step

    def step(P, *args):
        K, new = real(P, *args)
        if np.array_equal(P, answer):                   # the check's step (no iteration starts from the answer)
            new = new.copy()
            new.flat[np.argmax(np.abs(new))] += factor * MOMENT_RESIDUAL_RTOL * np.linalg.norm(P)
        return K, new

    monkeypatch.setattr(riccati_module, "dp_step", step)
    if kept:
        res = coupled_riccati(s)
        np.testing.assert_allclose(res.cost_matrices.ravel(), [PHI, (1 + 0.5 * PHI) / 0.5], rtol=1e-12)
        assert res.residual == pytest.approx(factor * MOMENT_RESIDUAL_RTOL, rel=0.01)
    else:
        with pytest.raises(NumericalError, match="coupled Riccati equations: relative residual 3.0e-09"):
            coupled_riccati(s)


@pytest.mark.parametrize("mu", [[0.9, 0.7], [0.6, 0.0]])
def test_the_one_state_chain_is_the_bernoulli_dp(mu):
    """One solver (closedloop.riccati.mode_riccati): coupled_riccati behind the one-state chain of a Bernoulli channel
    is dp_riccati at that mu, to 1e-12, the gain row of an actuator that never delivers (mu_i = 0) included; and the
    DP's P solves the modified Riccati equation written out by hand."""
    from packetloss_cvx.closedloop.riccati import dp_riccati
    from packetloss_cvx.model.channel import MarkovChannel

    two = pl.load_example("two_actuator")
    chain, dp = coupled_riccati(two.with_channel(MarkovChannel.bernoulli(mu))), dp_riccati(two.with_mu(mu))
    np.testing.assert_allclose(chain.cost_matrices[0], dp.cost_to_go, rtol=1e-12)
    np.testing.assert_allclose(chain.gains[0], dp.gain, rtol=1e-12)
    assert chain.spectral_radius == pytest.approx(dp.spectral_radius, rel=1e-12)
    A, B, W, psi, m = two.A, two.B, two.state_weights[0], two.input_weights[0], np.array(mu)
    P = dp.cost_to_go
    G = B.T @ P @ B * m + np.diag(psi + (1 - m) * np.diag(B.T @ P @ B))
    K = np.linalg.solve(G, B.T @ P @ A)
    np.testing.assert_allclose(W + A.T @ P @ A - A.T @ P @ B @ np.diag(m) @ K, P, rtol=1e-12)


def test_no_stabilising_chain_law_is_said_with_its_proof():
    """a = 2 behind a Gilbert channel (p = 0.3, r = 0.2), the mode known: a good step can zero x, a bad one leaves
    x+ = 2x, so every law's radius is at least a^2 (1 - r) = 3.2 (the bad mode's block). The coupled value iteration
    diverges and its direction proves it exactly (certificates.chain_outside_proved, "current")."""
    with pytest.raises(NumericalError, match="no stabilising solution behind the chain") as err:
        coupled_riccati(scalar(0.3, 0.2, a=2.0))
    assert "exact arithmetic" in str(err.value)


def test_chain_dp_started_from_stabilising_mode_gains_is_the_same_solution():
    """mode_riccati behind a chain, its policy iteration started from proved-stabilising mode gains (the optimum
    perturbed, radius checked), reaches the same fixed point as the value iteration from Omega (the stabilising
    solution is unique), without the value steps; a gain that is not stabilising is ignored."""
    from packetloss_cvx.closedloop.riccati import mode_riccati

    ch = GilbertElliott(p=[0.1, 0.2], r=[0.4, 0.5], h_good=[0.95, 0.9], h_bad=[0.1, 0.2])
    s = pl.load_example("two_actuator").with_channel(ch)
    res = coupled_riccati(s)
    _, T, h = mode_chain(ch)
    start = res.gains * 1.2
    assert mean_square_radius(s.A, s.B, ch, start) < 1
    args = (s.A, s.B, s.state_weights[0], s.input_weights[0], h, T)
    K, P, iterations, _, _ = mode_riccati(*args, proves=lambda P: False, gain=start)
    np.testing.assert_allclose(P, res.cost_matrices, rtol=1e-12)
    np.testing.assert_allclose(K, res.gains, rtol=1e-11)
    assert iterations < res.iterations
    unstable = res.gains * 0.0 + 50.0
    assert mean_square_radius(s.A, s.B, ch, unstable) > 1
    _, P2, iterations2, _, _ = mode_riccati(*args, proves=lambda P: False, gain=unstable)
    np.testing.assert_allclose(P2, res.cost_matrices, rtol=1e-12)
    assert iterations2 == res.iterations


def test_a_weight_per_step_is_the_scalar_second_moment_recursion_by_hand():
    """``mode_stage_costs(..., per_step=True)`` (the paper's time-varying weights, allocation.attainable):
    x+ = 2 x + v u with u_t = -k_t x_t, v ~ Bernoulli(mu_t), no noise, x0 = 1, so
    E[x_{t+1}^2] = ((2 - mu_t k_t)^2 + mu_t (1 - mu_t) k_t^2) E[x_t^2], stage t = (omega_t + psi_t mu_t k_t^2)
    E[x_t^2], terminal omega_N E[x_N^2], by hand below; a chain is refused (the weights per step are taken at one
    mode)."""
    from packetloss_cvx.closedloop.modes import mode_stage_costs
    from packetloss_cvx.errors import InputError

    k, mu, omega, psi = [1.5, 0.5], [0.8, 0.3], [1.0, 3.0, 5.0], [2.0, 7.0]
    second, stages = 1.0, []
    for t in range(2):
        stages.append((omega[t] + psi[t] * mu[t] * k[t] ** 2) * second)
        second *= (2 - mu[t] * k[t]) ** 2 + mu[t] * (1 - mu[t]) * k[t] ** 2
    stage, terminal = mode_stage_costs(np.array([[2.0]]), np.array([[1.0]]), np.array(omega).reshape(3, 1, 1),
                                       np.array(psi).reshape(2, 1), np.zeros((1, 1)), np.ones(1),
                                       np.array(k).reshape(2, 1, 1), np.array(mu).reshape(2, 1), per_step=True)
    np.testing.assert_allclose(stage, stages, rtol=1e-15)
    assert terminal == pytest.approx(omega[2] * second, rel=1e-15)
    with pytest.raises(InputError, match="per_step"):
        mode_stage_costs(np.eye(1), np.eye(1), np.ones((3, 1, 1)), np.ones((2, 1)), np.zeros((1, 1)), np.ones(1),
                         np.ones((2, 2, 1, 1)), np.full((2, 1), 0.5), T=np.full((2, 2), 0.5), start=np.full(2, 0.5),
                         per_step=True)
