"""Design on the TCP-like attainable cost behind a chain (``allocate(..., target="attainable")``,
allocation.attainable.ChainAttainableEvaluator): the chain DP's cost non-increasing along both families (the proof
in docs/mathematics.md, "Design on the attainable cost behind a chain", checked numerically on many seeded chains),
the allocation against a grid, and the refusals.

Independent reference, reused: the brute-force DP over delivery histories with probabilities summed over hidden
paths of tests/closedloop/test_chain_dp.py (no filter, no nodes); the chains at each mean rate written out here from
the family's formulas (Gilbert: p = (1 - mu)(1 - lambda), r = mu (1 - lambda); scaled: d mu / mubar).
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from packetloss_cvx import System, allocate
from packetloss_cvx.cli import main
from packetloss_cvx.errors import BudgetError, InputError
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.files import save_system
from packetloss_cvx.tolerances import ALLOCATION_COST_RTOL, PATH_AGREEMENT_RTOL

sys.path.insert(0, str(Path(__file__).parents[1] / "closedloop"))
from test_chain_dp import brute_force_dp  # noqa: E402


def held(lam, mu):
    return GilbertElliott(p=[(1 - mu) * (1 - lam)], r=[mu * (1 - lam)])


def scaled(T, d, mubar, mu):
    return MarkovChannel(transition=[T], delivery=[np.minimum(np.asarray(d) * mu / mubar, 1.0)])


def random_plant(rng, channel, horizon):
    n = int(rng.integers(1, 3))
    return System(A=rng.normal(size=(n, n)) * rng.uniform(0.6, 1.4), B=rng.normal(size=(n, 1)), horizon=horizon,
                  state_weight=rng.uniform(0.5, 2.0, n), input_weight=[float(rng.choice([0.05, 0.5, 2.0]))],
                  x0=rng.normal(size=n), noise_cov=0.1 * np.eye(n) if rng.uniform() < 0.5 else None,
                  channel=channel)


@pytest.mark.parametrize("seed", range(4))
def test_the_brute_force_dp_falls_along_the_burstiness_held_family(seed):
    """10 seeded plants a seed behind Gilbert channels (lambda in [0, 0.97]), N = 3, mean rates 0.05 .. 0.95."""
    rng = np.random.default_rng(seed)
    for _ in range(10):
        lam = float(rng.choice([0.0, 0.3, 0.7, 0.97]))
        s = random_plant(rng, held(lam, 0.5), 3)
        costs = [brute_force_dp(s.with_channel(held(lam, mu))) for mu in np.linspace(0.05, 0.95, 7)]
        assert all(b <= a * (1 + PATH_AGREEMENT_RTOL) for a, b in zip(costs, costs[1:], strict=False)), costs
        assert costs[-1] < costs[0]


@pytest.mark.parametrize("seed", range(4))
def test_the_brute_force_dp_falls_along_the_scaled_family_of_hidden_chains(seed):
    """10 seeded plants a seed behind two- and three-state chains with fractional deliveries (the state hidden),
    N = 3, mean rates up to the family's top."""
    rng = np.random.default_rng(100 + seed)
    for _ in range(10):
        k = int(rng.integers(2, 4))
        T = rng.dirichlet(np.ones(k), size=k)
        d = rng.uniform(0.0, 1.0, k)
        chain = MarkovChannel(transition=[T], delivery=[d])
        mubar = float(chain.mean_rate[0])
        top = mubar / d.max()
        s = random_plant(rng, chain, 3)
        costs = [brute_force_dp(s.with_channel(scaled(T, d, mubar, mu))) for mu in np.linspace(0.0, top, 6)]
        assert all(b <= a * (1 + PATH_AGREEMENT_RTOL) for a, b in zip(costs, costs[1:], strict=False)), costs


def test_the_attainable_design_behind_a_gilbert_channel_matches_a_grid_of_the_brute_force_dp():
    """x' = 1.5 x + v u behind a Gilbert channel (lambda = 0.1 held), N = 3: mu* is where the brute-force DP meets
    alpha (the least rate meeting it, the cost falling), to the allocation's gap."""
    lam, alpha = 0.1, 3.0
    s = System(A=[[1.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=held(lam, 0.9))
    a = allocate(s, "tcp", alpha, [1.0], target="attainable")
    assert a.status == "optimal"
    assert a.basis == "attainable"
    mu = float(a.mu[0])
    assert a.cost == pytest.approx(brute_force_dp(s.with_channel(held(lam, mu))), rel=PATH_AGREEMENT_RTOL)
    assert a.cost <= alpha * (1 + ALLOCATION_COST_RTOL)
    below = mu * (1 - 2 * a.gap) - 1e-6                            # cheaper by more than the certified gap
    assert brute_force_dp(s.with_channel(held(lam, below))) > alpha
    grid = np.linspace(0.0, 1.0, 101)
    first = next(x for x in grid if brute_force_dp(s.with_channel(held(lam, x))) <= alpha)
    assert first - 0.01 <= mu <= first
    assert a.attainable_cost == pytest.approx(a.cost, rel=PATH_AGREEMENT_RTOL)
    paper = allocate(s, "tcp", alpha, [1.0])                       # the paper's program: cheaper, and misses alpha
    assert paper.mu[0] < mu
    assert paper.attainable_cost > alpha


def test_the_attainable_design_behind_a_hidden_chain_stays_within_its_top():
    """A hidden two-state chain (deliveries (0.9, 0.3)): the family reaches mean rates up to mubar / 0.9; alpha met at
    mu* by the brute-force DP, and an alpha below the DP's least cost (at the top) is proved infeasible."""
    T = np.array([[0.85, 0.15], [0.25, 0.75]])
    d = np.array([0.9, 0.3])
    s = System(A=[[1.2]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=MarkovChannel(transition=[T], delivery=[d]))
    mubar = float(s.channel.mean_rate[0])
    top = mubar / 0.9
    least = brute_force_dp(s.with_channel(scaled(T, d, mubar, top)))
    alpha = 1.05 * least
    a = allocate(s, "tcp", alpha, [1.0], target="attainable")
    mu = float(a.mu[0])
    assert mu <= top * (1 + 1e-12)
    assert brute_force_dp(s.with_channel(scaled(T, d, mubar, mu))) <= alpha * (1 + ALLOCATION_COST_RTOL)
    from packetloss_cvx.errors import InfeasibleError
    with pytest.raises(InfeasibleError):
        allocate(s, "tcp", 0.95 * least, [1.0], target="attainable")


def test_the_attainable_design_refuses_a_hidden_chain_beyond_the_dp_budget_in_advance(capsys, tmp_path, monkeypatch):
    """The exact DP over a hidden chain's histories beyond chain_dp_nodes: a BudgetError (a ValueError) before the
    search, naming what to use instead; on the command line exit 2, one line."""
    s = System(A=[[1.2]], B=[[1.0]], horizon=12, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=GilbertElliott(p=[0.1], r=[0.3], h_good=[0.9], h_bad=[0.2]))
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_CHAIN_DP_NODES", "2000")
    with pytest.raises(BudgetError, match="chain_attainable's bounds") as err:
        allocate(s, "tcp", 100.0, [1.0], target="attainable")
    assert isinstance(err.value, ValueError)
    path = str(save_system(s, tmp_path / "hidden.toml"))
    code = main(["allocate", path, "--protocol", "tcp", "--alpha", "100", "--beta", "1", "--target", "attainable"])
    out, errtext = capsys.readouterr()
    assert (code, out) == (2, "")
    assert errtext.count("\n") == 1


def test_the_attainable_design_refuses_a_chain_with_a_given_state():
    s = System(A=[[1.2]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
               channel=GilbertElliott(p=[0.1], r=[0.3], state=["good"]))
    with pytest.raises(InputError, match="stationary start"):
        allocate(s, "tcp", 3.0, [1.0], target="attainable")
