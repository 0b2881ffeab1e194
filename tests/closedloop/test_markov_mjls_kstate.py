"""The closed loop behind k-state Markov channels (markov/mjls.py, simulation/markov_*.py on a MarkovChannel):
the product mode chain and its refusal, the mean-square radius against an operator enumerated by hand and
against Bernoulli for i.i.d. chains, the coupled Riccati gains against dp_riccati at the mean rate and against
the Gilbert–Elliott twin, the exact stage costs against enumeration of every state path, and sampling."""

import itertools

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.closedloop.mjls import (
    MAX_MODES,
    coupled_riccati,
    jump_law_stage_costs,
    mean_square_radius,
    mode_chain,
    mode_start,
)
from packetloss_cvx.closedloop.riccati import dp_riccati
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.montecarlo.markov_channels import sample_markov_paths, sample_states
from packetloss_cvx.montecarlo.simulate import simulate
from packetloss_cvx.tolerances import CHAIN_FORM_RTOL
from tests.references import enumerated_radius

T3 = [[0.7, 0.2, 0.1], [0.1, 0.5, 0.4], [0.3, 0.3, 0.4]]
D3 = [1.0, 0.6, 0.0]
T2 = [[0.9, 0.1], [0.6, 0.4]]
D2 = [0.95, 0.1]


def plant(seed, n=2, m=2):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 1.05 / max(abs(np.linalg.eigvals(A)))
    return A, rng.normal(size=(n, m))


def system(channel, seed=0, horizon=4, noise=0.0):
    A, B = plant(seed, m=channel.m)
    return pl.System(A=A, B=B, horizon=horizon, state_weight=[1.0, 2.0], input_weight=[0.5] * channel.m,
                     x0=[1.0, -0.5], noise_cov=noise * np.eye(2), channel=channel)


def hand_operator(A, B, T, modes, h, K):
    """The coupled second-moment map by three explicit loops (previous mode a, next mode b, delivery pattern v):
    Q_b <- sum_a T_ab sum_v P(v | a) (A - B V K_a) Q_a (A - B V K_a)'."""
    M, n = len(modes), A.shape[0]
    op = np.zeros((M * n * n, M * n * n))
    for a in range(M):
        for v in itertools.product((0, 1), repeat=h.shape[1]):
            p = np.prod([h[a, i] if bit else 1 - h[a, i] for i, bit in enumerate(v)])
            F = A - B @ np.diag(v) @ K[a]
            for b in range(M):
                op[b * n * n:(b + 1) * n * n, a * n * n:(a + 1) * n * n] += T[a, b] * p * np.kron(F, F)
    return op


def test_product_chain_of_a_three_and_a_two_state_channel():
    ch = MarkovChannel(transition=[T3, T2], delivery=[D3, D2], state=[2, 1])
    modes, T, h = mode_chain(ch)
    assert modes.tolist() == [[0, 0], [0, 1], [1, 0], [1, 1], [2, 0], [2, 1]]
    np.testing.assert_allclose(T, np.kron(T3, T2), rtol=1e-15)
    np.testing.assert_array_equal(h, [[D3[a], D2[b]] for a, b in modes])
    np.testing.assert_array_equal(mode_start(ch), [0, 0, 0, 0, 0, 1])


def test_product_chain_beyond_the_mode_budget_is_refused_naming_it():
    five = np.full((5, 5), 0.2).tolist()
    ch = MarkovChannel(transition=[five] * 3, delivery=[[1.0, 0.8, 0.5, 0.2, 0.0]] * 3)
    assert 5 ** 3 > MAX_MODES
    with pytest.raises(pl.InputError, match=r"channel: the MJLS has one mode per joint state, prod k_i = 5 \* 5 \* 5 "
                                            r"= 125; expected at most 64"):
        mode_chain(ch)
    s = pl.System(A=np.eye(2), B=np.ones((2, 3)), horizon=2, state_weight=[1, 1], input_weight=[1, 1, 1],
                  x0=[1, 0], channel=ch)
    with pytest.raises(pl.InputError, match="prod k_i"):
        coupled_riccati(s)


@pytest.mark.parametrize("delivery", ["current", "next"])
def test_radius_matches_the_operator_enumerated_by_hand(delivery):
    ch = MarkovChannel(transition=[T3, T2], delivery=[D3, D2])
    A, B = plant(3)
    K = np.random.default_rng(4).normal(size=(6, 2, 2)) * 0.3
    modes, T, h = mode_chain(ch)
    op = hand_operator(A, B, T, modes, h, K)
    if delivery == "next":   # deliveries follow the mode b moved to: P(v | b) in place of P(v | a)
        op = np.zeros_like(op)
        n = 2
        for a, b in itertools.product(range(6), repeat=2):
            for v in itertools.product((0, 1), repeat=2):
                p = np.prod([h[b, i] if bit else 1 - h[b, i] for i, bit in enumerate(v)])
                F = A - B @ np.diag(v) @ K[a]
                op[b * n * n:(b + 1) * n * n, a * n * n:(a + 1) * n * n] += T[a, b] * p * np.kron(F, F)
    expected = float(max(abs(np.linalg.eigvals(op))))
    for method in ("dense", "krylov"):
        assert mean_square_radius(A, B, ch, K, delivery, method) == pytest.approx(expected, rel=1e-9)


def test_iid_chains_have_the_bernoulli_radius_at_their_mean_rates():
    """Identical rows: each step's state is drawn afresh, so each channel delivers Bernoulli(pi . d)."""
    rows3, rows2 = [[0.5, 0.3, 0.2]] * 3, [[0.25, 0.75]] * 2
    ch = MarkovChannel(transition=[rows3, rows2], delivery=[D3, D2])
    A, B = plant(5)
    K = np.random.default_rng(6).normal(size=(2, 2)) * 0.4
    mu = [0.5 + 0.3 * 0.6, 0.25 * 0.95 + 0.75 * 0.1]
    np.testing.assert_allclose(ch.mean_rate, mu, rtol=1e-15)
    assert mean_square_radius(A, B, ch, K) == pytest.approx(enumerated_radius(A, B, K, mu), rel=1e-10)


def test_iid_chain_coupled_riccati_is_dp_riccati_at_the_mean_rate():
    """One channel, identical rows: every E_a is one P, and sum_a pi_a P_a solves the Bernoulli TCP-like (modified)
    Riccati equation at mu = pi . d; each mode that can deliver uses the Bernoulli gain, the others 0."""
    ch = MarkovChannel(transition=[[[0.5, 0.3, 0.2]] * 3], delivery=[D3])
    A, B = plant(7, m=1)
    s = pl.System(A=A, B=B, horizon=3, state_weight=[1.0, 2.0], input_weight=[0.5], x0=[1.0, 0.0], channel=ch)
    res = coupled_riccati(s)
    dp = dp_riccati(s.with_mu(ch.mean_rate))
    pi = np.array([0.5, 0.3, 0.2])
    np.testing.assert_allclose(np.einsum("a,aij->ij", pi, res.cost_matrices), dp.cost_to_go, rtol=1e-8)
    for a in (0, 1):
        np.testing.assert_allclose(res.gains[a], dp.gain, rtol=1e-8)
    np.testing.assert_array_equal(res.gains[2], np.zeros((1, 2)))


def test_gilbert_elliott_and_its_typed_chain_give_the_same_loop():
    """GilbertElliott(p, r, h_bad, belief) and the two-state chains typed as decimals (one chain to rounding: the
    belief 0.2 against 1 - 0.8 = 0.19999999999999996): the coupled Riccati law, the mode start and the jump-law costs
    agree within CHAIN_FORM_RTOL of their largest entries."""
    ge = GilbertElliott(p=[0.1, 0.3], r=[0.4, 0.5], h_bad=[0.1, 0.0], belief=[0.3, 0.8])
    typed = MarkovChannel(transition=[[[0.9, 0.1], [0.4, 0.6]], [[0.7, 0.3], [0.5, 0.5]]],
                          delivery=[[1.0, 0.1], [1.0, 0.0]], belief=[[0.3, 0.7], [0.8, 0.2]])
    a, b = coupled_riccati(system(ge, 8)), coupled_riccati(system(typed, 8))
    for x, y in ((a.gains, b.gains), (a.cost_matrices, b.cost_matrices), (a.transition, b.transition),
                 (mode_start(ge), mode_start(typed))):
        np.testing.assert_allclose(x, y, rtol=0, atol=CHAIN_FORM_RTOL * np.abs(y).max())
    assert a.spectral_radius == pytest.approx(b.spectral_radius, rel=CHAIN_FORM_RTOL)
    gains = np.random.default_rng(9).normal(size=(5, 4, 2, 2)) * 0.3
    for delivery in ("current", "next"):
        costs = [jump_law_stage_costs(system(c, 8), gains, 5, delivery, first_gain=gains[0, 0]) for c in (ge, typed)]
        np.testing.assert_allclose(costs[0], costs[1], rtol=0, atol=CHAIN_FORM_RTOL * np.abs(costs[1]).max())


def test_jump_law_stage_costs_match_every_state_path():
    """E[x_t' Omega x_t + (V u)' Psi (V u)] of u = -K_{t, mode} x over 3 steps, against the sum over every joint
    state path and every delivery pattern (noise-free: each outcome's cost is deterministic)."""
    ch = MarkovChannel(transition=[T3, T2], delivery=[D3, D2], belief=[[0.2, 0.5, 0.3], [0.6, 0.4]])
    s = system(ch, 10, horizon=3)
    modes, T, h = mode_chain(ch)
    steps = 3
    K = np.random.default_rng(11).normal(size=(steps, 6, 2, 2)) * 0.4
    Omega, psi = s.state_weights[0], s.input_weights[0]
    expected = np.zeros(steps)
    start = mode_start(ch)
    for path in itertools.product(range(6), repeat=steps):
        prob = start[path[0]] * np.prod([T[path[t], path[t + 1]] for t in range(steps - 1)])
        if prob == 0:
            continue
        for pattern in itertools.product(itertools.product((0, 1), repeat=2), repeat=steps):
            p = prob * np.prod([h[path[t], i] if pattern[t][i] else 1 - h[path[t], i]
                                for t in range(steps) for i in range(2)])
            x = s.x0.copy()
            for t in range(steps):
                applied = np.array(pattern[t]) * (-K[t, path[t]] @ x)
                expected[t] += p * (x @ Omega @ x + applied @ (psi * applied))
                x = s.A @ x + s.B @ applied
    np.testing.assert_allclose(jump_law_stage_costs(s, K, steps, "current"), expected, rtol=1e-11)


def test_sampled_paths_follow_the_chain():
    ch = MarkovChannel(transition=[T3, T2], delivery=[D3, D2], state=[2, 0])
    states, v = sample_markov_paths(ch, 6, 40_000, np.random.default_rng(12))
    assert states.dtype.kind == "i"
    assert states.max(axis=(0, 1)).tolist() == [2, 1]
    mu = ch.delivery_schedule(6)
    se = np.sqrt(mu * (1 - mu) / 40_000) + 1e-12
    assert np.all(np.abs(v.mean(axis=0) - mu) <= 4 * se)
    moved = states[:, :-1, 0] == 1                                    # from state 1 of channel 0
    freq = np.bincount(states[:, 1:, 0][moved], minlength=3) / moved.sum()
    assert np.all(np.abs(freq - np.array(T3[1])) <= 4 * np.sqrt(np.array(T3[1]) * 0.9 / moved.sum()) + 1e-12)
    assert np.all(sample_states(ch, 1, 5, np.random.default_rng(0))[:, 0] == [2, 0])


def test_gilbert_elliott_paths_follow_the_documented_draws():
    """sample_markov_paths' rule for a Gilbert–Elliott channel, written out by hand on the same uniform numbers:
    good at the start iff u_0 < r / (p + r), then good iff u_t < 1 - p after a good step and u_t < r after a bad one;
    where a state does not reveal the outcome (h_bad = 0.5), a second uniform array decides v = u' < h. The draws are
    a function of the stream (the one sampler run on it), so they agree to the bit."""
    p, r, h_bad = np.array([0.25, 0.5]), np.array([0.75, 0.25]), np.array([0.5, 0.0])
    ge = GilbertElliott(p=p, r=r, h_bad=h_bad)
    states, v = sample_markov_paths(ge, 8, 50, np.random.default_rng(13))
    rng = np.random.default_rng(13)
    u = rng.random((50, 8, 2))
    good = np.empty((50, 8, 2), dtype=bool)
    good[:, 0] = u[:, 0] < r / (p + r)
    for t in range(1, 8):
        good[:, t] = u[:, t] < np.where(good[:, t - 1], 1.0 - p, r)
    h = np.where(good, 1.0, h_bad)
    second = rng.random((50, 8, 2))
    np.testing.assert_array_equal(states == 0, good)
    np.testing.assert_array_equal(v, second < h)


@pytest.mark.parametrize("seed", [14, 15])
def test_simulate_behind_an_unseen_three_state_chain_agrees_with_the_exact_values(seed):
    rng = np.random.default_rng(seed)
    T = rng.dirichlet(np.ones(3) * 0.7, size=3)
    ch = MarkovChannel(transition=[T.tolist(), T2], delivery=[rng.uniform(0, 1, 3).tolist(), [1.0, 0.0]],
                       belief=[rng.dirichlet(np.ones(3)).tolist(), [0.5, 0.5]])
    s = system(ch, seed, horizon=5, noise=0.1)
    sim = simulate(s, samples=20_000, steps=30, seed=seed, closed_loop=True, laws=["udp", "dp"], progress=False)
    assert sim.channel == "markov"
    for check in sim.open_loop.values():
        assert abs(check.mean - check.exact) <= 4 * check.stderr
    for law in ("udp", "dp"):
        run = sim.closed_loop[law]
        assert abs(run.mean_stage_cost - run.exact_stage_cost) <= 4 * run.stderr, law
        assert np.isfinite(run.spectral_radius)
    tcp = simulate(s, samples=20, steps=3, seed=seed, closed_loop=True, laws=["tcp"], progress=False)
    assert "continuum" in tcp.closed_loop["tcp"].exact_reason               # a 3-state outcome hides the state


def test_closed_loop_costs_behind_an_iid_chain_are_bernoulli_at_the_mean_rate():
    """markov_closed_loop_costs samples k-state chains: with identical rows each step delivers Bernoulli(pi . d), so the
    plug-in UDP-like law's realised cost has the Bernoulli loop's exact mean (simulation.moments)."""
    from packetloss_cvx.closedloop.moments import finite_horizon_costs
    from packetloss_cvx.lq.costs import closed_form
    from packetloss_cvx.montecarlo.markov_loop import markov_closed_loop_costs

    ch = MarkovChannel(transition=[[[0.5, 0.3, 0.2]] * 3], delivery=[D3])
    A, B = plant(16, m=1)
    s = pl.System(A=A * 0.9, B=B, horizon=3, state_weight=[1.0, 2.0], input_weight=[0.5], x0=[1.0, -1.0],
                  noise_cov=0.05 * np.eye(2), channel=ch)
    costs = markov_closed_loop_costs(s, ["plug-in-udp"], steps=6, samples=20_000, rng=np.random.default_rng(17))[0]
    twin = s.with_mu(ch.mean_rate)
    stage, terminal = finite_horizon_costs(twin, closed_form(twin, "udp").gain, 6)
    assert abs(costs.mean() - stage.sum() - terminal) <= 4 * costs.std(ddof=1) / np.sqrt(costs.size)
