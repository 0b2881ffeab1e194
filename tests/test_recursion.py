"""The O(N) recursion against the dense closed form, and long horizons."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import packetloss_cvx as pl
from packetloss_cvx.random_systems import random_system

PROTOCOLS = ("tcp", "udp")


def _agree(system, protocol, rtol=1e-9):
    dense = pl.closed_form(system, protocol, method="dense")
    rec = pl.closed_form(system, protocol, method="recursion")
    scale_u = max(1.0, np.abs(dense.inputs).max())
    scale_k = max(1.0, np.abs(dense.gain).max())
    assert abs(rec.cost - dense.cost) <= rtol * abs(dense.cost)
    assert np.abs(rec.inputs - dense.inputs).max() <= rtol * scale_u
    assert np.abs(rec.gain - dense.gain).max() <= rtol * scale_k
    assert rec.method == "recursion"
    assert dense.method == "dense"


@given(seed=st.integers(0, 2**32 - 1), protocol=st.sampled_from(PROTOCOLS))
@settings(max_examples=150, deadline=None)
def test_recursion_equals_dense_on_random_systems(seed, protocol):
    system = random_system(np.random.default_rng(seed))
    _agree(system, protocol)


@pytest.mark.parametrize("horizon", [30, 60])
@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_recursion_equals_dense_longer_horizons(horizon, protocol):
    rng = np.random.default_rng(horizon)
    system = random_system(rng, n=4, m=2, horizon=horizon, spectral_radius=0.98, non_stationary=True,
                           noise=True, time_varying=True)
    _agree(system, protocol)


@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_recursion_on_the_examples(pendulum, two_actuator, protocol):
    _agree(pendulum, protocol)
    _agree(two_actuator, protocol)


def _unstable(horizon, noise=False):
    rng = np.random.default_rng(7)
    A = rng.normal(size=(4, 4))
    A *= 1.2 / max(abs(np.linalg.eigvals(A)))
    return pl.System(A=A, B=rng.normal(size=(4, 2)), horizon=horizon, state_weight=[1, 1, 1, 1],
                     input_weight=[1, 1], mu=[0.9, 0.6], x0=[1, 0, 0, 0],
                     noise_cov=np.eye(4) * 0.01 if noise else None)


def test_long_unstable_tcp_recursion_is_finite_and_stabilising():
    system = _unstable(2000)
    sol = pl.closed_form(system, "tcp", method="recursion")
    assert np.isfinite(sol.cost)
    assert np.all(np.isfinite(sol.inputs))
    # the mean closed loop A - B M K of the receding-horizon law is stable
    mean_loop = system.A - system.B @ np.diag(system.mu) @ sol.gain
    assert max(abs(np.linalg.eigvals(mean_loop))) < 1
    # at N = 60 it agrees with the (well-conditioned) sparse QP, while the dense form
    # has already lost about 1e-7 of the gain to the conditioning of Omega_g ~ 1.2^120
    short = _unstable(60)
    rec = pl.closed_form(short, "tcp", "recursion")
    qp = pl.solve_qp(short, "tcp", "sparse", cross_check=False)
    assert np.allclose(rec.gain, qp.gain, rtol=1e-9, atol=1e-12)
    assert abs(rec.cost - qp.cost) <= 1e-9 * rec.cost


def test_long_unstable_dense_raises_instead_of_overflowing():
    """Refused up front by the condition estimate, before the 8000×4000 Gamma is built."""
    with pytest.raises(pl.NumericalError, match="condition estimate .* exceeds"):
        pl.closed_form(_unstable(2000), "tcp", method="dense")


@pytest.mark.parametrize(("protocol", "noise"), [("udp", False), ("tcp", True)])
def test_long_unstable_out_of_range_costs_raise(protocol, noise):
    """The exact cost is ~1.2^(2N) ~ 1e316 here: it cannot be returned as a double."""
    with pytest.raises(pl.NumericalError, match="double-precision range"):
        pl.closed_form(_unstable(2000, noise), protocol, method="recursion")


def test_auto_method_and_formulation(two_actuator, pendulum):
    assert pl.closed_form(two_actuator, "tcp", method="auto").method == "dense"
    assert pl.closed_form(_unstable(60), "tcp", method="auto").method == "recursion"  # 1.2^120
    assert pl.closed_form(_unstable(200).with_mu([0.5, 0.5]), "tcp", method="auto").method == "recursion"
    assert pl.solve_qp(two_actuator, "tcp", with_gain=False).method == "qp-condensed"
    assert pl.solve_qp(pendulum, "tcp", with_gain=False).method == "qp-sparse"
    with pytest.raises(pl.InputError, match="formulation: expected"):
        pl.solve_qp(two_actuator, "tcp", formulation="dense")
    with pytest.raises(pl.InputError, match="method: expected"):
        pl.closed_form(two_actuator, "tcp", method="fast")
