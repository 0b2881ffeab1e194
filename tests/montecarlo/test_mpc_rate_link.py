"""The loop's rate bound against the previous command (montecarlo/mpc.py through ``ConstrainedQP(..., u_prev=True)``).

Reference, not the code under test: the same loop whose programs link u_0 to the previous command through the
user's path (a Parameter of the test's own added with ``ConstrainedQP.add_constraints``, which the KKT check and the
polish skip), on the same seed."""

import cvxpy as cp
import numpy as np

from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo import mpc
from packetloss_cvx.qp.constrained import ConstrainedQP
from packetloss_cvx.tolerances import CONSTRAINED_AGREEMENT_RTOL


def _plant() -> System:
    return System(A=[[1.1, 0.2], [0.0, 0.8]], B=[[1.0, 0.0], [0.3, 1.0]], horizon=5, state_weight=[1.0, 2.0],
                  input_weight=[1.0, 0.5], x0=[1.0, -0.5], noise_cov=[[0.02, 0.0], [0.0, 0.01]], mu=[0.7, 0.6])


def _users_link(monkeypatch):
    """Swap the loop's programs for ones whose rate rows at t = 0 are the user's cvxpy constraints."""
    def compile_(self, constraints):
        qp = ConstrainedQP(self.twin, self.protocol, constraints)
        qp.previous = cp.Parameter(self.twin.m)
        qp.add_constraints([cp.abs(qp.U[0] - qp.previous) <= constraints.du_max])
        return qp

    def solve(self, program, mu, x, previous, belief=None):       # a Bernoulli plant: no belief
        program.previous.value = np.asarray(previous, dtype=float)
        return program.solve(mu=mu, x0=x)
    monkeypatch.setattr(mpc._Program, "_compile", compile_)
    monkeypatch.setattr(mpc._Program, "_solve", solve)


def test_the_loop_with_the_programs_own_link_is_the_loop_with_the_users_rows(monkeypatch):
    # the rate bound binds from rest, the expected-state limit makes the hard program infeasible on some steps (the
    # soft fallback runs), the chance row binds
    s = _plant()
    c = Constraints(u_min=[-1.0, -1.0], u_max=[1.0, 1.0], du_max=[0.15, 0.15], x_max=[1.02, 1e3],
                    chance=[([1.0, 0.0], 1.1, 0.2)])
    args = dict(samples=6, steps=8, seed=4, controllers=["certainty-equivalent", "expected-cost"], progress=False)
    own = mpc.simulate_mpc(s, c, **args)
    with monkeypatch.context() as patch:
        _users_link(patch)
        users = mpc.simulate_mpc(s, c, **args)
    fallbacks = 0
    for protocol in ("tcp", "udp"):
        for controller in ("certainty-equivalent", "expected-cost"):
            a, b = own.runs[protocol][controller], users.runs[protocol][controller]
            scale = float(np.abs(b.stage_cost_mean).max())
            assert np.abs(a.stage_cost_mean - b.stage_cost_mean).max() <= CONSTRAINED_AGREEMENT_RTOL * scale
            assert abs(a.mean_stage_cost - b.mean_stage_cost) <= CONSTRAINED_AGREEMENT_RTOL * abs(b.mean_stage_cost)
            assert [v.count for v in a.violations] == [v.count for v in b.violations]
            assert (a.infeasible.count, a.fallback_steps, a.failed_steps) == (b.infeasible.count, b.fallback_steps,
                                                                             b.failed_steps)
            fallbacks += a.fallback_steps
    assert fallbacks > 0                                        # the soft programs ran too
