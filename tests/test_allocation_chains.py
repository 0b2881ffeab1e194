"""Allocation behind Markov chains (allocation/chains.py; issue 23 item 5): mean rates chosen with the burstiness
held, the exact cost under the chain as the constraint. References: the Bernoulli allocation for memoryless chains
and for every TCP-like case, a grid of the exact cost, the QP twin of the exact minimum, and refusals by field."""

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.allocation import allocate, min_cost
from packetloss_cvx.allocation.chains import ChainEvaluator, chain_at
from packetloss_cvx.channel import GilbertElliott
from packetloss_cvx.cli import main
from packetloss_cvx.io import dumps_system
from packetloss_cvx.markov import exact_closed_form, exact_qp
from packetloss_cvx.markov_channel import MarkovChannel


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


@pytest.mark.parametrize("seed", range(4))
def test_exact_cost_falls_as_a_mean_rate_rises(seed):
    """The monotonicity the certificate rests on (proved in docs/design.md): seeded random plants and lambdas."""
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
    ("channel", "protocol", "match"),
    [
        (GilbertElliott(p=[0.08, 0.35], r=[0.32, 0.35], state=["good", "bad"]), "udp", r"channel\.state/belief"),
        (GilbertElliott(p=[0.08, 0.35], r=[0.32, 0.35], belief=[0.5, 0.5]), "tcp", r"channel\.state/belief"),
        (GilbertElliott(p=[0.08, 0.35], r=[0.32, 0.35], h_bad=[0.2, 0.0]), "udp",
         r"channel\.h_good/h_bad: UDP-like allocation over a chain needs Gilbert channels"),
        (GilbertElliott(p=[0.8, 0.35], r=[0.7, 0.35]), "udp", r"channel\.p: .*lambda = 1 - p - r in \[0, 1\)"),
        (MarkovChannel(transition=[[[0.7, 0.2, 0.1], [0.1, 0.5, 0.4], [0.3, 0.3, 0.4]], [[0.9, 0.1], [0.6, 0.4]]],
                       delivery=[[1.0, 0.6, 0.0], [1.0, 0.0]]), "udp", r"channel\.transition: .*two-state"),
        (MarkovChannel(transition=[[[0.9, 0.1], [0.3, 0.7]]] * 2, delivery=[[1.0, 0.2], [1.0, 0.0]]), "udp",
         r"channel\.delivery: UDP-like allocation over a chain needs Gilbert channels"),
    ],
)
def test_chains_outside_the_proof_are_refused_naming_the_field(channel, protocol, match):
    with pytest.raises(pl.InputError, match=match):
        allocate(two_channel(channel), protocol, 10.0, [1.0, 1.0])


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
    text = dumps_system(pl.load_example("pendulum_bursty")).replace("h_bad = [0.0]", "h_bad = [0.1]")
    path = tmp_path / "leaky.toml"
    path.write_text(text)
    code = main(["allocate", str(path), "--protocol", "udp", "--alpha", "60000", "--beta", "1"])
    out, err = capsys.readouterr()
    assert (code, out) == (2, "")
    assert err.count("\n") == 1
    assert "channel.h_good/h_bad" in err
