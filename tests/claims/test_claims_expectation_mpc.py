"""expectation-mpc-feasibility (claims/expectation_mpc.py): Trodden & Li's phenomenon on the package's scalar
example. References: the certificate by enumerating the expected dynamics on a grid, the program's first input and
its infeasibility threshold by hand."""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx.claims import CLAIMS
from packetloss_cvx.claims.context import Context
from packetloss_cvx.claims.expectation_mpc import expectation_mpc, feasibility_case
from packetloss_cvx.errors import InfeasibleError
from packetloss_cvx.qp.constrained import ConstrainedQP


def test_the_box_is_invariant_under_the_expected_dynamics_on_a_grid():
    s, c = feasibility_case()
    a, mu = s.A[0, 0], s.mu[0]
    z = np.linspace(-1.0, 1.0, 2001)
    u = np.linspace(-3.0, 3.0, 6001)
    reach = np.abs(a * z[:, None] + mu * u[None, :]).min(axis=1)     # the best next expected state from each z
    assert reach.max() <= 1.0


def test_the_program_overshoots_on_a_delivery_and_is_infeasible_past_the_hand_threshold():
    s, c = feasibility_case()
    a, mu, R = s.A[0, 0], s.mu[0], s.input_weights[0, 0]
    qp = ConstrainedQP(s, "tcp", c)
    u = qp.solve(x0=[0.5]).inputs[0, 0]
    assert u == pytest.approx(-a * 0.5 / (mu + R), rel=1e-7)          # inside its bounds: -0.6 / 0.31
    assert abs(a * 0.5 + u) > 1.0                                      # one delivered packet leaves the box
    threshold = (1.0 + mu * 3.0) / a                                   # (x_max + mu u_max) / a = 1.583
    qp.solve(x0=[threshold - 1e-3])
    with pytest.raises(InfeasibleError):
        qp.solve(x0=[threshold + 1e-3])


def test_the_claim_holds_with_its_numbers_in_the_note():
    assert "expectation-mpc-feasibility" in CLAIMS
    r = expectation_mpc(Context(paper={}, random=[], seed=0))
    assert r.verdict == "holds"
    assert r.worst > 0
    assert r.outcomes == "+"
    assert "expected-cost MPC infeasible in" in r.note
    assert "certainty-equivalent MPC infeasible in 0 of" in r.note
