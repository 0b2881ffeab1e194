"""Allocation against a brute-force reference: grid on mu1, bisection on mu2 (monotonicity)."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.allocation import allocate, best_cost_within_budget, min_cost, parse_constraint
from packetloss_cvx.allocation.brute_force import brute_force_allocation
from packetloss_cvx.random_systems import random_system


def _J(system, protocol, mu):
    return pl.closed_form(system.with_mu(mu), protocol).cost


def _check(system, protocol, alpha, beta, constraints=(), G=None, h=None):
    G = np.zeros((0, 2)) if G is None else G
    h = np.zeros(0) if h is None else h
    ref = brute_force_allocation(system, protocol, alpha, beta, G, h)
    got = allocate(system, protocol, alpha, beta, constraints=constraints)
    assert got.cost <= alpha * (1 + 1e-7)                       # never infeasible
    assert np.isclose(_J(system, protocol, got.mu), got.cost, rtol=1e-12)
    if G.shape[0]:
        assert np.all(G @ got.mu <= h + 1e-7)
    assert got.communication_cost <= ref[0] * (1 + 1e-3) + 1e-9  # within 1e-3 of the reference
    assert got.lower_bound <= ref[0] + 1e-9                      # the certificate is a real bound
    assert got.gap <= 1e-4 + 1e-12
    return got, ref


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize("beta", [(1.0, 1.0), (0.05, 1.0), (1.0, 0.05)])
@pytest.mark.parametrize("alpha", [4.78, 8.0])
def test_two_actuator_against_brute_force(two_actuator, protocol, beta, alpha):
    _check(two_actuator, protocol, alpha, beta)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_with_linear_constraints(two_actuator, protocol):
    texts = ["mu1 >= mu2", "mu1 + 2*mu2 <= 2.5"]
    pairs = [parse_constraint(t, 2) for t in texts]
    G = np.vstack([p[0] for p in pairs])
    h = np.concatenate([p[1] for p in pairs])
    got, _ = _check(two_actuator, protocol, 6.0, (0.05, 1.0), constraints=pairs, G=G, h=h)
    assert got.mu[0] >= got.mu[1] - 1e-7


def test_callable_constraint_tcp(two_actuator):
    got = allocate(two_actuator, "tcp", 6.0, (1.0, 1.0), constraints=[lambda mu: [mu[0] <= 0.3]])
    assert got.mu[0] <= 0.3 + 1e-7
    assert got.cost <= 6.0 * (1 + 1e-7)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_random_systems_against_brute_force(seed, protocol):
    rng = np.random.default_rng(100 + seed)
    s = random_system(rng, n=2, m=2, horizon=4, non_stationary=False, edge_mu=False)
    full = _J(s, protocol, [1.0, 1.0])
    none = _J(s, protocol, [0.0, 0.0])
    alpha = full + 0.25 * (none - full)
    beta = rng.uniform(0.1, 1.0, 2)
    G, h = parse_constraint("mu1 + mu2 <= 1.8", 2)
    _check(s, protocol, alpha, beta)
    if _J(s, protocol, [0.9, 0.9]) <= alpha:
        _check(s, protocol, alpha, beta, constraints=[(G, h)], G=G, h=h)


def test_infeasible_alpha_reports_min_cost(two_actuator):
    least = _J(two_actuator, "udp", [1.0, 1.0])
    with pytest.raises(pl.InfeasibleError) as info:
        allocate(two_actuator, "udp", least * 0.99, (1.0, 1.0))
    assert np.isclose(info.value.min_cost, least, rtol=1e-9)
    capped = _J(two_actuator, "tcp", [0.5, 1.0])
    with pytest.raises(pl.InfeasibleError) as info:
        allocate(two_actuator, "tcp", capped * 0.99, (1.0, 1.0), constraints=[parse_constraint("mu1 <= 0.5", 2)])
    assert np.isclose(info.value.min_cost, capped, rtol=1e-6)


def test_budget_side_of_the_tradeoff(two_actuator):
    """min J* s.t. beta'mu <= b, then allocating at that cost spends about b."""
    for protocol in ("tcp", "udp"):
        best = best_cost_within_budget(two_actuator, protocol, (1.0, 1.0), 1.2)
        back = allocate(two_actuator, protocol, best * (1 + 1e-6), (1.0, 1.0))
        assert back.communication_cost <= 1.2 + 1e-3
        assert back.communication_cost >= 1.2 * 0.98
    assert min_cost(two_actuator, "udp") == pytest.approx(_J(two_actuator, "udp", [1.0, 1.0]))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"alpha": -1.0}, "alpha: expected a positive"),
        ({"beta": (1.0,)}, "beta: expected 2"),
        ({"beta": (1.0, -1.0)}, "beta: expected finite non-negative"),
        ({"bounds": (0.5, 0.2)}, "bounds: expected 0 <= lo <= hi <= 1"),
        ({"constraints": [(np.ones((1, 3)), [1.0])]}, r"constraints\[0\]: expected G of shape"),
        ({"gap": 0.0}, "gap: expected a number in"),
    ],
)
def test_bad_allocation_input(two_actuator, kwargs, match):
    args = {"protocol": "tcp", "alpha": 5.0, "beta": (1.0, 1.0), **kwargs}
    with pytest.raises(pl.InputError, match=match):
        allocate(two_actuator, **args)


@pytest.mark.parametrize(
    ("text", "G", "h"),
    [
        ("mu1 + 2*mu2 <= 1.5", [[1, 2]], [1.5]),
        ("mu1 >= mu2", [[-1, 1]], [0.0]),
        ("mu2 <= 0.8", [[0, 1]], [0.8]),
        ("0.5 mu1 - mu2 + 0.1 >= 0.2", [[-0.5, 1]], [-0.1]),
        ("mu1 == 0.3", [[1, 0], [-1, 0]], [0.3, -0.3]),
    ],
)
def test_parse_constraint(text, G, h):
    g, c = parse_constraint(text, 2)
    assert np.allclose(g, G)
    assert np.allclose(c, h)


@pytest.mark.parametrize(
    ("text", "match"),
    [("mu3 <= 1", "unknown channel 'mu3'"), ("mu1 <=", "expression on both sides"), ("mu1 + <= 1", "cannot parse"),
     ("mu1 mu2 <= 1", "expected '\\+' or '-'"), ("mu1 <= 1 <= 2", "one comparison"), ("1 <= 2", "does not involve"),
     ("__import__('os') <= 1", "cannot parse")],
)
def test_parse_constraint_errors(text, match):
    with pytest.raises(pl.InputError, match=match):
        parse_constraint(text, 2)
