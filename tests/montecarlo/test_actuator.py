"""The sampled loop of ``u = -K x`` under each actuator strategy (montecarlo/actuator.py) against the mode engine's
exact expectation (closedloop.actuator.actuator_costs, not the code under test)."""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx.closedloop.actuator import actuator_costs
from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo.actuator import sample_actuator_loop, simulate_actuator
from packetloss_cvx.tolerances import SAMPLED_Z_MAX


@pytest.mark.parametrize("actuator", ["zero", "hold", "buffer:2", "buffer:2:hold"])
def test_the_sampled_loop_is_the_exact_cost_within_its_interval(actuator):
    # mu = 0.4: plans run out often, so buffer:2 and buffer:2:hold differ (exact 1.64 against 2.05 per step)
    s = System(A=[[1.1]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.4], x0=[2.0],
               noise_cov=[[0.1]])
    # hold and buffer:2:hold have growing fourth moments (rho_4 1.78, 1.14), so simulate_actuator gives them no
    # error bar; over 15 steps the run cost's variance is still finite, and the raw sample's standard error is used
    per_run = sample_actuator_loop(s, [[0.7]], 15, actuator, 20000, seed=1).mean(axis=1)
    mean, stderr = per_run.mean(), per_run.std(ddof=1) / np.sqrt(per_run.size)
    row = simulate_actuator(s, [[0.7]], 15, actuator, 20000, seed=1)
    exact = float(actuator_costs(s, [[0.7]], 15, actuator)[0].mean())
    assert row["mean_stage_cost"] == mean
    assert row["exact_stage_cost"] == exact
    assert abs(mean - exact) <= SAMPLED_Z_MAX * stderr
    assert stderr < 0.02 * exact



def _hold_rho4(a: float, k: float, mu: float) -> float:
    """rho(L_4) of the scalar hold loop written out by hand: z = (x, w) with w the last applied input; delivered
    x+ = (a - k) x, w+ = -k x; lost x+ = a x + w, w+ = w (B = 1)."""
    delivered, lost = np.array([[a - k, 0.0], [-k, 0.0]]), np.array([[a, 1.0], [0.0, 1.0]])

    def fourth(F):
        return np.kron(np.kron(F, F), np.kron(F, F))

    return float(np.abs(np.linalg.eigvals(mu * fourth(delivered) + (1 - mu) * fourth(lost))).max())


@pytest.mark.parametrize(("a", "k", "mu", "bar"), [(1.2, 1.0, 0.8, False), (1.3, 1.0, 0.9, True)])
def test_a_hold_loop_has_an_error_bar_only_when_its_fourth_moments_decay(a, k, mu, bar):
    # both loops are mean-square stable (radius 0.743, 0.471), but the first one's fourth moments grow
    s = System(A=[[a]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])
    row = simulate_actuator(s, [[k]], 20, "hold", 500, seed=2)
    rho4 = _hold_rho4(a, k, mu)
    assert row["stable"]
    assert (rho4 < 1) == bar
    if bar:
        assert row["stderr"] > 0
        assert np.isfinite(row["z"])
        assert "stderr_reason" not in row
    else:
        assert row["stderr"] is None
        assert row["z"] is None
        assert f"rho_4 = {rho4:.4g} >= 1" in row["stderr_reason"]


def test_a_loop_that_is_not_mean_square_stable_has_no_error_bar_and_no_z():
    # x+ = 3 x: every loss lets it grow; hold with mu = 0.1 is not mean-square stable (rho_4 >= rho_2^2 >= 1)
    s = System(A=[[3.0]], B=[[1.0]], horizon=200, state_weight=[1.0], input_weight=[1.0], mu=[0.1], x0=[1.0])
    for actuator in ("zero", "hold"):
        row = simulate_actuator(s, [[26.7]], 50, actuator, 200, seed=0)
        assert not row["stable"]
        assert row["stderr"] is None
        assert row["z"] is None
        assert row["stderr_reason"].startswith("no error bar: the fourth moments grow")
