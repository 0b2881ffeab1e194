"""The one-point dense path (pointwise.PointEvaluator): its two checks, the solve's residual and the self-check
against the forward cost of its own plan, each refusing (None: the caller takes the checked batch path) a
disagreement of 3 times its tolerance and keeping one of 0.3 times. Its values, checked and unchecked, against the
closed form: tests/lq/test_evaluator.py (through CostEvaluator.cost and line)."""

import numpy as np
import pytest

import packetloss_cvx as pl
import packetloss_cvx.lq.pointwise as pointwise_module
from packetloss_cvx.lq.pointwise import PointEvaluator
from packetloss_cvx.lq.prediction import prediction
from packetloss_cvx.lq.recursion import udp_variance_weights
from packetloss_cvx.tolerances import DENSE_RESIDUAL_RTOL, SELF_CHECK_RTOL

MU = np.array([0.9, 0.5])


def _point(system: pl.System, protocol: str = "udp") -> PointEvaluator:
    return PointEvaluator(system, protocol, prediction(system), udp_variance_weights(system))


def _schedule(system: pl.System, mu: np.ndarray) -> np.ndarray:
    return np.tile(mu, (system.horizon, 1))


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_self_check_refuses_3_and_keeps_0_3_times_self_check_rtol(two_actuator, monkeypatch, factor, kept):
    """The referee (recursion.forward_cost) moved by factor SELF_CHECK_RTOL relative: None at 3, the cost at 0.3."""
    point = _point(two_actuator)
    exact = point.cost(_schedule(two_actuator, MU))
    real = pointwise_module.forward_cost
    monkeypatch.setattr(pointwise_module, "forward_cost",
                        lambda *a, **k: real(*a, **k) * (1 + factor * SELF_CHECK_RTOL))
    got = point.cost(_schedule(two_actuator, MU))
    assert (got == exact) if kept else got is None
    assert exact == pytest.approx(pl.closed_form(two_actuator.with_mu(MU), "udp").cost, rel=1e-12)


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_solve_residual_refuses_3_and_keeps_0_3_times_dense_residual_rtol(two_actuator, monkeypatch, factor, kept):
    """LAPACK's gesv returned a solution w whose residual ||G w - g|| is factor DENSE_RESIDUAL_RTOL (||G||_F ||w||
    + ||g||), along a direction that leaves the cost C - g'Vbar w unchanged to first order (so the self-check has
    nothing to see): None at 3, the cost at 0.3."""
    point = _point(two_actuator)
    schedule = _schedule(two_actuator, MU)
    exact = point.cost(schedule)
    keep = schedule.ravel() * (prediction(two_actuator).Omega_gp @ two_actuator.x0)    # Vbar g
    real = pointwise_module._gesv

    def gesv(G, g, overwrite_a=False):
        G0 = np.array(G, copy=True)
        lu, piv, w, info = real(G, g, overwrite_a=overwrite_a)
        y = np.linalg.solve(G0.T, keep)          # keep' G^{-1} r = y' r: r orthogonal to y moves no cost
        r = np.zeros_like(w)
        r[0], r[1] = y[1], -y[0]
        scale = np.linalg.norm(G0) * np.linalg.norm(w) + np.linalg.norm(g)
        r *= factor * DENSE_RESIDUAL_RTOL * scale / np.linalg.norm(r)
        return lu, piv, w + np.linalg.solve(G0, r), info

    monkeypatch.setattr(pointwise_module, "_gesv", gesv)
    got = point.cost(schedule)
    if kept:
        assert got == pytest.approx(exact, rel=1e-13)
    else:
        assert got is None
