"""The exact UDP-like cost under finite-state Markov losses as an LQ problem on the augmented state
(markov/augmented.py, markov.chain.chain_matrices): against the dense second-moment route (N <= 200), the
cvxpy + Clarabel QP twin, enumeration of every loss pattern (Gilbert–Elliott and a hand-written 3-state
chain), and the lumped 3-state twin of a Gilbert–Elliott channel."""

import importlib

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.errors import BudgetError, InputError
from packetloss_cvx.lq.augmented import augmented_solve, chain_cost, chain_lift
from packetloss_cvx.lq.markov_cost import exact_closed_form, exact_cost
from packetloss_cvx.model.chain import attach_channel, chain_matrices, channel_covariance
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.markov import exact_qp
from tests.model.test_markov_chain import random_channel
from tests.references import enumerated_chain_cost


class ThreeStateChains:
    """A stand-in for any channel class honouring the chain_matrices() contract: per channel (T, d, pi0)."""

    def __init__(self, chains):
        self.chains = tuple((np.asarray(T, float), np.asarray(d, float), np.asarray(p, float)) for T, d, p in chains)

    def chain_matrices(self):
        return self.chains


def random_chain(rng, k):
    T = rng.uniform(0.05, 1, (k, k))
    T /= T.sum(axis=1, keepdims=True)
    pi0 = rng.uniform(0, 1, k)
    return T, rng.uniform(0, 1, k), pi0 / pi0.sum()


def schedule(chains, horizon):
    """mu_{t,i} = pi_{i,t} d_i, pi propagated by T: the predicted delivery rates of the chains."""
    out = np.empty((horizon, len(chains)))
    for i, (T, d, pi) in enumerate(chains):
        row = pi.copy()
        for t in range(horizon):
            out[t, i] = row @ d
            row = row @ T
    return out


def bursty(seed, **kwargs):
    rng = np.random.default_rng(seed)
    s = random_system(rng, spectral_radius=rng.uniform(0.5, 1.1), **kwargs)
    return attach_channel(s, random_channel(rng, s.m, given=seed % 2 == 0))


def test_chain_matrices_of_a_gilbert_elliott_channel():
    ch = GilbertElliott(p=[0.1, 0.3], r=[0.4, 0.2], h_good=[0.9, 1.0], h_bad=[0.2, 0.0], state=["bad", "good"])
    (T0, d0, p0), (T1, d1, p1) = chain_matrices(ch)
    np.testing.assert_array_equal(T0, [[0.9, 0.1], [0.4, 0.6]])
    np.testing.assert_array_equal(T1, [[0.7, 0.3], [0.2, 0.8]])
    np.testing.assert_array_equal(np.stack([d0, d1]), [[0.9, 0.2], [1.0, 0.0]])
    np.testing.assert_array_equal(np.stack([p0, p1]), [[0.0, 1.0], [1.0, 0.0]])
    stationary = chain_matrices(GilbertElliott(p=[0.1], r=[0.4]))[0][2]      # r / (p + r) = 0.8
    np.testing.assert_allclose(stationary, [0.8, 0.2], rtol=1e-15)


def test_chain_matrices_asks_any_other_channel_for_its_own():
    chains = ((np.full((3, 3), 1 / 3), np.array([1.0, 0.5, 0.0]), np.array([1.0, 0.0, 0.0])),)
    assert chain_matrices(ThreeStateChains(chains))[0][0].shape == (3, 3)
    with pytest.raises(InputError, match="chain_matrices"):
        chain_matrices(object())


@pytest.mark.parametrize("seed", range(10))
def test_forward_cost_matches_the_dense_second_moment_route(seed):
    s = bursty(seed, time_varying=True, noise=seed % 3 == 0)
    U = np.random.default_rng(100 + seed).normal(size=(s.horizon, s.m))
    dense = exact_cost(s, U, method="dense")
    assert exact_cost(s, U) == pytest.approx(dense, rel=1e-12)


@pytest.mark.parametrize("seed", range(10))
def test_recursion_matches_the_dense_closed_form(seed):
    s = bursty(seed, time_varying=seed % 2 == 1, noise=seed % 3 == 0)
    rec, dense = exact_closed_form(s, method="recursion"), exact_closed_form(s, method="dense")
    assert rec.method == "markov-recursion"
    assert dense.method == "markov-dense"
    assert rec.cost == pytest.approx(dense.cost, rel=1e-10)
    scale = max(1.0, float(np.abs(dense.inputs).max()))
    np.testing.assert_allclose(rec.inputs, dense.inputs, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(rec.gain, dense.gain, rtol=0, atol=1e-10 * max(1.0, float(np.abs(dense.gain).max())))


@pytest.mark.parametrize("case", ["gilbert-elliott", "slow gilbert-elliott", "three-state"])
def test_a_stationary_chain_closes_the_value_and_rolls_its_run_by_powers(monkeypatch, case):
    """Chains started in their stationary distributions on a stable plant (noise): below the step where the
    Lyapunov sums closed, every step is one map, and the augmented value closes its stationary tail (the run of one
    gain rolled out by powers of its closed loop, the steps after it one by one). Against the full pass, every step
    one by one (PATH_AGREEMENT_RTOL), and the dense second-moment route (another formulation: cost, plan and gain
    to 1e-10; rho(A) = 0.6, N = 300). "slow": rho(A) = 0.97 and a weak B, where the plan after the run is still
    1e-3 of its largest input (a wrong step after the run shows)."""
    import packetloss_cvx.lq.augmented as augmented
    from packetloss_cvx.model.files import system_from_dict
    from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

    slow = case == "slow gilbert-elliott"
    rng = np.random.default_rng(0 if slow else 5)
    s = random_system(rng, n=3, m=2, horizon=700 if slow else 300, spectral_radius=0.97 if slow else 0.6,
                      full_weights=True, time_varying=False, non_stationary=False, noise=True, edge_mu=False)
    chain_list = None
    if case != "three-state":
        channel = GilbertElliott(p=[0.1, 0.3], r=[0.4, 0.5], h_good=[0.95, 0.9], h_bad=[0.2, 0.0])
        s = pl.System(A=s.A, B=0.05 * s.B if slow else s.B, horizon=s.horizon, state_weight=s.state_weights[0],
                      input_weight=s.input_weights[0], x0=s.x0, noise_cov=s.noise_cov, channel=channel)
    else:
        # dyadic entries and a dyadic stationary distribution: pi T = pi holds to the bit whatever the order of the
        # sums (an eigenvector from np.linalg.eig is stationary only to rounding, which under OpenBLAS's SkylakeX
        # kernel moved the belief in its last bit each step, so no two steps' maps were equal and nothing closed)
        T = np.array([[0.5, 0.5, 0.0], [0.25, 0.5, 0.25], [0.0, 0.5, 0.5]])
        d = np.array([1.0, 0.5, 0.0])
        pi = np.array([0.25, 0.5, 0.25])
        assert np.array_equal(pi @ T, pi)
        chain_list = ((T, d, pi), (T, d[::-1].copy(), pi))
        s = s.with_mu(np.repeat([[pi @ d, pi @ d[::-1]]], s.horizon, axis=0))
    runs = []
    powers = augmented.states_by_powers

    def spy(*args):
        runs.append(args[0].shape[1])
        return powers(*args)

    monkeypatch.setattr(augmented, "states_by_powers", spy)
    U, gain, cost = augmented_solve(s, chain_list)
    assert runs                                           # the tail closed ...
    assert runs[0] > 100                                  # ... more than 100 steps before step 1
    if slow:
        assert np.abs(U[runs[0] + 1:]).max() > 1e-4 * np.abs(U).max()
    with monkeypatch.context() as patch:
        patch.setattr(augmented, "STATIONARY_RUN", 10**9)
        U_full, gain_full, cost_full = augmented_solve(system_from_dict(s.to_dict()), chain_list)
    assert len(runs) == 1
    for a, b in ((U, U_full), (gain, gain_full), (cost, cost_full)):
        assert np.abs(np.asarray(a) - b).max() <= PATH_AGREEMENT_RTOL * np.abs(b).max()
    if case == "gilbert-elliott":
        dense = exact_closed_form(s, method="dense")
        assert cost == pytest.approx(dense.cost, rel=1e-10)
        np.testing.assert_allclose(U, dense.inputs, rtol=0, atol=1e-10 * float(np.abs(dense.inputs).max()))
        np.testing.assert_allclose(gain, dense.gain, rtol=0, atol=1e-10 * float(np.abs(dense.gain).max()))


@pytest.mark.parametrize("horizon", [150, 200])
def test_recursion_matches_the_dense_route_on_the_unstable_pendulum_at_long_horizons(horizon):
    s = pl.load_example("pendulum_bursty")
    s = pl.System(A=s.A, B=s.B, horizon=horizon, state_weight=np.diag(s.state_weights[0]),
                  input_weight=s.input_weights[0], x0=s.x0, channel=s.channel)
    assert max(abs(np.linalg.eigvals(s.A))) > 1
    rec, dense = exact_closed_form(s, method="recursion"), exact_closed_form(s, method="dense")
    assert rec.cost == pytest.approx(dense.cost, rel=1e-10)
    np.testing.assert_allclose(rec.gain, dense.gain, rtol=1e-9)


@pytest.mark.parametrize("seed", range(3))
def test_recursion_matches_the_qp_twin(seed):
    s = bursty(seed)
    rec = exact_closed_form(s, method="recursion")
    qp = exact_qp(s, reference=rec)                   # binds: CrossCheckError beyond its tolerances
    assert qp.cost == pytest.approx(rec.cost, rel=1e-10)


@pytest.mark.parametrize("method", ["recursion", "dense"])
@pytest.mark.parametrize("seed", range(4))
def test_gilbert_elliott_against_every_loss_pattern(seed, method):
    rng = np.random.default_rng(seed)
    s = random_system(rng, n=2, m=2, horizon=4, time_varying=True, noise=False)
    s = attach_channel(s, random_channel(rng, 2, given=seed % 2 == 0))
    sol = exact_closed_form(s, method=method)
    ch = s.channel
    chains = [([[1 - p, p], [r, 1 - r]], [hg, hb], [b, 1 - b]) for p, r, hg, hb, b in
              zip(ch.p, ch.r, ch.h_good, ch.h_bad, ch.initial_belief[:, 0], strict=True)]
    enum = enumerated_chain_cost(s.A, s.B, s.state_weights, s.input_weights, s.initial_weight, s.x0, chains,
                                 sol.inputs)
    assert sol.cost == pytest.approx(enum, rel=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_a_three_state_chain_against_every_loss_pattern(seed):
    """A k = 3 chain through chain_matrices' contract: the forward cost of a random plan and the recursion's
    minimum equal the enumerated expectation, and the enumerated cost is stationary at the minimiser."""
    rng = np.random.default_rng(seed)
    N, m = 4, 2
    chains = chain_matrices(ThreeStateChains([random_chain(rng, 3) for _ in range(m)]))
    s = random_system(rng, n=2, m=m, horizon=N, time_varying=True, noise=False).with_mu(schedule(chains, N))

    def enum(U):
        return enumerated_chain_cost(s.A, s.B, s.state_weights, s.input_weights, s.initial_weight, s.x0, chains, U)

    U = rng.normal(size=(N, m))
    assert float(chain_cost(s, U[None], chain_lift(s, chains))[0]) == pytest.approx(enum(U), rel=1e-12)
    plan, gain, cost = augmented_solve(s, chains)
    assert cost == pytest.approx(enum(plan), rel=1e-12)
    u = plan.ravel()
    grad = np.empty(u.size)
    for j in range(u.size):                            # central differences of a quadratic: exact but rounding
        e = np.zeros(u.size)
        e[j] = 1e-3
        grad[j] = (enum((u + e).reshape(N, m)) - enum((u - e).reshape(N, m))) / 2e-3
    assert np.abs(grad).max() <= 1e-8 * max(1.0, cost)
    np.testing.assert_allclose(gain @ s.x0, -plan[0], atol=1e-12 * max(1.0, np.abs(plan[0]).max()))


@pytest.mark.parametrize("seed", range(4))
def test_a_lumped_three_state_twin_gives_the_gilbert_elliott_numbers(seed):
    """Splitting the good state into two identical halves changes nothing the controller sees: the k = 3
    recursion (two eigenvalues besides 1) must reproduce the dense Gilbert–Elliott route."""
    s = bursty(seed)
    twins = []
    for p, r, hg, hb, b in zip(s.channel.p, s.channel.r, s.channel.h_good, s.channel.h_bad,
                               s.channel.initial_belief[:, 0], strict=True):
        T = [[(1 - p) / 2, (1 - p) / 2, p], [(1 - p) / 2, (1 - p) / 2, p], [r / 2, r / 2, 1 - r]]
        twins.append((np.array(T), np.array([hg, hg, hb]), np.array([b / 2, b / 2, 1 - b])))
    plan, gain, cost = augmented_solve(s, chain_matrices(ThreeStateChains(twins)))
    dense = exact_closed_form(s, method="dense")
    assert cost == pytest.approx(dense.cost, rel=1e-10)
    np.testing.assert_allclose(plan, dense.inputs, rtol=0, atol=1e-10 * max(1.0, np.abs(dense.inputs).max()))


def test_a_channel_that_cannot_deliver_gets_no_input():
    """A Gilbert channel known bad now (h_bad = 0: mu_0 = 0) and one that never delivers (h = 0, 0)."""
    s = pl.System(A=[[1.1, 0.2], [0.0, 0.9]], B=[[1.0, 0.0], [0.3, 1.0]], horizon=6, state_weight=[1.0, 2.0],
                  input_weight=[1.0, 0.5], x0=[1.0, -1.0],
                  channel=GilbertElliott(p=[0.2, 0.3], r=[0.3, 0.4], h_good=[1.0, 0.0], state=["bad", "good"]))
    assert s.mu_schedule[0, 0] == 0.0
    assert np.all(s.mu_schedule[:, 1] == 0.0)
    rec, dense = exact_closed_form(s, method="recursion"), exact_closed_form(s, method="dense")
    assert rec.inputs[0, 0] == 0.0
    assert np.all(rec.inputs[:, 1] == 0.0)
    assert rec.cost == pytest.approx(dense.cost, rel=1e-10)
    np.testing.assert_allclose(rec.inputs, dense.inputs, atol=1e-10)


def test_chains_that_disagree_with_the_schedule_are_refused():
    chains = (random_chain(np.random.default_rng(0), 3),)
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    with pytest.raises(InputError, match="mu_schedule"):
        augmented_solve(s, chains)


@pytest.mark.parametrize(("T", "d", "pi0", "match"), [
    ([[0.5, 0.6], [0.5, 0.5]], [1.0, 0.0], [0.5, 0.5], "row-stochastic"),
    ([[1.2, -0.2], [0.5, 0.5]], [1.0, 0.0], [0.5, 0.5], "row-stochastic"),
    ([[0.5, 0.5], [0.5, 0.5]], [1.5, 0.0], [0.5, 0.5], "delivery"),
    ([[0.5, 0.5], [0.5, 0.5]], [1.0, 0.0], [0.7, 0.7], "initial distribution"),
    ([[0.5, 0.5], [0.5, 0.5]], [1.0, 0.0, 0.0], [0.5, 0.5], "expected"),
])
def test_chains_that_break_the_contract_are_refused(T, d, pi0, match):
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    chains = chain_matrices(ThreeStateChains([(T, d, pi0)]))
    with pytest.raises(InputError, match=match):
        augmented_solve(s, chains)


def test_method_is_checked():
    s = pl.load_example("pendulum_bursty")
    with pytest.raises(InputError, match="method"):
        exact_closed_form(s, method="qr")
    with pytest.raises(InputError, match="method"):
        exact_cost(s, np.zeros((s.horizon, 1)), method="qr")


def test_the_covariance_of_a_three_state_chain_against_every_loss_pattern():
    """channel_covariance of any chain_matrices() channel (what the dense route and the QP twin read) against
    E[v_t v_s] - mu_t mu_s summed over all 2^N loss patterns; and the lumped twin of a Gilbert-Elliott channel
    through it equals the Gilbert-Elliott formula."""
    from tests.references import loss_pattern_probabilities

    rng = np.random.default_rng(7)
    N = 6
    chains = [random_chain(rng, 3) for _ in range(2)]
    C = channel_covariance(ThreeStateChains(chains), N)
    for i, (T, d, pi0) in enumerate(chains):
        probs = loss_pattern_probabilities(T, d, pi0, N)
        V = np.array(list(probs)), np.array(list(probs.values()))
        mean = V[1] @ V[0]
        second = (V[0] * V[1][:, None]).T @ V[0]
        np.testing.assert_allclose(C[i], second - np.outer(mean, mean), rtol=0, atol=1e-14)
    ge = GilbertElliott(p=[0.15], r=[0.35], h_good=[0.9], h_bad=[0.2], belief=[0.4])
    p, r, hg, hb, b = 0.15, 0.35, 0.9, 0.2, 0.4
    lumped = ThreeStateChains([([[(1 - p) / 2, (1 - p) / 2, p], [(1 - p) / 2, (1 - p) / 2, p], [r / 2, r / 2, 1 - r]],
                                [hg, hg, hb], [b / 2, b / 2, 1 - b])])
    np.testing.assert_allclose(channel_covariance(lumped, 9), channel_covariance(ge, 9), rtol=0, atol=1e-15)


# --- method="auto" and the recursion's time budget (docs/mathematics.md, "The exact cost at any horizon") -------------

def pendulum_at(horizon, radius=None):
    """pendulum_bursty at another horizon (and A scaled to spectral radius ``radius``)."""
    s = pl.load_example("pendulum_bursty")
    A = s.A if radius is None else s.A * radius / max(abs(np.linalg.eigvals(s.A)))
    return pl.System(A=A, B=s.B, horizon=horizon, state_weight=np.diag(s.state_weights[0]),
                     input_weight=s.input_weights[0], x0=s.x0, channel=s.channel)


def test_auto_takes_the_dense_route_where_it_is_faster_and_safe(monkeypatch):
    short = pendulum_at(80)
    auto, rec = exact_closed_form(short), exact_closed_form(short, method="recursion")
    assert auto.method == "markov-dense"                       # N m = 80: about 2 ms against 5 ms
    assert auto.cost == pytest.approx(rec.cost, rel=1e-10)
    np.testing.assert_allclose(auto.gain, rec.gain, rtol=1e-8)
    assert exact_closed_form(pendulum_at(160)).method == "markov-recursion"        # condition estimate beyond 1e8
    assert exact_closed_form(pendulum_at(600, radius=0.99)).method == "markov-recursion"   # the recursion is faster
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "1e5")                  # the dense route would not fit
    assert exact_closed_form(short).method == "markov-recursion"


def test_auto_falls_back_to_the_recursion_when_the_dense_route_loses_its_digits(monkeypatch):
    exact_module = importlib.import_module("packetloss_cvx.lq.markov_cost")   # the name is also a function

    def lost(system):
        raise pl.NumericalError("planted: the dense prediction lost its digits")

    monkeypatch.setattr(exact_module, "dense_prediction", lost)
    sol = exact_closed_form(pendulum_at(80))
    assert sol.method == "markov-recursion"
    with pytest.raises(pl.NumericalError, match="planted"):
        exact_closed_form(pendulum_at(80), method="dense")


def test_the_recursion_is_refused_beyond_its_time_budget_before_any_work(monkeypatch):
    """pendulum_bursty at N = 80: n = 4 behind one Gilbert channel, D = 4 (1 + 1) = 8, priced by hand at
    N (D^3 + 6e5) = 80 (512 + 600000) = 48,040,960 units: runs at that budget, refused 1 % below it."""
    exact_module = importlib.import_module("packetloss_cvx.lq.markov_cost")   # the name is also a function

    def never(*args, **kwargs):
        raise AssertionError("the recursion ran")

    s = pendulum_at(80)
    work = 80 * (8 ** 3 + 6e5)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MARKOV_RECURSION_WORK", str(work))
    assert exact_closed_form(s, method="recursion").method == "markov-recursion"     # at the budget: runs
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MARKOV_RECURSION_WORK", str(work * 0.99))
    monkeypatch.setattr(exact_module, "augmented_solve", never)
    with pytest.raises(BudgetError, match=r"^channel: the exact Markov recursion over N = 80 steps on an augmented "
                                             r"state of size D = 8 \(at most about .*, every step priced in full: a "
                                             r"stable chain's settled tail ends sooner; method='dense' needs about .* "
                                             r"within the memory budget.*PACKETLOSS_CVX_BUDGET_MARKOV_RECURSION_WORK="
                                             r"4\.81e\+07$") as err:
        exact_closed_form(s, method="recursion")
    assert isinstance(err.value, pl.InputError)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "1e5")
    with pytest.raises(BudgetError, match="over the memory budget: use a chain with fewer states or a shorter"):
        exact_closed_form(s)                                   # auto: the dense route does not fit either


def test_the_recursion_budget_prices_the_augmented_step_cubed(monkeypatch):
    """A 40-state chain behind n = 2: D = 2 (1 + 39) = 80, where a step's D^3 = 512,000 is as large as its fixed
    6e5, priced by hand at N (D^3 + 6e5) = 10 (512000 + 600000) = 11,120,000 units: runs at that budget, refused 1 %
    below it (a formula that left out or shrank the D^3 term would run there)."""
    rng = np.random.default_rng(3)
    T = rng.uniform(size=(40, 40)) + 20 * np.eye(40)
    ch = MarkovChannel(transition=[T / T.sum(axis=1, keepdims=True)], delivery=[rng.uniform(size=40)])
    s = pl.System(A=[[0.9, 0.2], [0.0, 0.8]], B=[[1.0], [0.5]], horizon=10, state_weight=[1.0, 1.0],
                  input_weight=[1.0], x0=[1.0, 1.0], channel=ch)
    work = 10 * (80 ** 3 + 6e5)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MARKOV_RECURSION_WORK", str(work))
    assert exact_closed_form(s, method="recursion").method == "markov-recursion"
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MARKOV_RECURSION_WORK", str(work * 0.99))
    with pytest.raises(BudgetError, match=r"D = 80 .*PACKETLOSS_CVX_BUDGET_MARKOV_RECURSION_WORK=1\.12e\+07$"):
        exact_closed_form(s, method="recursion")


def test_the_recursion_budget_is_an_upper_bound_on_the_steps_the_pass_takes(monkeypatch):
    """The budget prices all N steps of the backward pass: no pass takes more (an unstable plant, whose tail never
    settles, takes exactly N), and a stable chain's pass, which closes its settled tail, takes fewer, with the same
    minimum as the pass that takes every step (a horizon below 2 STATIONARY_RUN checks for no tail)."""
    from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL
    augmented = importlib.import_module("packetloss_cvx.lq.augmented")
    original = augmented._augmented_step
    taken = []

    def counted(*args, **kwargs):
        taken.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(augmented, "_augmented_step", counted)
    for horizon, radius, expected in ((400, None, 400), (2000, 0.9, None)):
        taken.clear()
        s = pendulum_at(horizon, radius)
        cost = exact_closed_form(s, method="recursion").cost
        if expected is not None:                                 # rho(A) = 1.06: every step
            assert len(taken) == expected
            continue
        assert len(taken) < horizon / 4                           # the settled tail closed early
        monkeypatch.setattr(augmented, "STATIONARY_RUN", 10 ** 9)
        taken.clear()
        every = exact_closed_form(s, method="recursion").cost
        assert len(taken) == horizon
        assert cost == pytest.approx(every, rel=PATH_AGREEMENT_RTOL)


def test_a_chain_too_large_for_the_budget_exits_2_with_one_line(tmp_path, capsys, monkeypatch):
    """A 100-state chain behind a scalar plant at N = 2000: D = 100, the recursion (about 0.4 s) is faster than the
    dense route (about 2.6 s), so auto takes it; a budget of 1e9 units refuses it before any work, in one line."""
    from packetloss_cvx.cli import main
    from packetloss_cvx.model.files import dumps_system

    rng = np.random.default_rng(0)
    T = rng.uniform(size=(100, 100)) + 50 * np.eye(100)
    ch = MarkovChannel(transition=[T / T.sum(axis=1, keepdims=True)], delivery=[rng.uniform(size=100)])
    s = pl.System(A=[[0.9]], B=[[1.0]], horizon=2000, state_weight=[1.0], input_weight=[1.0], x0=[1.0], channel=ch)
    path = tmp_path / "big.toml"
    path.write_text(dumps_system(s))
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MARKOV_RECURSION_WORK", "1e9")
    code = main(["solve", str(path), "--no-qp"])
    out, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1
    assert "D = 100" in err
    assert "PACKETLOSS_CVX_BUDGET_MARKOV_RECURSION_WORK" in err


# ---------------------------------------------------------------- the self-check's band, pinned on both sides

def _chain_cost_off(monkeypatch, relative: float = 0.0, absolute: float = 0.0) -> None:
    """augmented_solve's referee (chain_cost, the exact forward cost of the plan) moved by a chosen amount."""
    augmented_module = importlib.import_module("packetloss_cvx.lq.augmented")
    real = augmented_module.chain_cost
    monkeypatch.setattr(augmented_module, "chain_cost", lambda *a, **k: real(*a, **k) * (1 + relative) + absolute)


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_recursion_self_check_refuses_3_and_keeps_0_3_times_self_check_rtol(monkeypatch, factor, kept):
    """The augmented recursion's cost off its plan's chain_cost by 3 SELF_CHECK_RTOL (relative) raises, by 0.3 is
    returned (pendulum_bursty at N = 40: its own disagreement is at rounding level)."""
    from packetloss_cvx.tolerances import SELF_CHECK_RTOL

    s = pendulum_at(40)
    exact = augmented_solve(s)[2]
    _chain_cost_off(monkeypatch, relative=factor * SELF_CHECK_RTOL)
    if kept:
        assert augmented_solve(s)[2] == exact
    else:
        with pytest.raises(pl.NumericalError, match="the forward cost of its own plan"):
            augmented_solve(s)


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_recursion_self_check_absolute_term_is_self_check_atol_times_p0_and_x(monkeypatch, factor, kept):
    """The absolute term SELF_CHECK_ATOL ||P_0|| ||x||^2 on its own: a weight of 1e6 on a mode no input reaches makes
    ||P_0|| = 1e6 (0.81 + ... + 0.81^10) (by hand: the mode decays by 0.9 whatever the channel does), x0 outside
    it keeps the cost below 1, so the term is over 1e3 times SELF_CHECK_RTOL's."""
    from packetloss_cvx.tolerances import SELF_CHECK_ATOL

    s = pl.System(A=[[0.9, 0.0], [0.0, 0.5]], B=[[0.0], [1.0]], horizon=10, state_weight=[1e6, 1.0],
                  input_weight=[1.0], x0=[0.0, 1.0], channel=GilbertElliott(p=[0.2], r=[0.3]))
    norm_P0 = 1e6 * sum(0.81 ** t for t in range(1, 11))
    exact = augmented_solve(s)[2]
    assert 0.0 < exact < 1.0
    _chain_cost_off(monkeypatch, absolute=factor * SELF_CHECK_ATOL * norm_P0 * 1.0)
    if kept:
        assert augmented_solve(s)[2] == exact
    else:
        with pytest.raises(pl.NumericalError, match="the forward cost of its own plan"):
            augmented_solve(s)


@pytest.mark.parametrize(("seed", "noise"), [(0, True), (1, True), (2, False)])
def test_the_chain_cost_closes_the_free_tail_after_the_plan_ends(monkeypatch, seed, noise):
    """After a plan's last nonzero input the second moment xhat xhat' + Sigma follows Pi+ = A Pi A' + Sigma_W alone;
    on a stable plant with one state weight chain_cost sums the rest of the horizon by Stein sums (with or without
    noise). Against the dense second-moment route (J_udp + U'(Omega_g o C_off)U) of the same plan: a plan that ends
    at step 40 of 300, its tail of 260 steps closed."""
    from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

    augmented_module = importlib.import_module("packetloss_cvx.lq.augmented")
    rng = np.random.default_rng(300 + seed)
    s = attach_channel(random_system(rng, n=3, m=2, horizon=300, spectral_radius=0.9, time_varying=False,
                                     non_stationary=False, noise=noise), GilbertElliott(p=[0.1, 0.3], r=[0.4, 0.2]))
    U = np.zeros((s.horizon, s.m))
    U[:40] = rng.normal(size=(40, s.m))
    closed = []
    real = augmented_module._free_sums
    monkeypatch.setattr(augmented_module, "_free_sums", lambda *a: closed.append(a[-1]) or real(*a))
    assert exact_cost(s, U) == pytest.approx(exact_cost(s, U, method="dense"), rel=PATH_AGREEMENT_RTOL)
    assert closed == [260]


def plain_chain_cost(s, U):
    """The exact UDP-like cost of the plan U (N, m) by the plain forward loop over all N steps, on the chains'
    unreduced correlations xi_i = E[e 1{S_i = a}] (n×k_i: no lift, no basis, no blocks, no closed tail):
    xi+ = A xi T + b u c'T with c = pi o (d - mu), E[e delta_i] = xi_i d_i, and the covariance
    Sigma+ = A Sigma A' + A Y B' + B Y'A' + B diag(mu (1 - mu) u^2) B' + Sigma_W."""
    A, B, N, n, m = s.A, s.B, s.horizon, s.n, s.m
    chains = chain_matrices(s.channel)
    pis = [np.asarray(pi0, float) for _, _, pi0 in chains]
    xis = [np.zeros((n, np.size(d))) for _, d, _ in chains]
    xhat, Sig = s.x0.copy(), np.zeros((n, n))
    total = float(s.x0 @ s.initial_weight @ s.x0)
    for t in range(N):
        u, mu, W = U[t], s.mu_schedule[t], s.state_weights[t]
        Y = np.zeros((n, m))
        for i, (T, d, _) in enumerate(chains):
            Y[:, i] = xis[i] @ d * u[i]
            c = pis[i] * (d - pis[i] @ d)
            xis[i] = A @ xis[i] @ T + np.outer(B[:, i], c @ T) * u[i]
            pis[i] = pis[i] @ T
        Sig = A @ Sig @ A.T + A @ Y @ B.T + B @ Y.T @ A.T + B @ np.diag(mu * (1 - mu) * u * u) @ B.T + s.noise_cov
        xhat = A @ xhat + B @ (mu * u)
        total += float(mu @ (s.input_weights[t] * u * u) + xhat @ W @ xhat + np.sum(W * Sig))
    return total


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("radius", [0.9, 1.03])
@pytest.mark.parametrize("spans", ["one span", "spans of 64 steps"])
def test_the_chain_cost_in_blocks_and_closed_tail_equals_the_plain_loop(monkeypatch, seed, radius, spans):
    """chain_cost (a stable plant with one weight: the forward pass in blocks, in one span or in spans of 64 steps
    carrying the state across, and the free tail by Stein sums; an unstable one: step by step) against the plain loop
    over all N steps on the unreduced correlations, for plans that end early (the tail closed), late and never, on
    Gilbert–Elliott and 3-state chains started away from their stationary laws, with and without noise: to
    PATH_AGREEMENT_RTOL."""
    from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

    if spans != "one span":
        monkeypatch.setattr(importlib.import_module("packetloss_cvx.lq.augmented"), "CHAIN_SPAN_ENTRIES", 1)
    rng = np.random.default_rng(800 + seed)
    N = 300
    if seed % 2:
        channel = MarkovChannel(transition=[rng.dirichlet(np.ones(3), size=3), [[0.5, 0.5], [0.2, 0.8]]],
                                delivery=[rng.uniform(0, 1, 3), [1.0, 0.0]], state=[0, 1])
    else:
        channel = random_channel(rng, 2)
    s = attach_channel(random_system(rng, n=3, m=2, horizon=N, spectral_radius=radius, time_varying=seed == 4,
                                     non_stationary=False, noise=seed % 3 == 0), channel)
    plans = np.zeros((3, N, s.m))                 # ending at steps 17, 250 and N
    for plan, end in zip(plans, (17, 250, N), strict=True):
        plan[:end] = rng.normal(size=(end, s.m)) * 0.98 ** np.arange(end)[:, None]
    references = [plain_chain_cost(s, plan) for plan in plans]
    alone = [chain_cost(s, plan[None])[0] for plan in plans]        # each alone: the first two close a free tail
    assert alone == pytest.approx(references, rel=PATH_AGREEMENT_RTOL, abs=0)
    assert chain_cost(s, plans).tolist() == pytest.approx(references, rel=PATH_AGREEMENT_RTOL, abs=0)


@pytest.mark.parametrize("seed", range(4))
def test_the_recursion_closes_its_run_from_the_chains_fixed_point(monkeypatch, seed):
    """Chains started away from their stationary laws: their distributions reach a float fixed point after some tens
    of steps, from there the augmented data are one map, and the backward pass closes its stationary run there
    (first > 1) and the plan's run is rolled out by powers. Against the same recursion stepped over all N steps (no
    closure, no powers) to PATH_AGREEMENT_RTOL: cost, plan and gain."""
    from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

    augmented_module = importlib.import_module("packetloss_cvx.lq.augmented")
    rng = np.random.default_rng(900 + seed)
    if seed % 2:
        channel = MarkovChannel(transition=[rng.dirichlet(np.ones(3), size=3)], delivery=[rng.uniform(0.2, 1, 3)],
                                state=[2])
        s = attach_channel(random_system(rng, n=2, m=1, horizon=400, spectral_radius=0.8, time_varying=False,
                                         non_stationary=False, noise=True), channel)
    else:
        s = attach_channel(random_system(rng, n=3, m=2, horizon=400, spectral_radius=0.9, time_varying=False,
                                         non_stationary=False, noise=False),
                           GilbertElliott(p=[0.1, 0.3], r=[0.4, 0.2], state=["bad", "good"]))
    starts, runs = [], []
    real, powers = augmented_module._steady_from, augmented_module.states_by_powers
    monkeypatch.setattr(augmented_module, "_steady_from", lambda *a: starts.append(real(*a)) or starts[-1])
    monkeypatch.setattr(augmented_module, "states_by_powers", lambda Y, L: runs.append(Y.shape[1]) or powers(Y, L))
    U, gain, cost = augmented_solve(s)
    assert 1 < starts[0] < 150                     # the chains' fixed point
    assert len(runs) == 1                          # the closed run, rolled out by powers
    assert runs[0] > 100
    monkeypatch.setattr(augmented_module, "STATIONARY_RUN", 10**6)     # every step of the backward pass and rollout
    U_full, gain_full, cost_full = augmented_solve(s)
    assert cost == pytest.approx(cost_full, rel=PATH_AGREEMENT_RTOL, abs=0)
    assert np.max(np.abs(U - U_full)) <= PATH_AGREEMENT_RTOL * np.max(np.abs(U_full))
    assert np.max(np.abs(gain - gain_full)) <= PATH_AGREEMENT_RTOL * np.max(np.abs(gain_full))
