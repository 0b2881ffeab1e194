"""closedloop.actuator_region: which channels each actuator strategy can stabilise, with exact certificates.

References: the scalar plant by hand (every strategy's critical mu is 1 - 1/a^2: a loss run of length j from any
delivered state leaves a^j times a nonzero combination, and the law that zeroes x on delivery attains it), the
held input of an actuator that never delivers (``w+ = w``: radius 1), and for zero the Bernoulli region's own
membership (closedloop.region, another algorithm: the homogeneous Riccati eigenpair and its certificates).
"""

from __future__ import annotations

import numpy as np
import pytest

from packetloss_cvx import load_example
from packetloss_cvx.closedloop.actuator_design import design_modes
from packetloss_cvx.closedloop.actuator_region import (
    actuator_critical,
    actuator_membership,
    least_radius,
    strategy_inside_proved,
    strategy_outside_proved,
)
from packetloss_cvx.closedloop.critical import critical_mu
from packetloss_cvx.closedloop.region import membership
from packetloss_cvx.errors import InputError, NumericalError
from packetloss_cvx.model.system import System
from packetloss_cvx.results.region import Membership
from packetloss_cvx.tolerances import ACTUATOR_DP_RTOL, CRITICAL_MU_TOL

SCALAR = System(A=[[2.0]], B=[[1.0]], horizon=4, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])


@pytest.mark.parametrize("actuator", ["zero", "buffer:2", "buffer:3", "buffer:2:hold", "buffer:3:hold"])
def test_scalar_critical_mu_is_one_minus_one_over_a_squared_with_both_ends_certified(actuator):
    point = actuator_critical(SCALAR, actuator, tol=CRITICAL_MU_TOL)
    assert point.lower <= 0.75 <= point.t
    assert point.t - point.lower <= CRITICAL_MU_TOL
    assert point.inside.verdict == "stable"
    assert point.outside.verdict == "unstable"


def test_scalar_hold_is_stabilisable_just_above_the_hand_critical_mu_and_its_least_radius_is_a2_loss():
    point = actuator_critical(SCALAR, "hold", tol=CRITICAL_MU_TOL)
    assert point.inside.verdict == "stable"
    assert 0.75 <= point.t <= 0.75 + 1e-4              # proved stable above 3/4, and by the hand value not below
    for mu in (0.3, 0.5, 0.6):                        # away from the defective boundary: growth a^2 (1 - mu)
        growth = least_radius(design_modes([[2.0]], [[1.0]], [mu], "hold")).growth
        assert growth == pytest.approx(4 * (1 - mu), rel=ACTUATOR_DP_RTOL)
    assert actuator_membership(SCALAR, "hold", [0.6]).verdict == "unstable"
    assert actuator_membership(SCALAR, "hold", [0.8]).verdict == "stable"


def test_hold_behind_a_link_that_never_delivers_is_certified_unstable_by_its_held_input():
    system = load_example("two_actuator")
    found = actuator_membership(system, "hold", [0.9, 0.0])
    assert found.verdict == "unstable"
    expected = np.zeros((1, 4, 4))
    expected[0, 3, 3] = 1.0
    assert np.array_equal(found.certificate, expected)
    assert actuator_membership(system, "zero", [0.9, 0.0]).verdict == "stable"


@pytest.mark.parametrize("actuator", ["buffer:2:hold", "buffer:3:hold"])
def test_buffer_hold_behind_a_link_that_never_delivers_is_certified_unstable_by_the_input_it_holds(actuator):
    """Actuator 2 never delivers: from the start it holds its memory's last entry (0 at the start, the plan's
    last entry of any earlier packet) on every loss, so ``w+ = w`` whatever the law: e_w e_w' proves radius >= 1 (the
    memory of buffer:L:hold: L - 1 entries per actuator, the held one last, at 2 + 2 (L - 1) - 1)."""
    system = load_example("two_actuator")
    L = int(actuator.split(":")[1])
    found = actuator_membership(system, actuator, [0.9, 0.0])
    assert found.verdict == "unstable"
    held = 2 + 2 * (L - 1) - 1
    assert np.array_equal(np.flatnonzero(found.certificate[0]), [held * (2 + 2 * (L - 1)) + held])
    assert np.all(found.certificate[:, held, held] == 1.0)
    assert actuator_membership(system, f"buffer:{L}", [0.9, 0.0]).verdict == "stable"


@pytest.mark.parametrize("mu", [[0.05, 0.05], [0.07, 0.07], [0.3, 0.02], [0.08, 0.2]])
def test_zero_membership_agrees_with_the_bernoulli_region(mu):
    system = load_example("two_actuator")
    reference = membership(system, mu)
    assert reference.verdict in ("stable", "unstable")
    assert actuator_membership(system, "zero", mu).verdict == reference.verdict


def test_certificates_fail_just_beyond_what_they_prove():
    """The exact checks at the scalar boundary: zero's law k = a has radius a^2 (1 - mu), 1/2 at mu = 7/8; every
    law's radius is at least 1 at mu = 3/4 and not beyond."""
    modes = design_modes([[2.0]], [[1.0]], [0.875], "zero")
    K = np.full((1, 1, 1), 2.0)
    assert strategy_inside_proved(modes, K, np.ones((1, 1, 1)), 0.5 + 2.0 ** -50)
    assert not strategy_inside_proved(modes, K, np.ones((1, 1, 1)), 0.5)
    assert strategy_outside_proved(design_modes([[2.0]], [[1.0]], [0.75], "zero"), np.ones((1, 1, 1)))
    assert not strategy_outside_proved(design_modes([[2.0]], [[1.0]], [0.75 + 2.0 ** -40], "zero"),
                                       np.ones((1, 1, 1)))


def test_two_actuator_strategies_share_the_region_to_the_tolerance_along_the_diagonal():
    """Measured: zero and buffer:L share the boundary 0.0610 along mu1 = mu2 (hold's too, to 2e-6)."""
    system = load_example("two_actuator")
    zero = actuator_critical(system, "zero", [1.0, 1.0], tol=1e-4)
    buffer = actuator_critical(system, "buffer:2", [1.0, 1.0], tol=1e-4)
    assert zero.inside.verdict == buffer.inside.verdict == "stable"
    assert abs(zero.t - buffer.t) <= 1e-4
    assert zero.outside.verdict == "unstable"


@pytest.mark.parametrize("direction", [[1.0], [1.0, -0.5], [0.0, 0.0]])
def test_bad_direction_is_an_input_error(direction):
    with pytest.raises(InputError, match="direction"):
        actuator_critical(load_example("two_actuator"), "hold", direction)


def _hold_loop_radius(A: np.ndarray, B: np.ndarray, mu, K: np.ndarray) -> float:
    """Hold's mean-square radius under ``u = -K (x, w)`` by enumeration of the delivery patterns, written out
    independently: the applied input ``a = D u + (I - D) w``, ``x+ = A x + B a``, ``w+ = a``."""
    n, m = B.shape
    operator = np.zeros(((n + m) ** 2, (n + m) ** 2))
    for d in np.ndindex(*(2,) * m):
        D = np.diag(np.asarray(d, dtype=float))
        applied = -D @ K + np.hstack([np.zeros((m, n)), np.eye(m) - D])
        C = np.vstack([np.hstack([A, np.zeros((n, m))]) + B @ applied, applied])
        p = np.prod([mu[i] if d[i] else 1.0 - mu[i] for i in range(m)])
        operator += p * np.kron(C, C)
    return float(np.max(np.abs(np.linalg.eigvals(operator))))


def test_scalar_hold_critical_bracket_holds_the_hand_value_with_both_ends_certified():
    """The power iteration converges slowly at the defective boundary (its float crossing lay 3.4e-5 above 3/4,
    on the stable side); the policy iteration finishes it, and both ends are proved."""
    point = actuator_critical(SCALAR, "hold", tol=CRITICAL_MU_TOL)
    assert point.lower <= 0.75 <= point.t
    assert point.t - point.lower <= CRITICAL_MU_TOL
    assert point.inside.verdict == "stable"
    assert point.outside.verdict == "unstable"


@pytest.mark.parametrize("mu", [[0.02, 0.02], [0.06, 0.02], [0.04, 0.04], [0.06, 0.06]])
def test_two_actuator_hold_below_the_boundary_is_certified_unstable_by_a_tilted_direction(mu):
    """Hold's direction is rank-deficient (the held inputs): unrounded, tilted or not at c = 1, it does not check;
    tilted by the Stein solution at c halfway to lambda it does. Reference: no law found by Nelder-Mead from zero
    and from the zero strategy's region's direction has an enumerated radius below 1."""
    from scipy.optimize import minimize
    system = load_example("two_actuator")
    found = actuator_membership(system, "hold", mu)
    assert found.verdict == "unstable"
    assert found.certificate_margin >= 0.0
    best = min(minimize(lambda k: _hold_loop_radius(system.A, system.B, mu, k.reshape(2, 4)), start,
                        method="Nelder-Mead", options={"maxiter": 4000, "xatol": 1e-10, "fatol": 1e-12}).fun
               for start in (np.zeros(8), np.hstack([system.A, np.zeros((2, 2))]).ravel()))
    assert best >= 1.0


def test_two_actuator_hold_critical_lower_end_is_proved_near_the_float_crossing():
    """Measured: t = 0.0610313 proved stable; lower proved unstable 6.5e-5 below the float crossing under Haswell,
    1.0e-3 below under Prescott and SkylakeX (the tilt's exact check at the nearer points depends on the kernel's
    last bits); before, lower was undecided at 0.0611029, the power iteration's growth still 1.3e-6 high there after
    5000 steps. Reference: the inside gain's radius by enumeration is below 1 at t."""
    system = load_example("two_actuator")
    point = actuator_critical(system, "hold", [1.0, 1.0])
    assert point.inside.verdict == "stable"
    assert point.outside.verdict == "unstable"
    assert 0.0 < point.t - point.lower <= 2e-3
    assert _hold_loop_radius(system.A, system.B, point.t * np.ones(2), point.inside.gain[0]) < 1.0


def test_hold_laws_of_the_state_alone_have_a_stabilising_set_that_is_not_convex():
    """docs/mathematics.md's UDP-like hold: the laws u = -K x (the held input unobserved) on two_actuator at
    mu = (0.9, 0.9); two stabilising gains, their midpoint not (radius about 3.05), by the enumerated operator."""
    system = load_example("two_actuator")
    mu = [0.9, 0.9]
    first, second = np.array([[1.002, -0.114], [4.931, 0.418]]), np.array([[1.229, 2.27], [0.301, 0.633]])

    def radius(K):
        return _hold_loop_radius(system.A, system.B, mu, np.hstack([K, np.zeros((2, 2))]))

    assert radius(first) < 1.0
    assert radius(second) < 1.0
    assert radius(0.5 * (first + second)) == pytest.approx(3.05, abs=0.01)


def test_two_actuator_buffer_direction_lies_along_the_irrational_unstable_eigenvector_of_a():
    """docs/mathematics.md: at an undecided point of buffer:2 on two_actuator the least-radius direction is rank
    one, its plant part along A's left eigenvector for 1.02 + sqrt(0.00185) (by hand: A' q = lambda q gives
    q2 / q1 = (lambda - 1.03) / 0.35) in every mode where it weighs the plant."""
    system = load_example("two_actuator")
    modes = design_modes(system.A, system.B, [0.04, 0.04], "buffer:2")
    found = least_radius(modes)
    assert found.growth > 1.0
    assert actuator_membership(system, "buffer:2", [0.04, 0.04]).verdict == "undecided"
    lam = 1.02 + np.sqrt(0.00185)
    q = np.array([1.0, (lam - 1.03) / 0.35])
    for P in found.P:
        w, V = np.linalg.eigh(P)
        size = np.sort(np.abs(w))
        assert size[-2] <= 1e-9 * size[-1]                # rank one
        top = V[:2, -1] if abs(w[-1]) >= abs(w[0]) else V[:2, 0]
        assert abs(top[0] * q[1] - top[1] * q[0]) <= 1e-6 * np.linalg.norm(top) * np.linalg.norm(q)


#: a controllable single-input plant whose deadbeat law makes zero's map at mu = 1 nilpotent: the power iteration's
#: normalised iterates are rounding noise there (its growth read 1.64 before the greedy law's own radius was used)
DEADBEAT = System(A=[[1.2, 0.1], [0.0, 0.9]], B=[[1.0], [0.5]], horizon=3, state_weight=[1.0, 1.0],
                  input_weight=[1.0], mu=[0.7], x0=[1.0, 0.0])


def test_zero_at_full_delivery_is_proved_stable_by_the_deadbeat_law():
    found = actuator_membership(DEADBEAT, "zero", [1.0])
    assert found.verdict == "stable"      # proved: the law it found (radius 1.6e-7 under Haswell, 0.0225 Prescott)
    growth = least_radius(design_modes(DEADBEAT.A, DEADBEAT.B, [1.0], "zero")).growth
    assert growth < 0.5                   # the least radius is 0 (a deadbeat law); the old float growth read 1.64


def test_zero_critical_mu_on_the_deadbeat_plant_agrees_with_the_bernoulli_engine():
    reference = critical_mu(DEADBEAT, "dp", tol=CRITICAL_MU_TOL)       # closedloop.critical, another engine
    point = actuator_critical(DEADBEAT, "zero", tol=CRITICAL_MU_TOL)
    assert point.inside.verdict == "stable"
    assert point.outside.verdict == "unstable"
    assert point.lower <= reference.t
    assert reference.lower <= point.t


def test_an_undecided_ray_end_is_a_numerical_error_not_a_verdict(monkeypatch):
    """Floats say no law stabilises at the ray's end (an unreached unstable mode); without a certificate that is
    no verdict. The real membership proves it unstable (checked first), the planted one cannot."""
    import packetloss_cvx.closedloop.actuator_region as region

    def undecided(system, actuator, mu, **options):
        return Membership(np.asarray(mu, dtype=float), "undecided", None, float("nan"), None, float("nan"),
                          (("dp", "undecided"),), "planted: nothing checks")

    unreached = System(A=[[2.0, 0.0], [0.0, 0.5]], B=[[0.0], [1.0]], horizon=3, state_weight=[1.0, 1.0],
                       input_weight=[1.0], mu=[0.9], x0=[1.0, 1.0])
    proved = actuator_critical(unreached, "zero", tol=1e-3)
    assert proved.t == float("inf")
    assert proved.outside.verdict == "unstable"
    monkeypatch.setattr(region, "actuator_membership", undecided)
    with pytest.raises(NumericalError, match="ray's end .* undecided"):
        actuator_critical(unreached, "zero", tol=1e-3)
