"""What one lossy input can promise (docs/mathematics.md §7): at k = 1 the chance row
``a'A x0 + mu h + kappa sqrt(mu (1 - mu) h^2 + s^2) <= b`` has a plan for every x0 when mu > 1 - eps, and below
only when ``a'A x0 + s sqrt(kappa^2 - mu / (1 - mu)) <= b`` (nothing won back without noise). Reference: that
threshold by hand, and scipy's bounded scalar minimiser of the row over h; the package's program decides
feasibility on either side of it."""

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from packetloss_cvx.errors import InfeasibleError, SolverError
from packetloss_cvx.model.constraints import Constraints, cantelli_factor
from packetloss_cvx.model.system import System

EPS, B_ROW = 0.1, 1.0


def _program_has_a_plan(mu: float, noise: float, x0: float) -> bool:
    """x' = x + v u + w, N = 1, the row P(x_1 <= 1) >= 0.9, a wide input box: does the hard program have a plan?"""
    from packetloss_cvx.qp.constrained import solve_constrained

    s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[x0],
               noise_cov=[[noise]])
    c = Constraints(u_min=[-100.0], u_max=[100.0], chance=[([1.0], B_ROW, EPS)])
    try:
        solve_constrained(s, "tcp", c)
    except InfeasibleError:
        return False
    except SolverError as err:          # a chance row: the solver's "infeasible", its certificate undecided
        if err.status != "infeasible":
            raise
        return False
    return True


@pytest.mark.parametrize(("mu", "noise"), [(0.4, 0.01), (0.8, 0.04), (0.6, 0.0)])
def test_below_one_minus_eps_the_input_wins_back_only_part_of_the_noise_margin(mu, noise):
    kappa, s = cantelli_factor(EPS), np.sqrt(noise)
    least = s * np.sqrt(kappa ** 2 - mu / (1 - mu))                      # the row's least value over h, by hand
    row = minimize_scalar(lambda h: mu * h + kappa * np.sqrt(mu * (1 - mu) * h * h + noise), bounds=(-50, 50),
                          method="bounded", options={"xatol": 1e-12})
    assert row.fun == pytest.approx(least, abs=1e-9)
    threshold = B_ROW - least                                            # x0 above it: no plan
    assert _program_has_a_plan(mu, noise, threshold - 1e-3)
    assert not _program_has_a_plan(mu, noise, threshold + 1e-3)


def test_above_one_minus_eps_an_input_brings_any_state_back():
    for x0 in (1.5, 5.0):
        assert _program_has_a_plan(0.95, 0.01, x0)
