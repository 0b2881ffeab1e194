"""Never silently wrong: every default path returns the right number or raises a typed error.

Each case here was a wrong number returned without an error (issue "Never silently wrong").
References are independent of the path under test: the exact O(N) recursion where it passes
its own check, the Clarabel QP twin, a hand value, or the forward pass of the mean state.
"""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.io import system_from_dict
from packetloss_cvx.random_systems import random_system
from packetloss_cvx.recursion import recursion_cost


def _readme(N: int) -> pl.System:
    return pl.System(A=[[1.1, 0.2], [0, 0.9]], B=[[1], [0.5]], state_weight=[1, 1], input_weight=[0.5],
                     mu=[0.8], x0=[1, 0], horizon=N)


def _unstable(rho: float, N: int) -> pl.System:
    return random_system(np.random.default_rng(0), n=2, m=2, horizon=N, spectral_radius=rho, full_weights=False,
                         time_varying=False, non_stationary=False, noise=False, edge_mu=False)


def _pendulum(N: int, mu: float = 1.0) -> pl.System:
    data = pl.load_example("pendulum").with_mu([mu]).to_dict()
    data["cost"]["horizon"] = N
    return system_from_dict(data)


def _weighted(w: float) -> pl.System:
    data = pl.load_example("two_actuator").to_dict()
    data["cost"]["state_weight"] = [w, 1.0]
    return system_from_dict(data)


def test_default_method_is_auto_everywhere():
    import inspect

    for fn, name in ((pl.closed_form, "method"), (pl.expected_cost, "method"), (pl.solve_qp, "formulation")):
        assert inspect.signature(fn).parameters[name].default == "auto"


def test_readme_system_at_long_horizon_matches_the_qp():
    """Was 128.0 from the dense default; the QP twin and the recursion give 1.3044."""
    s = _readme(200)
    sol = pl.closed_form(s, "tcp")
    qp = pl.solve_qp(s, "tcp", "sparse", with_gain=False, cross_check=False)
    assert abs(sol.cost - qp.cost) <= 1e-7 * qp.cost
    assert 1.30 < sol.cost < 1.31


@pytest.mark.parametrize(("rho", "N"), [(3.0, 20), (1.5, 200)])
def test_dense_refuses_unstable_plants_up_front(rho, N):
    """Was -4096 (true 9.5587 class) and -6.1e56: refused before anything dense is built."""
    s = _unstable(rho, N)
    with pytest.raises(pl.NumericalError, match="condition estimate"):
        pl.closed_form(s, "tcp", method="dense")
    with pytest.raises(pl.NumericalError, match="use method='recursion'"):
        pl.expected_cost(s, np.zeros((N, 2)), "tcp", method="dense")
    sol = pl.closed_form(s, "tcp")               # auto: the right number
    qp = pl.solve_qp(s, "tcp", "sparse", with_gain=False, cross_check=False)
    assert abs(sol.cost - qp.cost) <= 1e-7 * max(1.0, qp.cost)


@pytest.mark.parametrize("N", [200, 300, 2000])
def test_pendulum_at_mu_one_long_horizons(N):
    """Dense was off by 3e-6 (N=200), 220% (N=300) and 5.9e90 (N=2000); auto is right."""
    s = _pendulum(N)
    with pytest.raises(pl.NumericalError):
        pl.closed_form(s, "tcp", method="dense")
    sol = pl.closed_form(s, "tcp")
    assert sol.method == "recursion"
    # independent: the forward pass of the plan (nonnegative terms) and the mean closed loop is stable
    assert np.isclose(recursion_cost(s, sol.inputs, "tcp"), sol.cost, rtol=1e-9)
    assert max(abs(sol.closed_loop_eigenvalues)) < 1.0
    if N <= 300:
        qp = pl.solve_qp(s, "tcp", "sparse", with_gain=False, cross_check=False)
        assert abs(qp.cost - sol.cost) <= 1e-7 * sol.cost


def test_expected_cost_of_the_optimal_plan_on_an_unstable_plant():
    """expected_cost(..., method='dense') returned 0.0 where the cost is about 21.6."""
    s = _unstable(3.0, 20)
    sol = pl.closed_form(s, "tcp")
    qp = pl.solve_qp(s, "tcp", "sparse", with_gain=False, cross_check=False)
    value = pl.expected_cost(s, sol.inputs, "tcp")
    assert abs(value - qp.cost) <= 1e-7 * qp.cost


def test_expected_cost_beyond_the_double_range_raises():
    s = pl.load_example("two_actuator")
    with pytest.raises(pl.NumericalError, match="double-precision range"):
        pl.expected_cost(s, np.full((10, 2), 1e200), "tcp")


@pytest.mark.parametrize("w", [1e12, 1e14, 1e16, 1e100])
def test_badly_scaled_weights_are_refused_naming_the_weights(w):
    """1e12 gave rel dJ 1.1e-3 at exit 0; 1e16 gave dense 32 / recursion 1.75; 1e100 a negative cost.
    The true cost is about 3.0522 (it only grows with the weight and is 3.052228 at 1e10)."""
    s = _weighted(w)
    for method in ("auto", "dense", "recursion"):
        with pytest.raises(pl.NumericalError, match="weights"):
            pl.closed_form(s, "tcp", method=method)


def test_moderate_weights_are_still_solved_and_agree_with_the_qp():
    s = _weighted(1e6)
    sol = pl.closed_form(s, "tcp")
    qp = pl.solve_qp(s, "tcp", with_gain=False, cross_check=False)
    assert abs(sol.cost - qp.cost) <= 1e-7 * sol.cost


def test_dense_memory_is_refused_up_front():
    s = _readme(1)
    data = s.to_dict()
    data["cost"]["horizon"] = 60000
    big = system_from_dict(data)
    with pytest.raises(pl.ResourceError, match="GiB"):
        pl.closed_form(big, "tcp", method="dense")
