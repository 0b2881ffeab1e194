"""The QP twin's memory is linear in the horizon (no Parameter multiplies a Variable), and its
re-solves through Parameters, pinned channels and schedules agree with the closed form."""

import tracemalloc

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.expected_cost import qp_memory_estimate
from packetloss_cvx.tolerances import CROSS_CHECK_COST_RTOL, QP_PIN_MU


def _system(N: int) -> pl.System:
    return random_system(np.random.default_rng(2026), n=3, m=2, horizon=N, spectral_radius=0.95, full_weights=False,
                         time_varying=False, non_stationary=False, noise=False, edge_mu=False)


def _peak(system: pl.System) -> int:
    tracemalloc.start()
    tracemalloc.reset_peak()
    pl.solve_qp(system, "udp", "sparse", with_gain=False, cross_check=False)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak


def test_sparse_qp_memory_is_linear_in_the_horizon_and_within_its_estimate():
    """With a Parameter per entry, cvxpy kept 8 (N m)^2 bytes: 4x the horizon cost 16x the memory."""
    _peak(_system(20))                                     # imports and caches outside the measurement
    small, large = _system(300), _system(1200)
    a, b = _peak(small), _peak(large)
    assert b < 6 * a                                       # linear (4x) with slack; quadratic would be 16x
    assert b < qp_memory_estimate(large, "sparse")
    assert a < qp_memory_estimate(small, "sparse")


@pytest.mark.parametrize("formulation", ["condensed", "sparse"])
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_re_solves_across_pinned_channels_and_schedules_agree_with_the_closed_form(formulation, protocol):
    s = random_system(np.random.default_rng(11), n=3, m=3, horizon=6, spectral_radius=0.9, non_stationary=False)
    qp = pl.ExpectedCostQP(s, protocol, formulation)
    schedule = np.random.default_rng(12).uniform(0.0, 1.0, (6, 3))
    schedule[2, 1] = 0.0
    for mu in ([0.5, 0.2, 0.9], [0.0, 0.2, 1.0], [0.0, 0.0, 0.0], schedule, [0.5, 0.2, 0.9], [1e-40, 0.3, 0.3]):
        got = qp.solve(mu=mu, with_gain=True, cross_check=False)
        ref = pl.closed_form(s.with_mu(mu), protocol)
        assert abs(got.cost - ref.cost) <= CROSS_CHECK_COST_RTOL * ref.cost
        mean = s.with_mu(mu).mu_schedule
        assert np.allclose(mean * got.inputs, mean * ref.inputs, rtol=1e-5, atol=1e-6)
        live = mean[0] > QP_PIN_MU                         # a pinned channel's input is any value (reported 0)
        assert np.allclose(got.gain[live], ref.gain[live], rtol=1e-5, atol=1e-6)


def test_a_qp_beyond_the_solve_budget_is_refused_before_cvxpy_sees_it():
    """The QP's horizon is priced (budgets.qp_work) before cvxpy compiles anything: 2e6 steps of a scalar plant are
    refused at once under ``horizon`` (by hand: 2e6 (28 + 1.1 + 1.5) = 6.12e7 units of 1e-6 s, over the 6e7 budget),
    where compiling and solving took minutes and gigabytes."""
    import time

    s = pl.System(A=[[0.9]], B=[[1.0]], horizon=2 * 10 ** 6, state_weight=[1.0], input_weight=[1.0], mu=[0.5],
                  x0=[1.0])
    start = time.perf_counter()
    with pytest.raises(pl.ResourceError, match="PACKETLOSS_CVX_BUDGET_SOLVE_WORK=6.12e\\+07") as info:
        pl.solve_qp(s, "udp")
    assert time.perf_counter() - start < 5
    assert info.value.field == "horizon"
    assert isinstance(info.value, ValueError)         # a BudgetError: the caller's size, an InputError too


def test_qp_memory_grows_with_n_and_is_refused_in_advance(monkeypatch):
    """The estimate counts the state terms (~250 N n^2 bytes measured): n = 3000 over 5 steps needs ~11 GiB,
    and a 300-state system is refused against a budget it would exceed."""
    from packetloss_cvx.qp.expected_cost import qp_memory_estimate

    def system(n: int) -> pl.System:
        return pl.System(A=np.eye(n) * 0.5, B=np.ones((n, 1)), horizon=5, state_weight=np.ones(n),
                         input_weight=[1.0], mu=[0.5], x0=np.ones(n))

    small = system(300)
    assert qp_memory_estimate(small, "sparse") > 8e7
    assert qp_memory_estimate(system(600), "sparse") - 1e7 > 3.9 * (qp_memory_estimate(small, "sparse") - 1e7)
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_MEMORY_BYTES", "5e7")
    with pytest.raises(pl.ResourceError, match="GiB"):
        pl.ExpectedCostQP(small, "tcp", "sparse")
