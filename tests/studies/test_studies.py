"""Sweeps: the costs over a grid against the QP twin at sample points, the grid's orientation,
and the difference against the two QP minima."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.studies import shared_channel_sweep, two_channel_sweep


def _qp(system, mu, protocol):
    return pl.solve_qp(system.with_mu(mu), protocol, with_gain=False, cross_check=False).cost


def test_shared_channel_sweep_against_the_qp_twin(pendulum):
    nus = np.array([0.05, 0.4, 0.9])
    sweep = shared_channel_sweep(pendulum, nus)
    for k, nu in enumerate(nus):
        tcp, udp = _qp(pendulum, [nu], "tcp"), _qp(pendulum, [nu], "udp")
        assert abs(sweep.costs["tcp"][k] - tcp) <= 1e-7 * tcp
        assert abs(sweep.costs["udp"][k] - udp) <= 1e-7 * udp
        assert abs(sweep.difference[k] - (udp - tcp)) <= 1e-7 * udp
    assert np.all(np.diff(sweep.costs["udp"]) < 0)      # Theorem 3
    assert sweep.difference_method.startswith("cancellation-free")


def test_two_channel_sweep_orientation_and_values(two_actuator):
    axis = [0.1, 0.6, 1.0]
    sweep = two_channel_sweep(two_actuator, axis, protocols=("udp",))
    assert sweep.costs["udp"].shape == (3, 3)
    assert sweep.difference is None
    # rows follow mu2, columns mu1: the asymmetric point (mu1, mu2) = (1.0, 0.1) is [0, 2]
    assert abs(sweep.costs["udp"][0, 2] - _qp(two_actuator, [1.0, 0.1], "udp")) <= 1e-7 * sweep.costs["udp"][0, 2]
    assert abs(sweep.costs["udp"][2, 0] - _qp(two_actuator, [0.1, 1.0], "udp")) <= 1e-7 * sweep.costs["udp"][2, 0]
    with pytest.raises(ValueError, match="read-only"):
        sweep.costs["udp"][0, 0] = 0.0


def test_ill_conditioned_systems_take_the_difference_of_checked_costs():
    s = random_system(np.random.default_rng(0), n=2, m=2, horizon=40, spectral_radius=1.5, noise=False)
    sweep = shared_channel_sweep(s, [0.5])
    assert sweep.difference_method.startswith("difference of the two closed forms")
    assert sweep.difference[0] == sweep.costs["udp"][0] - sweep.costs["tcp"][0]


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"nus": [1.5]}, "nus"), ({"nus": []}, "nus"), ({"nus": [[0.5]]}, "nus"), ({"nus": ["a"]}, "nus"),
    ({"nus": [0.5], "protocols": ()}, "protocols"), ({"nus": [0.5], "protocols": ("ftp",)}, "protocols"),
])
def test_bad_sweep_input_names_the_field(two_actuator, kwargs, field):
    with pytest.raises(pl.InputError) as info:
        shared_channel_sweep(two_actuator, **kwargs)
    assert info.value.field == field


def test_two_channel_sweep_needs_two_channels(pendulum):
    with pytest.raises(pl.InputError, match="m = 2"):
        two_channel_sweep(pendulum, [0.5])


def test_grid_difference_is_not_negative_at_the_deterministic_corners(two_actuator):
    # Theorem 2: J_Delta >= 0; at the deterministic corners it is exactly 0, never a rounding residue below 0
    result = two_channel_sweep(two_actuator, np.linspace(0, 1, 11))
    assert np.all(result.difference >= 0)
    assert result.difference[0, 0] == result.difference[-1, 0] == result.difference[0, -1] == 0
    assert result.difference[-1, -1] == 0
    # off the corners it is still J*_udp - J*_tcp (against the QP at one interior point)
    point = two_actuator.with_mu([0.3, 0.6])
    qp = pl.solve_qp(point, "udp").cost - pl.solve_qp(point, "tcp").cost
    assert result.difference[6, 3] == pytest.approx(qp, rel=1e-6)


@pytest.mark.parametrize(("factor", "cancellation_free"), [(3.0, False), (0.3, True)])
def test_the_difference_is_taken_cancellation_free_only_below_dense_max_condition(factor, cancellation_free):
    """J_Delta by difference.cost_difference (dense inverses) only where the condition estimate is within
    DENSE_MAX_CONDITION; above it, the difference of the two closed forms. The integrator x+ = x + u, unit state
    weight, N = 10 has the estimate (55 + psi) / psi by hand (see tests/lq/test_costs.py), put at factor times the
    band; either way J_Delta equals the difference of the recursion's costs."""
    from packetloss_cvx.tolerances import DENSE_MAX_CONDITION

    psi = 55.0 / (factor * DENSE_MAX_CONDITION - 1.0)
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=10, state_weight=[1.0], input_weight=[psi], mu=[0.7], x0=[1.0])
    sweep = shared_channel_sweep(s, [0.3, 0.7])
    assert sweep.difference_method.startswith("cancellation-free" if cancellation_free else "difference of the two")
    for k, nu in enumerate((0.3, 0.7)):
        udp, tcp = (pl.closed_form(s.with_mu([nu]), p, "recursion").cost for p in ("udp", "tcp"))
        assert sweep.difference[k] == pytest.approx(udp - tcp, rel=1e-6)
