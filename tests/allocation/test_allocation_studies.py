"""The studies compute what the figures show: allocations along alpha, and the J*(mu) grid."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.allocation import allocate
from packetloss_cvx.allocation.brute_force import brute_force_allocation
from packetloss_cvx.studies.allocation import contour_allocations, cost_grid, pareto_curve


def test_pareto_curve_rows(two_actuator):
    rows = {p: pareto_curve(two_actuator, p, (1.0, 1.0), [1.5, 4.78]) for p in ("tcp", "udp")}
    assert rows["udp"][0] == {"alpha": 1.5, "communication_cost": None, "mu": None, "lower_bound": None,
                              "status": "infeasible"}             # below J*_udp(1, 1) = 1.8
    tcp, udp = rows["tcp"][1], rows["udp"][1]
    assert tcp["communication_cost"] < udp["communication_cost"]   # TCP-like needs less channel (Theorem 2)
    for protocol in ("tcp", "udp"):
        ref = brute_force_allocation(two_actuator, protocol, 4.78, (1.0, 1.0))
        assert rows[protocol][1]["lower_bound"] <= ref[0] + 1e-9
    direct = allocate(two_actuator, "udp", 4.78, (1.0, 1.0))
    assert udp["mu"] == direct.mu.tolist()
    assert udp["status"] == direct.status == "optimal"


def test_contour_allocations_keys(two_actuator):
    out = contour_allocations(two_actuator, "tcp", [10.0], betas=[(1, 1), (0.05, 1)])
    assert list(out) == [(1.0, 1.0), (0.05, 1.0)]
    for beta, rows in out.items():
        assert rows[0]["lower_bound"] <= brute_force_allocation(two_actuator, "tcp", 10.0, beta)[0] + 1e-9
    assert out[(0.05, 1.0)][0]["mu"][0] > out[(0.05, 1.0)][0]["mu"][1]   # the cheap channel is bought first


def test_cost_grid_against_the_qp_twin(two_actuator):
    axis, costs = cost_grid(two_actuator, "udp", grid=5)
    assert np.array_equal(axis, [0.0, 0.25, 0.5, 0.75, 1.0])
    for i, j in [(1, 3), (3, 1), (4, 0)]:                       # costs[j, i] = J*(mu1 = axis[i], mu2 = axis[j])
        qp = pl.solve_qp(two_actuator.with_mu([axis[i], axis[j]]), "udp", cross_check=False, with_gain=False)
        assert costs[j, i] == pytest.approx(qp.cost, rel=1e-6)


@pytest.mark.parametrize("grid", [1, 402, 2.5, True])
def test_cost_grid_bad_size(two_actuator, grid):
    with pytest.raises(pl.InputError, match="^grid"):
        cost_grid(two_actuator, "tcp", grid=grid)


def test_cost_grid_needs_two_channels(pendulum):
    with pytest.raises(pl.InputError, match="^system: the contour grid needs m = 2"):
        cost_grid(pendulum, "tcp")
