"""The QP twin on badly scaled systems: weights spanning ~1e12 make the scaled minimum ~1e-11, below
Clarabel's absolute gap tolerance; the QP is then rescaled by its first value and solved again
(tolerances.QP_RESCALE_BELOW). Reference: the closed form by the backward recursion (Theorem 1), an
independent algorithm; tolerances: the cross-check's own (tolerances.CROSS_CHECK_*), not widened.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

import packetloss_cvx as pl
import packetloss_cvx.qp.expected_cost as qp_module
from packetloss_cvx.errors import NumericalError
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.expected_cost import ExpectedCostQP
from packetloss_cvx.tolerances import CROSS_CHECK_COST_RTOL, CROSS_CHECK_INPUT_ATOL


def _spread_systems(seed: int, count: int, keep) -> dict[int, pl.System]:
    """Random stationary systems with input and state weights drawn log-uniformly in [1e-12, 1]."""
    rng = np.random.default_rng(seed)
    found = {}
    for k in range(count):
        s = random_system(rng, non_stationary=False)
        iw = 10.0 ** rng.uniform(-12, 0, s.m)
        sw = 10.0 ** rng.uniform(-12, 0, s.n)
        if k in keep:
            found[k] = pl.System(A=s.A, B=s.B, horizon=s.horizon, state_weight=sw, input_weight=iw,
                                 mu=s.mu_schedule[0], x0=s.x0)
    return found


#: seed 3, systems 266, 276, 288: on main the sparse form said 'optimal' 0.56 %, 2.7 % and 6.5 % high
CASE_KEYS = (266, 276, 288)
#: seed 11: more of the same family; on main these were beyond the tolerances (the sparse form's J up to
#: 9e-5 relative, inputs up to 4 %; system 67's condensed TCP inputs by 1.1e-6)
MORE_KEYS = (11, 64, 67, 107)


@functools.cache
def cases() -> dict[int, pl.System]:
    """The seed-3 systems, drawn when a test first needs them (not at collection: every xdist worker collects
    this module, one runs it; the 289 draws cost 0.07 s)."""
    return _spread_systems(3, 289, set(CASE_KEYS))


@functools.cache
def more() -> dict[int, pl.System]:
    """The seed-11 systems, drawn when a test first needs them."""
    return _spread_systems(11, 108, set(MORE_KEYS))


def _agree(sol: pl.Solution, ref: pl.Solution, system: pl.System) -> None:
    mu = system.mu_schedule
    rel = abs(sol.cost - ref.cost) / ref.cost
    assert rel <= CROSS_CHECK_COST_RTOL, (sol.cost, ref.cost, rel)
    diff = np.abs(mu * (sol.inputs - ref.inputs)).max()
    assert diff <= CROSS_CHECK_INPUT_ATOL * np.abs(mu * ref.inputs).max(), diff


@pytest.mark.parametrize("formulation", ["sparse", "condensed"])
@pytest.mark.parametrize("protocol", ["udp", "tcp"])
@pytest.mark.parametrize("k", CASE_KEYS)
def test_badly_scaled_cases_agree_with_the_recursion(k, protocol, formulation):
    system = cases()[k]
    ref = pl.closed_form(system, protocol, method="recursion")
    sol = ExpectedCostQP(system, protocol, formulation).solve(cross_check=False)
    assert sol.status == "optimal"
    _agree(sol, ref, system)
    # the gain K (n more solves at the unit states) against Theorem 1's, to the input tolerance
    mu0 = system.mu_schedule[0][:, None]
    assert np.abs(mu0 * (sol.gain - ref.gain)).max() <= CROSS_CHECK_INPUT_ATOL * np.abs(mu0 * ref.gain).max()


@pytest.mark.parametrize("formulation", ["sparse", "condensed"])
@pytest.mark.parametrize("k", MORE_KEYS)
def test_more_badly_scaled_systems(k, formulation):
    system = more()[k]
    for protocol in ("udp", "tcp"):
        ref = pl.closed_form(system, protocol, method="recursion")
        _agree(ExpectedCostQP(system, protocol, formulation).solve(cross_check=False, with_gain=False), ref, system)


def test_the_new_scale_is_kept_for_later_solves():
    system = cases()[288]
    qp = ExpectedCostQP(system, "udp", "sparse")
    qp.solve(cross_check=False, with_gain=False)
    assert qp.rescaled >= 1
    for mu, x0 in (([0.3, 0.9, 0.5, 0.7], None), (None, -3.0 * system.x0), ([0.95, 0.2, 0.6, 0.4], 1e-4 * system.x0)):
        changed = system if mu is None else system.with_mu(mu)
        changed = changed if x0 is None else changed.with_x0(x0)
        ref = pl.closed_form(changed, "udp", method="recursion")
        _agree(qp.solve(mu=mu, x0=x0, cross_check=False, with_gain=False), ref, changed)
    assert qp.solve(cross_check=True).cross_check is not None     # the default path's check still runs


def test_without_the_passes_a_tiny_minimum_raises(monkeypatch):
    monkeypatch.setattr(qp_module, "QP_RESCALE_PASSES", 0)
    with pytest.raises(NumericalError, match="closed form"):
        ExpectedCostQP(cases()[276], "udp", "sparse").solve(cross_check=False)


@pytest.mark.parametrize("formulation", ["sparse", "condensed"])
def test_an_exactly_zero_minimum_is_not_rescaled(formulation):
    """No state weight: the optimal plan is 0 and the variable part of J is exactly 0 (hand value)."""
    s = pl.System(A=[[1.2, 0.1], [0.0, 0.7]], B=[[1.0], [0.5]], horizon=4, state_weight=[0.0, 0.0],
                  input_weight=[1e-6], mu=[0.6], x0=[1.0, -2.0])
    qp = ExpectedCostQP(s, "udp", formulation)
    sol = qp.solve(cross_check=False, with_gain=False)
    assert qp.rescaled == 0
    assert np.abs(sol.inputs).max() <= 1e-12
    assert sol.cost == pytest.approx(pl.closed_form(s, "udp", method="recursion").cost, rel=CROSS_CHECK_COST_RTOL)


@pytest.mark.parametrize("formulation", ["sparse", "condensed"])
@pytest.mark.parametrize(("factor", "rescaled"), [(3.0, 0), (0.3, 1)])
def test_a_scaled_minimum_below_qp_rescale_below_is_solved_again_and_one_above_is_not(formulation, factor, rescaled):
    """One step, unit weights and x0 (the QP's own scale): min_u (a + u)^2 + u^2 = a^2 / 2 by hand, put at factor
    QP_RESCALE_BELOW. At 0.3 the QP is rescaled once, at 3 not; the minimum is a^2 / 2 either way."""
    from packetloss_cvx.tolerances import QP_RESCALE_BELOW

    a = np.sqrt(2 * factor * QP_RESCALE_BELOW)
    s = pl.System(A=[[a]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    qp = ExpectedCostQP(s, "tcp", formulation)
    sol = qp.solve(cross_check=False, with_gain=False)
    assert qp.rescaled == rescaled
    assert sol.cost == pytest.approx(a * a / 2, rel=CROSS_CHECK_COST_RTOL)


def _pendulum_scaled(weight_scale: float, x0_scale: float, mu: float = 0.9) -> pl.System:
    p = pl.load_example("pendulum")
    return pl.System(A=p.A, B=p.B, horizon=80, state_weight=np.array([5.0, 1, 1, 1]) * weight_scale,
                     input_weight=[2.0 * weight_scale], mu=[mu], x0=[x0_scale, 0, 0, 0])


@pytest.mark.parametrize(("weight_scale", "x0_scale", "mu", "protocol"), [
    (1e-15, 1e-7, 0.9, "tcp"),     # the QP dropped every state weight below 1e-14: 15x too low
    (1.0, 1e-10, 0.3, "udp"),      # the cost check was absolute below J* = 1: 3.5% too low
    (1.0, 1e-6, 0.9, "udp"),       # 2.1e-5 relative, exit 0
    (1e-8, 1.0, 0.9, "tcp"),       # refused: the QP's inputs were inexact at that scale
])
def test_qp_is_right_at_every_scale(weight_scale, x0_scale, mu, protocol):
    """Reference by scaling: J* is homogeneous of degree 1 in the weights and 2 in x0 (no noise)."""
    unit = pl.closed_form(_pendulum_scaled(1.0, 1.0, mu), protocol).cost
    expected = unit * weight_scale * x0_scale**2
    s = _pendulum_scaled(weight_scale, x0_scale, mu)
    qp = pl.solve_qp(s, protocol, with_gain=False)        # the default cross-check binds
    assert abs(qp.cost - expected) <= 1e-7 * expected
    assert abs(pl.closed_form(s, protocol).cost - expected) <= 1e-9 * expected


def test_cross_check_against_an_exact_zero(two_actuator):
    """No state weight: J* = 0 exactly; the QP's 1e-33 is rounding at the problem's scale."""
    s = pl.System(A=two_actuator.A, B=two_actuator.B, horizon=3, state_weight=[0.0, 0.0], input_weight=[1, 1],
                  mu=[0.5, 0.5], x0=[1.0, -1.0])
    qp = pl.solve_qp(s, "udp", with_gain=False)
    assert qp.cost < 1e-20
    assert pl.closed_form(s, "udp").cost == 0.0
