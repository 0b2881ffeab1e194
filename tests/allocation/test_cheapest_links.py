"""allocation.api.cheapest_links and stability_allocate(actuator=): the cheapest links per actuator strategy for a
cost target on its optimal TCP-like law.

References: brute force, a grid over mu with the strategy's optimal law's cost at every point
(closedloop.actuator_design.actuator_dp, no search, no monotonicity used), which brackets the optimal price: every
feasible grid point bounds it from above, and rounding any feasible point up to the grid keeps it feasible (the cost
falls in each mu_i) at a price at most sum_i beta_i h higher, so the optimum is at least the grid's best minus
that (behind a chain, along its family written out by hand); zero's design on the channel's own DP
(stability_allocate without a strategy: dp_riccati and the region's membership, another algorithm); the scalar
plant by hand.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from packetloss_cvx import load_example
from packetloss_cvx.allocation.api import cheapest_links
from packetloss_cvx.allocation.stability import stability_allocate
from packetloss_cvx.closedloop.actuator_design import actuator_dp
from packetloss_cvx.errors import InputError, NumericalError
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.system import System
from packetloss_cvx.tolerances import ALLOCATION_COST_RTOL

GAP = 1e-3


def _cost(system: System, strategy: str, mu) -> float:
    try:
        return actuator_dp(system, strategy, np.asarray(mu, dtype=float)).initial    # noise-free: the cost from x0
    except NumericalError:
        return np.inf


def _grid_best(system: System, strategy: str, alpha: float, beta: np.ndarray, axis: np.ndarray) -> float:
    """The least beta'mu over the grid points whose cost is <= alpha: every point, cheapest first, until the first
    feasible one (the points after it cannot be cheaper)."""
    points = sorted(itertools.product(axis, repeat=system.m), key=lambda mu: float(beta @ np.array(mu)))
    return next((float(beta @ np.array(mu)) for mu in points if _cost(system, strategy, mu) <= alpha), np.inf)


def _axis(k: int) -> np.ndarray:
    """h, 2h, .., 1 (h = 1/k): any mu_i in [0, 1] rounds up onto it by at most h (mu_i = 0 itself, where an actuator
    never delivers and hold's value iteration runs to its cap, is not a grid point)."""
    return np.linspace(1.0 / k, 1.0, k)


def _check_against_grid(system: System, strategy: str, alpha: float, beta: np.ndarray, axis: np.ndarray) -> None:
    row = cheapest_links(system, alpha, beta, strategy, gap=GAP)[strategy]
    assert row["verdict"] == "reachable"
    assert row["basis"] == "total from x0"
    mu = np.array(row["mu"])
    assert _cost(system, strategy, mu) <= alpha                      # feasible, recomputed
    best = _grid_best(system, strategy, alpha, beta, axis)
    h = float(axis[1] - axis[0])
    # lower_bound <= optimum <= best; price <= optimum / (1 - gap); best <= price + sum beta h (round mu up)
    assert row["lower_bound"] <= best
    assert row["communication_cost"] <= best / (1.0 - GAP)
    assert best <= row["communication_cost"] + float(beta.sum()) * h
    assert row["status"] == "optimal"
    assert row["stabilisable"] is True


@pytest.mark.parametrize("strategy", ["zero", "hold"])
def test_two_actuator_cheapest_links_match_a_brute_force_grid(strategy):
    _check_against_grid(load_example("two_actuator"), strategy, 8.0, np.array([1.0, 0.5]), _axis(40))


@pytest.mark.parametrize("strategy", ["zero", "hold", "buffer:2"])
def test_pendulum_cheapest_links_match_a_brute_force_grid(strategy):
    _check_against_grid(load_example("pendulum"), strategy, 30000.0, np.array([1.0]), _axis(50))


def test_the_strategies_differ_on_the_pendulum_so_the_grid_checks_tell_them_apart():
    rows = cheapest_links(load_example("pendulum"), 30000.0, None, "zero,hold", gap=GAP)
    assert rows["zero"]["communication_cost"] - rows["hold"]["communication_cost"] > 0.1


def test_zero_through_the_strategy_engine_matches_the_channels_own_design():
    system = load_example("two_actuator")
    ours = stability_allocate(system, "dp-cost", [1.0, 1.0], alpha=8.0, gap=1e-2, actuator="zero")
    ref = stability_allocate(system, "dp-cost", [1.0, 1.0], alpha=8.0, gap=1e-2)
    assert max(ours.lower_bound, ref.lower_bound) <= min(ours.cost, ref.cost)     # both bracket the optimum
    assert ours.dp_cost <= 8.0
    assert ref.dp_cost <= 8.0


def test_an_unreachable_target_is_proved_with_the_least_cost_at_the_upper_corner():
    # x+ = 2 x + v u, Omega = Psi = 1, from x0 = 1: at mu = 1 the DARE's P = 2 + sqrt(5), the least any strategy
    # reaches (all deliver: the actuator's memory is never used)
    s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    rows = cheapest_links(s, 4.0, None, "zero,hold,buffer:2")
    for row in rows.values():
        assert row["verdict"] == "unreachable"
        assert row["least_cost"] == pytest.approx(2 + 5 ** 0.5, rel=1e-9)
        assert row["least_cost_mu"] == [1.0]


def test_scalar_zero_by_hand():
    # zero's cost from x0 is the positive root of (4 mu - 3) P^2 - 4 P - 1 = 0: 4 + 3 sqrt(2) at mu = 7/8
    s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    row = cheapest_links(s, 4 + 3 * 2 ** 0.5, [2.0], "zero", gap=1e-7)["zero"]
    assert row["mu"][0] == pytest.approx(0.875, abs=1e-6)
    assert row["communication_cost"] == pytest.approx(1.75, abs=2e-6)
    assert row["cost"] <= (4 + 3 * 2 ** 0.5) * (1 + ALLOCATION_COST_RTOL)


def test_refusals_name_their_field():
    s = load_example("two_actuator")
    with pytest.raises(InputError, match="actuator"):
        cheapest_links(s, 8.0, None, "buffer:0")
    with pytest.raises(InputError, match="alpha"):
        cheapest_links(s, -1.0, None, "zero")
    with pytest.raises(InputError, match="margin"):
        stability_allocate(s, "stable", [1.0, 1.0], margin=0.5, actuator="hold")
    started = load_example("pendulum_bursty")
    started = started.with_channel(GilbertElliott(p=[0.02], r=[0.18], state=["bad"]))
    with pytest.raises(InputError, match="stationary channel"):
        cheapest_links(started, 80000.0, None, "zero")


def _gilbert_cost(system: System, strategy: str, rate: float) -> float:
    """The strategy's cost behind a Gilbert channel with burstiness 0.2 moved to mean rate ``rate``, by hand:
    p = (1 - rate)(1 - 0.2), r = rate (1 - 0.2)."""
    moved = system.with_channel(GilbertElliott(p=[(1.0 - rate) * 0.8], r=[rate * 0.8]))
    try:
        return actuator_dp(moved, strategy).initial
    except NumericalError:
        return np.inf


@pytest.mark.parametrize("strategy", ["zero", "hold", "buffer:2", "buffer:2:hold"])
def test_cheapest_mean_rate_behind_a_gilbert_channel_matches_a_brute_force_grid_along_its_family(strategy):
    system = System(A=[[1.5]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], x0=[1.0],
                    channel=GilbertElliott(p=[0.4], r=[0.4]))
    alpha = 20.0
    row = cheapest_links(system, alpha, None, strategy, gap=GAP)[strategy]
    assert row["verdict"] == "reachable"
    assert _gilbert_cost(system, strategy, row["mu"][0]) <= alpha
    axis = _axis(50)
    best = next((float(v) for v in axis if _gilbert_cost(system, strategy, float(v)) <= alpha), np.inf)
    assert row["lower_bound"] <= best
    assert row["communication_cost"] <= best / (1.0 - GAP)
    assert best <= row["communication_cost"] + float(axis[1] - axis[0])
    assert row["mu"][0] > 25 / 36              # above every strategy's critical mean rate (hand value)
