"""The buffered plan respects the input and rate bounds by construction (closedloop.actuator's buffer strategy fed
the constrained plan of qp/constrained.py): every entry of a plan lies within the input bounds, consecutive entries
within the rate bound and the first within it of ``u_prev``. A TCP-like controller knows from the acknowledgements
what the actuator applied last and plans from it, so along every delivery path an actuator that plays the received
plan's entries in order, and holds once it is exhausted, applies a sequence within both bounds; zero on a loss does
not (its step from U_j to 0).

Reference: every delivery path of six steps enumerated and the loop run along it, the actuator's applied sequence
built by hand from the plans and its bounds checked directly (no row of the program read back)."""

import itertools

import numpy as np
import pytest

from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.constrained import ConstrainedQP
from packetloss_cvx.tolerances import CONSTRAINED_ACTIVE_RTOL

BOUND, RATE, STEPS = 0.3, 0.1, 6


def _run(qp: ConstrainedQP, A: np.ndarray, b: np.ndarray, x0: np.ndarray, path: tuple[int, ...],
         strategy: str) -> list[float]:
    """The applied inputs along ``path`` (1: delivered): each step a plan from the state and the last applied input;
    "buffer:hold" plays the received plan's next entry on a loss and holds once it is exhausted, "zero" zero."""
    x, applied, plan, age = x0, [], None, 0
    for got in path:
        last = applied[-1] if applied else 0.0
        U = qp.solve(x0=x, u_prev=np.array([last])).inputs[:, 0]
        if got:
            plan, age = U, 0
        else:
            age += 1
        if strategy == "zero":
            a = float(U[0]) if got else 0.0
        elif plan is not None and age < len(plan):
            a = float(plan[age])
        else:
            a = last
        applied.append(a)
        x = A @ x + b * a
    return applied


def _within(applied: list[float]) -> tuple[bool, bool]:
    tol = CONSTRAINED_ACTIVE_RTOL
    return (all(abs(a) <= BOUND * (1 + tol) for a in applied),
            all(abs(b - a) <= RATE * (1 + tol) for a, b in itertools.pairwise([0.0, *applied])))


@pytest.mark.parametrize("seed", [0, 3])   # seeds where both bounds bind (the guard below)
def test_every_delivery_path_of_the_buffered_plan_stays_within_the_input_and_rate_bounds(seed):
    rng = np.random.default_rng(seed)
    system = random_system(rng, n=2, m=1, horizon=3, spectral_radius=1.3, non_stationary=False, noise=False,
                           time_varying=False, edge_mu=False)
    qp = ConstrainedQP(system, "tcp", Constraints(u_min=[-BOUND], u_max=[BOUND], du_max=[RATE]), u_prev=True)
    x0 = system.x0 * 20.0
    binds = zero_breaks = False
    for path in itertools.product((0, 1), repeat=STEPS):
        buffered = _run(qp, system.A, system.B[:, 0], x0, path, "buffer:hold")
        assert _within(buffered) == (True, True), (path, buffered)
        steps = [abs(b - a) for a, b in itertools.pairwise([0.0, *buffered])]
        binds |= max(abs(a) for a in buffered) >= BOUND * (1 - 1e-6) and max(steps) >= RATE * (1 - 1e-6)
        zero_breaks |= not all(_within(_run(qp, system.A, system.B[:, 0], x0, path, "zero")))
    assert binds                   # both bounds bind on some path: not a vacuous check
    assert zero_breaks             # zero on a loss leaves the rate bound on some path
