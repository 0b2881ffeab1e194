"""Clarabel's linear solver stays pinned (``direct_solve_method``, tolerances.CLARABEL_LINEAR_SOLVER) when a caller
passes ``solver_options`` to `ConstrainedQP`: the caller's keys are merged over the pin, so a tolerance alone keeps
it and a caller who sets ``direct_solve_method`` keeps theirs. Read from the settings cvxpy hands to Clarabel
(``CLARABEL.parse_solver_opts``), not from our own kwargs.

Hand value: one step of x' = x + v u from x0 = 1, mu = 1/2, Q = R = 1, u >= -1/2: the TCP-like optimum u = -2/3 is
cut to -1/2, J = (3/4)^2 + mu R u^2 = 9/16 + 1/8.
"""

import clarabel
import cvxpy as cp
import numpy as np
import pytest
from cvxpy.reductions.solvers.conic_solvers.clarabel_conif import CLARABEL

from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.system import System
from packetloss_cvx.qp.constrained import ConstrainedQP
from packetloss_cvx.tolerances import CLARABEL_LINEAR_SOLVER


@pytest.fixture
def settings(monkeypatch):
    """The Clarabel settings of every solve, as cvxpy builds them from the options it was given."""
    seen = []
    parse = CLARABEL.parse_solver_opts

    def recording(verbose, opts, settings=None):
        built = parse(verbose, opts, settings)
        seen.append({"direct_solve_method": built.direct_solve_method, "tol_gap_abs": built.tol_gap_abs})
        return built

    monkeypatch.setattr(CLARABEL, "parse_solver_opts", staticmethod(recording))
    return seen


def solve(options):
    s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    return ConstrainedQP(s, "tcp", Constraints(u_min=[-0.5]), solver=cp.CLARABEL, solver_options=options).solve()


def test_the_pin_is_not_clarabels_own_default():
    assert clarabel.DefaultSettings().direct_solve_method != CLARABEL_LINEAR_SOLVER     # else the tests prove nothing


def test_a_tolerance_given_keeps_the_linear_solver_pin(settings):
    sol = solve({"tol_gap_abs": 1e-9})
    assert settings, "Clarabel was not called through cvxpy"
    assert all(s["direct_solve_method"] == CLARABEL_LINEAR_SOLVER for s in settings)
    assert all(s["tol_gap_abs"] == 1e-9 for s in settings)                 # the caller's own key arrives
    assert np.isclose(sol.inputs[0, 0], -0.5)
    assert np.isclose(sol.cost, 9 / 16 + 1 / 8)


@pytest.mark.parametrize("method", ["auto", "faer"])
def test_a_caller_who_sets_the_linear_solver_keeps_theirs(settings, method):
    sol = solve({"direct_solve_method": method, "tol_gap_abs": 1e-9})
    assert settings
    assert all(s["direct_solve_method"] == method for s in settings)
    assert np.isclose(sol.inputs[0, 0], -0.5)
