"""The stabilisable set of a plant python-control users meet: two masses, a coupling spring and a destabilising
wall spring (one unstable mode and an undamped oscillator, eigenvalues of A on the unit circle), a force on each,
zero-order hold at 0.1 s. Its homogeneous Riccati eigenvector is numerically rank one beyond the boundary, so P's own
float bound is 0 and only the tilted certificates prove "unstable"; the Stein equation behind the tilts has no
solution at c = 1 (the oscillator), so they must aim between 1 and lambda."""

import numpy as np
import pytest
from scipy.linalg import expm

from packetloss_cvx import System
from packetloss_cvx.closedloop import critical_mu
from packetloss_cvx.closedloop.certificates import outside_proved
from packetloss_cvx.closedloop.region import homogeneous_riccati, membership


def spring() -> System:
    """The tutorial's plant (docs/tutorials/own-plant.md), discretised by the block exponential (scipy), which is
    python-control's zero-order hold."""
    k0, k = -3.0, 1.0
    Ac = np.array([[0, 1, 0, 0], [-(k0 + k), 0, k, 0], [0, 0, 0, 1], [k, 0, -k, 0]], float)
    Bc = np.array([[0, 0], [1, 0], [0, 0], [0, 1]], float)
    block = expm(np.block([[Ac, Bc], [np.zeros((2, 6))]]) * 0.1)
    return System(A=block[:4, :4], B=block[:4, 4:], horizon=40, state_weight=[1, 1, 1, 1], input_weight=[1, 1],
                  mu=[0.9, 0.9], x0=[1, 0, 0, 0])


@pytest.mark.parametrize("nu", [0.149, 0.1497, 0.1503])
def test_beyond_the_spring_boundary_no_law_stabilises_proved_exactly(nu):
    """Between 0.149 and the boundary (float lambda 1.0033 .. 1.0006) the verdict is "unstable" with a certificate
    the exact check accepts at the margin it reports (was "undecided": every form failed)."""
    s = spring()
    mu = np.array([nu, nu])
    lam = homogeneous_riccati(s.A, s.B, mu)[0]
    found = membership(s, mu)
    assert lam > 1.0
    assert found.verdict == "unstable"
    assert 0.0 < found.certificate_margin < lam - 1.0
    assert outside_proved(s.A, s.B, mu, found.certificate, 1.0 + found.certificate_margin)


def test_spring_critical_mu_is_bracketed_by_proofs_around_the_float_crossing():
    """critical_mu(spring, "dp") returns a bracket whose ends are proved (stable above, no law below), which holds
    the float crossing lambda(mu) = 1 (bisected here on the homogeneous eigenvalue alone) and lies above the
    unstable mode's own necessary bound (a^2 - 1) / (a^2 + 1), a = e^(0.1 sqrt 2) (two independent channels on one
    scalar mode: min_k E(a - sum g_i b_i k_i)^2 = a^2 (1 - mu) / (1 + mu)). Where the certificates cannot narrow
    the bracket to tol, the note says so (was a NumericalError)."""
    s = spring()
    point = critical_mu(s, "dp")
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if homogeneous_riccati(s.A, s.B, np.array([mid, mid]))[0] > 1.0 else (lo, mid)
    a2 = np.exp(0.2 * np.sqrt(2.0))
    assert point.inside.verdict == "stable"
    assert point.outside.verdict == "unstable"
    assert point.lower <= hi and lo <= point.t
    assert (a2 - 1) / (a2 + 1) < point.lower
    assert point.t - point.lower < 1e-5
    assert (point.t - point.lower <= 1e-6) == (point.note == "")
