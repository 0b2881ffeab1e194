"""Theorem 1 in closed form against the Clarabel QPs and against first principles."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.costs import dense_cost
from packetloss_cvx.prediction import prediction
from packetloss_cvx.random_systems import random_system

PROTOCOLS = ("tcp", "udp")
SEEDS = range(60)


def _random(seed: int) -> pl.System:
    rng = np.random.default_rng(seed)
    # cycle deterministically through the schema's features, then randomise the rest
    bits = [(seed >> k) & 1 == 1 for k in range(5)]
    return random_system(
        rng, full_weights=bits[0], time_varying=bits[1], non_stationary=bits[2],
        noise=bits[3], edge_mu=bits[4],
    )


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_closed_form_matches_condensed_qp(seed, protocol):
    system = _random(seed)
    ref = pl.closed_form(system, protocol, method="dense")
    qp = pl.solve_qp(system, protocol, "condensed", with_gain=False, cross_check=False)
    assert qp.status == "optimal"
    assert np.max(np.abs(qp.inputs - ref.inputs)) < 1e-6
    assert abs(qp.cost - ref.cost) <= 1e-7 * abs(ref.cost)


@pytest.mark.parametrize("seed", SEEDS[::3])
@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_closed_form_matches_sparse_qp_and_gain(seed, protocol):
    system = _random(seed)
    ref = pl.closed_form(system, protocol, method="dense")
    qp = pl.solve_qp(system, protocol, "sparse")
    assert np.max(np.abs(qp.inputs - ref.inputs)) < 1e-6
    assert abs(qp.cost - ref.cost) <= 1e-7 * abs(ref.cost)
    # the gain recovered from n solves at unit states is the first block of G^{-1} Omega_gp
    assert np.allclose(qp.gain, ref.gain, rtol=1e-6, atol=1e-6)
    assert qp.cross_check.max_input_diff < 1e-6


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_stationarity_and_minimality(seed, protocol):
    """KKT residual of the unconstrained QP is zero, and no perturbation does better."""
    system = _random(seed)
    pred = prediction(system)
    sol = pl.closed_form(system, protocol)
    u = sol.inputs.ravel()
    v = pred.Vbar
    hess = v[:, None] * pred.Omega_g * v[None, :] + np.diag(v * pred.Psi)
    if protocol == "udp":
        hess += np.diag(v * pred.Omega_d * (1 - v))
    grad = hess @ u + v * (pred.Omega_gp @ system.x0)
    scale = np.linalg.norm(hess, 2) * max(1.0, np.linalg.norm(u)) + np.linalg.norm(pred.Omega_gp @ system.x0)
    assert np.linalg.norm(grad) <= 1e-10 * scale
    assert np.isclose(pl.expected_cost(system, sol.inputs, protocol, "dense"), sol.cost, rtol=1e-10)
    rng = np.random.default_rng(seed)
    for _ in range(5):
        trial = sol.inputs + 1e-3 * rng.normal(size=sol.inputs.shape)
        assert pl.expected_cost(system, trial, protocol, "dense") >= sol.cost - 1e-9 * abs(sol.cost)


@pytest.mark.parametrize("seed", SEEDS)
def test_expected_cost_dense_equals_forward_pass(seed):
    system = _random(seed)
    U = np.random.default_rng(seed + 1000).normal(size=(system.horizon, system.m))
    for protocol in PROTOCOLS:
        a = pl.expected_cost(system, U, protocol, "dense")
        b = pl.expected_cost(system, U, protocol, "recursion")
        assert np.isclose(a, b, rtol=1e-10)


def test_udp_minus_tcp_is_the_variance_term(two_actuator):
    U = np.random.default_rng(3).normal(size=(10, 2))
    pred = prediction(two_actuator)
    u, v = U.ravel(), pred.Vbar
    diff = pl.expected_cost(two_actuator, U, "udp") - pl.expected_cost(two_actuator, U, "tcp")
    assert np.isclose(diff, np.sum(u * v * pred.Omega_d * (1 - v) * u), rtol=1e-12)
    assert diff > 0


@pytest.mark.parametrize("name", ["two_actuator", "pendulum"])
@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_examples_cross_check(name, protocol, request):
    system = request.getfixturevalue(name)
    for formulation in ("condensed", "sparse"):
        qp = pl.solve_qp(system, protocol, formulation)
        assert qp.status == "optimal"
        assert qp.cross_check.max_input_diff < 1e-6
        assert qp.cross_check.cost_rel_diff < 1e-7


def test_zero_probability_channel_is_handled(two_actuator):
    """mu_i = 0: that input never arrives, any value is optimal; cost and the rest agree."""
    system = two_actuator.with_mu([0.0, 0.7])
    for protocol in PROTOCOLS:
        ref = pl.closed_form(system, protocol)
        qp = pl.solve_qp(system, protocol, "sparse", with_gain=False)
        assert np.max(np.abs(qp.inputs[:, 1] - ref.inputs[:, 1])) < 1e-6
        assert abs(qp.cost - ref.cost) <= 1e-7 * ref.cost
        # with channel 1 dead, the cost is that of the single-actuator plant
        single = pl.System(A=system.A, B=system.B[:, 1:], horizon=10, state_weight=[1, 1],
                           input_weight=[1.0], mu=[0.7], x0=system.x0)
        assert np.isclose(ref.cost, pl.closed_form(single, protocol).cost, rtol=1e-12)


def test_paper_cost_formula_is_wrong_for_distinct_channels(two_actuator):
    """eq:TCP-opt-cost prints G^{-1} Vbar; the minimum has Vbar G^{-1} (docs/claims.md)."""
    for protocol in PROTOCOLS:
        true_min = pl.solve_qp(two_actuator, protocol, "condensed", with_gain=False).cost
        printed = pl.paper_optimal_cost(two_actuator, protocol)
        corrected = pl.closed_form(two_actuator, protocol).cost
        assert np.isclose(corrected, true_min, rtol=1e-7)
        assert abs(printed - true_min) > 1.0  # off by a factor: 169.8 vs 2.80 (TCP)


@pytest.mark.parametrize("seed", range(10))
def test_paper_cost_formula_holds_for_a_shared_channel(seed):
    """With Vbar = nu I the two orders commute and the printed formula is exact."""
    rng = np.random.default_rng(seed)
    base = random_system(rng, non_stationary=False, edge_mu=False)
    system = base.with_mu(np.full(base.m, float(rng.uniform(0.05, 0.95))))
    for protocol in PROTOCOLS:
        assert np.isclose(pl.paper_optimal_cost(system, protocol), pl.closed_form(system, protocol).cost,
                          rtol=1e-9)


def test_dense_cost_with_prebuilt_prediction_matches(two_actuator):
    U = np.ones((10, 2))
    pred = prediction(two_actuator)
    assert dense_cost(two_actuator, U, "udp", pred) == dense_cost(two_actuator, U, "udp")


def test_perfect_channel_protocols_coincide(two_actuator):
    system = two_actuator.with_mu([1.0, 1.0])
    tcp, udp = pl.closed_form(system, "tcp"), pl.closed_form(system, "udp")
    assert np.isclose(tcp.cost, udp.cost, rtol=1e-12)
    assert np.allclose(tcp.inputs, udp.inputs, atol=1e-12)


def test_receding_horizon_gain_is_first_block(two_actuator):
    sol = pl.closed_form(two_actuator, "tcp")
    other = pl.closed_form(two_actuator.with_x0([0.3, -2.0]), "tcp")
    assert np.allclose(sol.gain @ two_actuator.x0, -sol.inputs[0], atol=1e-12)
    assert np.allclose(sol.gain @ np.array([0.3, -2.0]), -other.inputs[0], atol=1e-12)
    assert np.allclose(np.sort_complex(sol.closed_loop_eigenvalues),
                       np.sort_complex(np.linalg.eigvals(two_actuator.A - two_actuator.B @ sol.gain)))


@pytest.mark.parametrize(
    "changes",
    [
        {"state_weight": [0.0, 0.0]},                                  # no state weight at all
        {"state_weight": None, "state_weights": [[0, 0], [1, 1], [0, 0]]},
        {"mu": None, "mu_schedule": [[0, 1], [1, 0], [0.5, 0.5]]},   # channels dead at some steps
        {"mu": [0.0, 0.0]},
        {"x0": [0.0, 0.0]},
    ],
)
@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_edge_cases_agree_everywhere(changes, protocol):
    kwargs = {"A": [[1.1, 0.2], [0, 0.9]], "B": [[1, 0], [0.5, 1]], "horizon": 3, "x0": [1, -1],
              "state_weight": [1, 1], "input_weight": [1, 1], "mu": [0.5, 0.5], "noise_cov": [[0.1, 0], [0, 0.1]]}
    kwargs.update(changes)
    system = pl.System(**{k: v for k, v in kwargs.items() if v is not None})
    dense = pl.closed_form(system, protocol, "dense")
    rec = pl.closed_form(system, protocol, "recursion")
    assert np.isclose(dense.cost, rec.cost, rtol=1e-12, atol=1e-12)
    for formulation in ("condensed", "sparse"):
        qp = pl.solve_qp(system, protocol, formulation)
        assert qp.status == "optimal"
        assert qp.cross_check.max_input_diff < 1e-6
        assert abs(qp.cost - dense.cost) <= 1e-7 * max(1.0, dense.cost)
