"""The QP twin's two backends behind one interface: ``ExpectedCostQP(system, protocol, formulation)``
builds the condensed or the sparse backend; both answer as the closed form (the recursion, an
independent algorithm) on stationary channels, schedules and pinned (never-delivering) channels."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.expected_cost import (
    AUTO_CONDENSED_MAX,
    CondensedBackend,
    CondensedExpectedCostQP,
    ExpectedCostQP,
    SparseBackend,
    SparseExpectedCostQP,
    choose_backend,
    qp_memory_estimate,
)
from packetloss_cvx.tolerances import CROSS_CHECK_COST_RTOL, CROSS_CHECK_INPUT_ATOL
from tests.references import unstable_system as _unstable


def _system(horizon, m=2, seed=3):
    return random_system(np.random.default_rng(seed), n=2, m=m, horizon=horizon, non_stationary=False)


@pytest.mark.parametrize(("horizon", "backend"), [(AUTO_CONDENSED_MAX // 2, CondensedBackend),
                                                  (AUTO_CONDENSED_MAX // 2 + 1, SparseBackend)])
def test_auto_picks_the_condensed_backend_up_to_its_crossover(horizon, backend):
    s = _system(horizon)                                   # N m = 60 (condensed) or 62 (sparse)
    qp = ExpectedCostQP(s, "udp")
    assert type(qp) is ExpectedCostQP                      # constructed as written: the backend is a part
    assert type(qp.backend) is backend
    assert qp.formulation == backend.formulation
    assert choose_backend(s, "auto") is backend
    assert type(ExpectedCostQP(s, "udp", "sparse").backend) is SparseBackend
    assert type(ExpectedCostQP(s, "udp", "condensed").backend) is CondensedBackend
    fixed = SparseExpectedCostQP(s, "udp"), CondensedExpectedCostQP(s, "udp")
    assert [type(qp.backend) for qp in fixed] == [SparseBackend, CondensedBackend]
    assert all(isinstance(qp, ExpectedCostQP) for qp in fixed)


def test_a_bad_formulation_is_bad_input():
    s = _system(3)
    with pytest.raises(pl.InputError, match="formulation: expected 'condensed', 'sparse' or 'auto', found 'dense'"):
        ExpectedCostQP(s, "udp", "dense")
    with pytest.raises(ValueError, match="backend is 'sparse', found 'condensed'"):
        SparseExpectedCostQP(s, "udp", "condensed")


@pytest.mark.parametrize("formulation", ["condensed", "sparse"])
def test_each_backend_states_its_memory(formulation):
    s = _system(50)
    assert choose_backend(s, formulation).memory_estimate(s) == qp_memory_estimate(s, formulation)
    assert qp_memory_estimate(s, "condensed") - qp_memory_estimate(s, "sparse") == 150.0 * (50 * 2) * (50 * 2)


def _agree(sol, ref, system):
    scale = max(float(np.abs(system.mu_schedule * ref.inputs).max(initial=0.0)), 1e-12)
    assert np.abs(system.mu_schedule * (sol.inputs - ref.inputs)).max() <= CROSS_CHECK_INPUT_ATOL * scale
    assert sol.cost == pytest.approx(ref.cost, rel=CROSS_CHECK_COST_RTOL)


@pytest.mark.parametrize("formulation", ["condensed", "sparse"])
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_both_backends_answer_as_the_recursion(formulation, protocol):
    s = _system(6, m=3)
    qp = ExpectedCostQP(s, protocol, formulation)
    cases = [s, s.with_mu([0.0, 0.7, 0.4]),                                    # a pinned channel
             s.with_mu(np.random.default_rng(1).uniform(0.2, 1.0, (6, 3))),   # a schedule
             s.with_mu([0.0, 0.0, 0.0])]                                       # nothing delivered
    for case in cases:
        sol = qp.solve(mu=case.mu_schedule, cross_check=False)
        assert sol.method == f"qp-{formulation}"
        ref = pl.closed_form(case, protocol, method="recursion")
        _agree(sol, ref, case)
        delivered = case.mu_schedule[0][:, None]       # a pinned channel's input is reported as 0, as in U
        assert np.allclose(delivered * sol.gain, delivered * ref.gain, rtol=0, atol=1e-6 * np.abs(ref.gain).max())


def test_nothing_delivered_costs_the_open_loop_exactly():
    """mu = 0: no input reaches the plant; J is the open-loop cost, a hand value for x' = 2x, N = 2."""
    s = pl.System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.0], x0=[1.0],
                  initial_weight=[[1.0]])
    for formulation in ("condensed", "sparse"):
        sol = ExpectedCostQP(s, "udp", formulation).solve(cross_check=False)
        assert sol.cost == pytest.approx(1.0 + 4.0 + 16.0, rel=1e-14)      # x0'Q x0 + x1^2 + x2^2
        assert not sol.inputs.any()



@pytest.mark.parametrize("formulation", ["sparse", "condensed"])
@pytest.mark.parametrize(("factor", "pinned"), [(3.0, False), (0.3, True)])
def test_a_channel_is_pinned_at_or_below_qp_pin_mu_and_solved_above(two_actuator, formulation, factor, pinned):
    """A channel of delivery probability factor QP_PIN_MU: at 0.3 its mean input is pinned to zero (input reported
    0), at 3 it is a variable whose input agrees with the closed form's (Clarabel resolves it there: 4e-12 measured
    down to 1e-30); the cost agrees with the closed form either way (pinning changes it by mu sum psi u^2)."""
    from packetloss_cvx.tolerances import QP_PIN_MU

    s = two_actuator.with_mu([factor * QP_PIN_MU, 0.5])
    ref = pl.closed_form(s, "udp", method="recursion")
    sol = pl.solve_qp(s, "udp", formulation, with_gain=False, cross_check=False)
    assert sol.cost == pytest.approx(ref.cost, rel=CROSS_CHECK_COST_RTOL)
    if pinned:
        assert not np.any(sol.inputs[:, 0])
    else:
        np.testing.assert_allclose(sol.inputs[:, 0], ref.inputs[:, 0], rtol=1e-6)


@pytest.mark.parametrize(("rho", "N"), [(1.5, 60), (3.0, 20), (1.01, 2000), (10.0, 200)])
def test_udp_qp_on_unstable_plants_raises_numerical_error_never_infeasible(rho, N):
    """Statuses 'infeasible' / 'optimal_inaccurate' / a cvxpy ValueError on an unconstrained QP."""
    s = _unstable(rho, N)
    with pytest.raises(pl.NumericalError, match="unconstrained|double-precision"):
        pl.solve_qp(s, "udp", "sparse" if rho == 10.0 else "auto", with_gain=False, cross_check=False)


def test_an_almost_dead_channel_does_not_fail_the_cross_check():
    """mu = 1e-300: that input is (almost) free, so any value is (almost) optimal; compared through Vbar U."""
    s = pl.load_example("two_actuator").with_mu([1e-300, 0.5])
    for protocol in ("tcp", "udp"):
        qp = pl.solve_qp(s, protocol, with_gain=False)
        dead = pl.closed_form(pl.load_example("two_actuator").with_mu([0.0, 0.5]), protocol).cost
        assert abs(qp.cost - dead) <= 1e-9 * dead
