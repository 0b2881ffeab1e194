"""python-control interop: a closed loop as control.StateSpace, a System from a discrete-time StateSpace."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx import InputError, System, closed_form, load_example
from packetloss_cvx.simulation import closed_loop_statespace, dp_riccati

control = pytest.importorskip("control")


def test_closed_loop_statespace_poles_are_the_mean_dynamics():
    s = load_example("two_actuator")
    K = closed_form(s, "tcp").gain
    cl = closed_loop_statespace(s, K, dt=0.05)
    assert cl.dt == 0.05
    assert control.isdtime(cl, strict=True)
    expected = np.linalg.eigvals(s.A - s.B @ np.diag(s.mu) @ K)
    assert np.allclose(np.sort_complex(cl.poles()), np.sort_complex(expected))
    # the mean state after 3 steps from x0, by python-control's own simulation
    resp = control.initial_response(cl, T=np.arange(4) * 0.05, X0=s.x0)
    Abar = s.A - s.B @ np.diag(s.mu) @ K
    assert np.allclose(resp.states[:, 3], np.linalg.matrix_power(Abar, 3) @ s.x0)


def test_from_statespace_round_trip_and_dare():
    plant = control.ss([[1.1, 0.2], [0.0, 0.9]], [[0.0], [1.0]], np.eye(2), np.zeros((2, 1)), dt=0.1)
    s = System.from_statespace(plant, horizon=5, state_weight=[1.0, 1.0], input_weight=[2.0], mu=[1.0],
                               x0=[1.0, 0.0])
    assert np.array_equal(s.A, plant.A)
    assert np.array_equal(s.B, plant.B)
    # at mu = 1 the DP optimum is python-control's discrete LQR (an independent DARE)
    K, P, _ = control.dlqr(plant, np.eye(2), np.array([[2.0]]))
    dp = dp_riccati(s)
    assert np.allclose(dp.cost_to_go, P, rtol=1e-9)
    assert np.allclose(dp.gain, K, rtol=1e-9)


def test_from_statespace_rejects_continuous_time_and_others():
    continuous = control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]])
    with pytest.raises(InputError, match="discrete-time"):
        System.from_statespace(continuous, horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    with pytest.raises(InputError, match="StateSpace"):
        System.from_statespace(np.eye(1), horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])


def test_the_closed_loop_statespace_stays_discrete_time():
    """dt=0 returned a continuous-time StateSpace of the discrete-time matrix A - B M K (poles read as
    continuous-time ones: a stable loop looks unstable and the reverse); dt=-1 leaked control's ValueError."""
    control = pytest.importorskip("control")
    from packetloss_cvx.simulation import closed_loop_statespace
    s = pl.load_example("two_actuator")
    for dt in (0, None, -1.0, float("nan"), False, "0.1"):
        with pytest.raises(InputError) as err:
            closed_loop_statespace(s, np.eye(2), dt=dt)
        assert err.value.field == "dt"
    assert control.isdtime(closed_loop_statespace(s, np.eye(2), dt=0.1), strict=True)
    with pytest.raises(InputError) as err:   # was a TypeError: got multiple values for keyword argument 'A'
        pl.System.from_statespace(control.ss([[1.0]], [[1.0]], [[1.0]], [[0.0]], 1), A=[[2.0]], horizon=3,
                                  state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    assert err.value.field == "A"


def test_without_python_control_the_interop_names_the_extra(monkeypatch):
    """python-control is the optional extra `control`: without it both directions are a typed error that says
    how to install it (optional.load), not a bare ModuleNotFoundError traceback."""
    import sys

    from packetloss_cvx.statespace import plant_matrices

    monkeypatch.setitem(sys.modules, "control", None)          # import control -> ImportError
    with pytest.raises(InputError, match=r"pip install 'packetloss-cvx\[control\]'") as err:
        closed_loop_statespace(load_example("two_actuator"), np.eye(2), dt=0.1)
    assert err.value.field == "closed_loop_statespace"
    with pytest.raises(InputError, match=r"pip install 'packetloss-cvx\[control\]'") as err:
        plant_matrices(object())
    assert err.value.field == "sys"
