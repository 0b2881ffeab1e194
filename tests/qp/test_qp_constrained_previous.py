"""The rate bound against the previous command (``ConstrainedQP(..., u_prev=True)``, qp/constrained.py): the rows
``|u_0 - u_prev| <= du_max`` as the program's own, covered by its KKT check, polish and compiled path.

References, none taken from the code under test: a scalar solved by hand (J from `expected_cost`, its derivative
by central differences, exact for a quadratic); the same rows written by the user through cvxpy
(``add_constraints`` with a Parameter of their own: the path the polish and the KKT check skip), solved by
``problem.solve``."""

import cvxpy as cp
import numpy as np
import pytest

from packetloss_cvx.errors import DimensionError, InputError
from packetloss_cvx.lq.costs import closed_form, expected_cost
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.model.system import System
from packetloss_cvx.qp.constrained import ConstrainedQP
from packetloss_cvx.tolerances import CONSTRAINED_AGREEMENT_RTOL, CONSTRAINED_KKT_RTOL


def _system(seed, n=2, m=2, horizon=5):
    return random_system(np.random.default_rng(seed), n=n, m=m, horizon=horizon, spectral_radius=0.9,
                         non_stationary=False, noise=True, time_varying=False, edge_mu=False)


def _users_rows(system, protocol, c, u_prev):
    """The reference: the same program with the rows of u_0 against u_prev added by the user, solved by cvxpy."""
    qp = ConstrainedQP(system, protocol, c)
    previous = cp.Parameter(system.m)
    qp.add_constraints([cp.abs(qp.U[0] - previous) <= c.du_max])
    qp.fast_path_refused = "the test's reference: cvxpy's own path"
    previous.value = np.asarray(u_prev, dtype=float)
    return qp.solve()


def test_a_scalar_rate_row_at_t0_binds_with_the_multiplier_by_hand():
    # x' = x + v u from 1, mu = 1/2, Q = R = 1, N = 1: the free optimum is u = -2/3; after u_prev = 1/2 with
    # du_max = 0.2, u lies in [0.3, 0.7] and the convex J puts it at 0.3, the "down" row u_prev - u <= du binding
    # with multiplier J'(0.3) (stationarity J' - lambda = 0).
    s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    qp = ConstrainedQP(s, "tcp", Constraints(du_max=[0.2]), u_prev=True)
    sol = qp.solve(u_prev=[0.5])
    assert sol.inputs[0, 0] == pytest.approx(0.3, abs=1e-12)
    assert sol.binding == ("du_max[0] at t=0 (down)",)
    assert sol.kkt_residual <= CONSTRAINED_KKT_RTOL
    assert sol.cost == pytest.approx(expected_cost(s, np.array([[0.3]]), "tcp"), rel=1e-12)
    h = 1e-3
    slope = (expected_cost(s, np.array([[0.3 + h]]), "tcp") - expected_cost(s, np.array([[0.3 - h]]), "tcp")) / (2 * h)
    report = qp.kkt(s, sol.inputs)                         # the solver's multipliers, in the cost's units
    lam = report["multipliers"][0]
    assert lam[0] == pytest.approx(0.0, abs=1e-6 * slope)               # "up" slack
    assert lam[1] == pytest.approx(slope, rel=CONSTRAINED_AGREEMENT_RTOL)
    # from rest (u_prev = 0, the default) the free optimum -2/3 is cut to -0.2, the same "down" row; from -1/2 the
    # optimum lies inside [-0.7, -0.3]: nothing binds
    rest = qp.solve()
    assert rest.inputs[0, 0] == pytest.approx(-0.2, abs=1e-12)
    assert rest.binding == ("du_max[0] at t=0 (down)",)
    inside = qp.solve(u_prev=[-0.5])
    assert inside.inputs[0, 0] == pytest.approx(-2 / 3, abs=1e-12)
    assert inside.binding == ()


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("formulation", ["condensed", "sparse"])
def test_the_rate_row_at_t0_meets_the_kkt_check_and_agrees_with_the_users_rows(protocol, seed, formulation):
    s = _system(seed)
    free = closed_form(s, protocol).inputs
    peak = np.abs(free).max(axis=0)
    c = Constraints(u_min=-0.8 * peak, u_max=0.8 * peak, du_max=0.3 * peak)
    qp = ConstrainedQP(s, protocol, c, formulation, u_prev=True)
    assert qp.problem.is_dpp()
    # the previous command on the far side of the free plan's first input: the row at t = 0 binds
    u_prev = -0.6 * np.sign(free[0]) * peak
    sol = qp.solve(u_prev=u_prev)
    assert qp.fast_path_refused == ""                                       # the compiled path served
    assert any(label.endswith("at t=0 (up)") or label.endswith("at t=0 (down)") for label in sol.binding)
    assert sol.kkt_residual <= CONSTRAINED_KKT_RTOL
    assert np.all(np.abs(sol.inputs[0] - u_prev) <= c.du_max * (1 + 1e-12))
    ref = _users_rows(s, protocol, c, u_prev)
    assert ref.kkt_residual is None                                          # the reference path skips the check
    scale = max(1.0, float(np.abs(ref.inputs).max()))
    assert np.abs(sol.inputs - ref.inputs).max() <= CONSTRAINED_AGREEMENT_RTOL * scale
    assert abs(sol.cost - ref.cost) <= CONSTRAINED_AGREEMENT_RTOL * abs(ref.cost)
    # a re-solve for another previous command on the same compiled program is a fresh object's answer
    other = 0.5 * u_prev
    again = qp.solve(u_prev=other)
    fresh = ConstrainedQP(s, protocol, c, formulation, u_prev=True).solve(u_prev=other)
    np.testing.assert_allclose(again.inputs, fresh.inputs, atol=1e-12)


def test_the_previous_command_is_checked_naming_the_field():
    s = _system(3)
    qp = ConstrainedQP(s, "tcp", Constraints(du_max=[0.1, 0.1]), u_prev=True)
    with pytest.raises(DimensionError, match="u_prev"):
        qp.solve(u_prev=[0.0])
    with pytest.raises(InputError, match="u_prev: expected finite"):
        qp.solve(u_prev=[0.0, np.inf])
    with pytest.raises(InputError, match="u_prev=True"):
        ConstrainedQP(s, "tcp", Constraints(du_max=[0.1, 0.1])).solve(u_prev=[0.0, 0.0])
    with pytest.raises(InputError, match="u_prev"):
        ConstrainedQP(s, "tcp", Constraints(du_max=[0.1, 0.1]), u_prev="yes")
