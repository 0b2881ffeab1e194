"""Allocation behind Markov chains (allocation/chains.py): mean rates chosen along each channel's
family (Gilbert channels: burstiness held; any other chain: deliveries scaled), the exact cost under the chain as
the constraint. References: the Bernoulli allocation for memoryless chains and for every TCP-like case, grids of
the exact cost by the dense route on chains built here, the QP twin of the exact minimum, every coin pattern of a
thinned plan, the counterexample that keeps fractional deliveries out of the burstiness-held family, and refusals."""

import itertools
import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.allocation import allocate, min_cost
from packetloss_cvx.allocation.chains import ChainEvaluator, chain_at, chain_family
from packetloss_cvx.cli import main
from packetloss_cvx.lq.costs import closed_form
from packetloss_cvx.lq.markov_cost import exact_closed_form, exact_cost
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.files import dumps_system
from packetloss_cvx.qp.markov import exact_qp


def two_channel(channel, horizon=4):
    return pl.System(A=[[1.05, 0.2], [0.0, 0.9]], B=[[0.0, 1.0], [1.0, 0.3]], horizon=horizon,
                     state_weight=[1.0, 1.0], input_weight=[0.5, 0.5], x0=[1.0, 1.0], channel=channel)


GILBERT = GilbertElliott(p=[0.08, 0.35], r=[0.32, 0.35])          # lambda = 0.6, 0.3; mean rates 0.8, 0.5


def test_memoryless_chain_allocates_as_bernoulli():
    s = two_channel(GilbertElliott(p=[0.3, 0.5], r=[0.7, 0.5]))      # p + r = 1: i.i.d. Bernoulli(r)
    bern = s.with_mu([0.7, 0.5])
    alpha = 1.02 * exact_closed_form(s).cost
    a = allocate(s, "udp", alpha, [1.0, 2.0], gap=1e-6)
    b = allocate(bern, "udp", alpha, [1.0, 2.0], gap=1e-6)
    assert a.status == b.status == "optimal"
    assert a.communication_cost == pytest.approx(b.communication_cost, rel=3e-6)
    assert a.lower_bound <= b.communication_cost * (1 + 1e-9)
    assert b.lower_bound <= a.communication_cost * (1 + 1e-9)
    assert "burstiness lambda = [0.0, 0.0] held" in a.method


def test_allocation_is_certified_against_a_grid_of_the_exact_cost():
    s = two_channel(GILBERT)
    alpha, beta = 1.05 * exact_closed_form(s).cost, np.array([1.0, 0.6])
    a = allocate(s, "udp", alpha, beta, gap=1e-5)
    assert a.status == "optimal"
    lam = np.array([0.6, 0.3])
    evaluator = ChainEvaluator(s.with_mu([0.8, 0.5]), lam)
    grid = np.linspace(0.0, 1.0, 41)
    best = min((beta @ mu for mu in (np.array([x, y]) for x in grid for y in grid) if evaluator.cost(mu) <= alpha),
               default=np.inf)
    assert a.lower_bound <= best * (1 + 1e-9)                  # no grid point beats the proven bound
    assert a.communication_cost <= best * (1 + 1e-5) + 1e-12   # and the allocation is as cheap as the grid allows
    chain = chain_at(s, lam, a.mu)
    np.testing.assert_allclose(chain.channel.mean_rate, a.mu, rtol=1e-14)
    np.testing.assert_allclose(chain.channel.correlation, lam, rtol=1e-12)
    qp = exact_qp(chain)                                        # the exact minimum by another route
    assert qp.cost <= alpha * (1 + 1e-7)
    assert a.cost == pytest.approx(qp.cost, rel=1e-7)


@pytest.mark.parametrize("max_boxes", [1, 2, 4])
def test_a_capped_allocation_reports_the_gap_between_its_own_cost_and_bound(max_boxes):
    """Stopped at a cap, the reported gap is (communication cost - lower bound) / communication cost of the reported
    numbers (prices whose largest is 3: the scaled and unscaled costs differ), and the bound is below every grid
    point that meets alpha (the exact cost by the chain's own evaluator)."""
    s = two_channel(GILBERT)
    alpha, beta = 1.05 * exact_closed_form(s).cost, np.array([3.0, 1.0])
    a = allocate(s, "udp", alpha, beta, max_boxes=max_boxes)
    assert a.status == "gap_not_certified"
    assert a.gap == pytest.approx((a.communication_cost - a.lower_bound) / a.communication_cost, rel=1e-12)
    assert a.communication_cost == pytest.approx(float(beta @ a.mu), rel=1e-12)
    evaluator = ChainEvaluator(s.with_mu([0.8, 0.5]), np.array([0.6, 0.3]))
    grid = np.linspace(0.0, 1.0, 21)
    best = min(beta @ mu for mu in (np.array([x, y]) for x in grid for y in grid) if evaluator.cost(mu) <= alpha)
    assert a.lower_bound <= best * (1 + 1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_exact_cost_falls_as_a_mean_rate_rises(seed):
    """The monotonicity the certificate rests on (proved in docs/mathematics.md): seeded random plants and lambdas."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(2, 2))
    s = pl.System(A=A * 1.1 / max(abs(np.linalg.eigvals(A))), B=rng.normal(size=(2, 2)), horizon=6,
                  state_weight=[1.0, 0.5], input_weight=rng.uniform(0.1, 2, 2), x0=rng.normal(size=2),
                  mu=[0.5, 0.5])
    ev = ChainEvaluator(s, rng.uniform(0.0, 0.95, 2))
    for _ in range(5):
        mu = rng.uniform(0, 1, 2)
        i = int(rng.integers(2))
        higher = mu.copy()
        higher[i] = rng.uniform(mu[i], 1)
        assert ev.cost(higher) <= ev.cost(mu) * (1 + 1e-12)


def test_tcp_allocation_behind_any_stationary_chain_is_the_bernoulli_one():
    ch = MarkovChannel(transition=[[[0.7, 0.2, 0.1], [0.1, 0.5, 0.4], [0.3, 0.3, 0.4]], [[0.9, 0.1], [0.6, 0.4]]],
                       delivery=[[1.0, 0.6, 0.0], [0.95, 0.1]])
    s = two_channel(ch)
    alpha = 1.1 * exact_closed_form(s, "tcp").cost
    a = allocate(s, "tcp", alpha, [1.0, 1.0])
    b = allocate(s.with_mu(ch.mean_rate), "tcp", alpha, [1.0, 1.0])
    np.testing.assert_array_equal(a.mu, b.mu)
    assert a.lower_bound == b.lower_bound


def test_min_cost_behind_a_chain_is_the_perfect_channel():
    least = min_cost(two_channel(GILBERT), "udp")
    perfect = exact_closed_form(chain_at(two_channel(GILBERT), np.array([0.6, 0.3]), np.ones(2)))
    assert least.status == "optimal"
    np.testing.assert_array_equal(least.mu, [1.0, 1.0])
    assert least.cost == pytest.approx(perfect.cost, rel=1e-12)


@pytest.mark.parametrize(
    ("channel", "protocol"),
    [
        (GilbertElliott(p=[0.08, 0.35], r=[0.32, 0.35], state=["good", "bad"]), "udp"),
        (GilbertElliott(p=[0.08, 0.35], r=[0.32, 0.35], belief=[0.5, 0.5]), "tcp"),
        (MarkovChannel(transition=[[[0.9, 0.1], [0.3, 0.7]]] * 2, delivery=[[1.0, 0.2], [1.0, 0.0]], state=[0, 1]),
         "udp"),
    ],
)
def test_a_given_start_is_refused_naming_the_field(channel, protocol):
    with pytest.raises(pl.InputError, match=r"channel\.state/belief"):
        allocate(two_channel(channel), protocol, 10.0, [1.0, 1.0])


# --- the k-state rule: deliveries scaled, transition held (docs/mathematics.md, "Allocation behind chains") -----------

THREE = [[0.8, 0.15, 0.05], [0.2, 0.6, 0.2], [0.1, 0.3, 0.6]]
MIXED = MarkovChannel(transition=[[[0.9, 0.1], [0.3, 0.7]], THREE], delivery=[[1.0, 0.0], [0.9, 0.5, 0.0]])


def stationary(T):
    """The stationary distribution by the eigenvector of T' (not the package's least squares)."""
    vals, vecs = np.linalg.eig(np.asarray(T).T)
    v = np.real(vecs[:, np.argmin(np.abs(vals - 1.0))])
    return v / v.sum()


def mixed_at(mu, horizon=4):
    """two_channel behind MIXED moved to mean rates mu, written from the rule itself: channel 1 a Gilbert channel
    with lambda = 0.6 held, channel 2 the 3-state chain with its deliveries scaled by mu_2 / mubar_2."""
    lam = 0.6
    p, r = (1 - mu[0]) * (1 - lam), mu[0] * (1 - lam)
    d = np.array([0.9, 0.5, 0.0])
    scale = mu[1] / (stationary(THREE) @ d)
    return two_channel(MarkovChannel(transition=[[[1 - p, p], [r, 1 - r]], THREE],
                                     delivery=[[1.0, 0.0], (d * scale).tolist()]), horizon)


def test_each_channel_gets_its_family():
    fam = chain_family(two_channel(MIXED))
    assert fam.lam[0] == pytest.approx(0.6, abs=1e-15)
    assert np.isnan(fam.lam[1])
    mubar = stationary(THREE) @ np.array([0.9, 0.5, 0.0])
    np.testing.assert_allclose(fam.top, [1.0, mubar / 0.9], rtol=1e-12)
    ch = fam.channel_at(np.array([0.3, 0.4]))
    np.testing.assert_allclose(ch.mean_rate, [0.3, 0.4], rtol=1e-12)
    np.testing.assert_allclose(ch.correlation[0], 0.6, rtol=1e-12)
    np.testing.assert_array_equal(ch.transition[1], MIXED.transition[1])          # the transition held
    leaky = chain_family(two_channel(GilbertElliott(p=[0.08, 0.35], r=[0.32, 0.35], h_bad=[0.2, 0.0])))
    assert np.isnan(leaky.lam[0])
    assert leaky.lam[1] == pytest.approx(0.3)
    alternating = chain_family(two_channel(GilbertElliott(p=[0.8, 0.35], r=[0.7, 0.35])))
    assert np.isnan(alternating.lam[0])                                         # lambda < 0: scaled
    np.testing.assert_allclose(alternating.top[0], 0.7 / 1.5, rtol=1e-12)


def test_scaled_deliveries_are_the_link_behind_an_independent_coin():
    """The identity the monotonicity proof rests on: the expected cost of a plan under deliveries s d is the
    average over every pattern of a coin that passes each packet with probability s of the expected cost of the
    thinned plan under d (dense route for the thinned plans, the recursion's forward pass for the scaled chain)."""
    rng = np.random.default_rng(7)
    N, s_ = 5, 0.55
    base = two_channel(MIXED, N)
    scaled = two_channel(MarkovChannel(transition=MIXED.transition, delivery=[MIXED.delivery[0],
                                                                              s_ * MIXED.delivery[1]]), N)
    U = rng.normal(size=(N, 2))
    average = 0.0
    for coin in itertools.product((0.0, 1.0), repeat=N):
        c = np.array(coin)
        thinned = U.copy()
        thinned[:, 1] *= c
        average += s_ ** c.sum() * (1 - s_) ** (N - c.sum()) * exact_cost(base, thinned, method="dense")
    assert exact_cost(scaled, U) == pytest.approx(average, rel=1e-12)


def test_exact_cost_falls_along_both_families_on_a_grid():
    """J* on an 8 x 8 grid of mean rates, each point a chain built by hand and solved by the dense route:
    nonincreasing along each axis; the evaluator agrees with it."""
    fam = chain_family(two_channel(MIXED))
    grid1, grid2 = np.linspace(0.0, 1.0, 8), np.linspace(0.0, fam.top[1], 8)
    J = np.array([[exact_closed_form(mixed_at((a, b)), method="dense").cost for b in grid2] for a in grid1])
    assert np.all(np.diff(J, axis=0) <= 1e-12 * J[1:])
    assert np.all(np.diff(J, axis=1) <= 1e-12 * J[:, 1:])
    assert J[0, 0] > 1.5 * J[-1, -1]                                   # the grid is not flat
    ev = ChainEvaluator(two_channel(MIXED), fam)
    for a, b in ((0.0, 0.0), (0.5, 0.3), (1.0, fam.top[1])):
        i, j = int(np.argmin(np.abs(grid1 - a))), int(np.argmin(np.abs(grid2 - b)))
        assert ev.cost(np.array([grid1[i], grid2[j]])) == pytest.approx(J[i, j], rel=1e-10)
    assert ev.cost(np.array([1.0, 1.0])) == ev.cost(np.array([1.0, fam.top[1]]))   # flat above the top


def test_k_state_allocation_is_certified_against_a_grid():
    s = two_channel(MIXED)
    fam = chain_family(s)
    alpha, beta = 1.1 * exact_closed_form(s).cost, np.array([1.0, 0.7])
    a = allocate(s, "udp", alpha, beta, gap=1e-5)
    assert a.status == "optimal"
    assert a.mu[1] <= fam.top[1] * (1 + 1e-12)
    grid1, grid2 = np.linspace(0.0, 1.0, 21), np.linspace(0.0, fam.top[1], 21)
    feasible = [beta @ (x, y) for x in grid1 for y in grid2
                if exact_closed_form(mixed_at((x, y)), method="dense").cost <= alpha]
    best = min(feasible)
    assert a.lower_bound <= best * (1 + 1e-9)                  # no grid point beats the proven bound
    assert a.communication_cost <= best * (1 + 1e-5) + 1e-12   # and the allocation is as cheap as the grid allows
    qp = exact_qp(mixed_at(a.mu))                              # the exact minimum at the answer by another route
    assert qp.cost <= alpha * (1 + 1e-7)
    assert a.cost == pytest.approx(qp.cost, rel=1e-7)
    assert "channel 2 deliveries scaled" in a.method
    assert "channel 1 burstiness lambda = 0.6 held" in a.method


def test_min_cost_along_scaled_deliveries_is_the_top_of_the_family():
    s = two_channel(MIXED)
    fam = chain_family(s)
    least = min_cost(s, "udp")
    assert least.status == "optimal"
    np.testing.assert_allclose(least.mu, [1.0, fam.top[1]], rtol=1e-9)
    assert least.cost == pytest.approx(exact_closed_form(mixed_at((1.0, fam.top[1])), method="dense").cost, rel=1e-9)
    with pytest.raises(pl.InfeasibleError, match="channel 2's chain reaches mean rates up to"):
        allocate(s, "udp", 1e6, [1.0, 1.0], bounds=(0.7, 1.0))


def test_burstiness_held_with_fractional_deliveries_is_not_monotone():
    """The counterexample of docs/mathematics.md: a Gilbert–Elliott channel h = (1, 0.2), lambda = 0.9 held; raising
    the mean rate from 0.2 to 0.28 raises the exact minimum by 6.9 %. At 0.2 the chain never leaves the bad state
    (i.i.d. losses: the paper's J*_udp at mu = 0.2); at 0.28 the dense route and the QP twin agree."""
    def at(b):
        lam = 0.9
        return pl.System(A=[[1.0]], B=[[1.0]], horizon=8, state_weight=[1.0], input_weight=[0.1], x0=[1.0],
                         channel=GilbertElliott(p=[(1 - b) * (1 - lam)], r=[b * (1 - lam)], h_bad=[0.2]))
    low = closed_form(at(0.0).with_mu([0.2]), "udp").cost
    high = at(0.1)
    assert high.channel.mean_rate[0] == pytest.approx(0.28)
    dense, qp = exact_closed_form(high, method="dense").cost, exact_qp(high).cost
    assert qp == pytest.approx(dense, rel=1e-7)
    assert dense > 1.06 * low
    assert exact_closed_form(at(0.0)).cost == pytest.approx(low, rel=1e-12)


def test_allocate_command_on_a_chain_file(capsys, tmp_path):
    code = main(["allocate", "pendulum_bursty", "--protocol", "udp", "--alpha", "60000", "--beta", "1", "--json"])
    out, err = capsys.readouterr()
    assert (code, err) == (0, "")
    data = json.loads(out)
    assert data["status"] == "optimal"
    assert data["cost"] <= 60000
    bern = allocate(pl.load_example("pendulum_bursty").with_mu([0.9]), "udp", 60000, [1.0])
    assert data["mu"][0] > bern.mu[0] + 0.3        # bursty losses need a far better link than Bernoulli ones
    assert main(["allocate", "pendulum_bursty", "--protocol", "udp", "--alpha", "100", "--beta", "1"]) == 3
    capsys.readouterr()
    leaky = pl.load_example("pendulum_bursty")
    text = dumps_system(leaky).replace("h_bad = [0.0]", "h_bad = [0.1]")
    path = tmp_path / "leaky.toml"
    path.write_text(text)
    code = main(["allocate", str(path), "--protocol", "udp", "--alpha", "60000", "--beta", "1", "--json"])
    out, err = capsys.readouterr()
    assert (code, err) == (0, "")
    data = json.loads(out)
    top = chain_family(pl.load_system(path)).top[0]
    assert data["mu"][0] <= top * (1 + 1e-12)
    assert "deliveries scaled" in data["method"]
    code = main(["allocate", str(path), "--protocol", "udp", "--alpha", "60000", "--beta", "1", "--bounds", "0.95,1"])
    out, err = capsys.readouterr()
    assert (code, out) == (3, "")
    assert err.count("\n") == 1
    assert "reaches mean rates up to" in err


def test_allocate_on_a_chain_file_allocates_under_the_chain(capsys):
    """allocate on a file whose channel is a chain allocates under the chain, not a Bernoulli mu*: the decision is
    the chain's mean rate: TCP-like, whose cost holds only mu_t, exactly the Bernoulli
    allocation of the same plant at that rate; UDP-like, the exact cost under the chain
    (tests/allocation/test_allocation_chains.py)."""
    assert main(["allocate", "pendulum_bursty", "--protocol", "tcp", "--alpha", "20000", "--beta", "1", "--json"]) == 0
    chain = json.loads(capsys.readouterr().out)
    bern = allocate(pl.load_example("pendulum_bursty").with_mu([0.9]), "tcp", 20000, [1.0])
    assert chain["status"] == "optimal"
    assert chain["mu"] == bern.mu.tolist()
