"""python-control interop: a closed loop as control.StateSpace, a System from a discrete-time StateSpace."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx import InputError, System, closed_form, load_example
from packetloss_cvx.closedloop.interop import closed_loop_statespace
from packetloss_cvx.closedloop.riccati import dp_riccati


@pytest.fixture(scope="module")
def control():
    """python-control, imported by the tests that use it (not at collection: every xdist worker collects this
    module and one runs it; the import is 0.5 s with the matplotlib it loads); without it they skip."""
    return pytest.importorskip("control")


def test_closed_loop_statespace_poles_are_the_mean_dynamics(control):
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


def test_from_statespace_round_trip_and_dare(control):
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


def test_from_statespace_rejects_continuous_time_and_others(control):
    continuous = control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]])
    with pytest.raises(InputError, match="discrete-time"):
        System.from_statespace(continuous, horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    with pytest.raises(InputError, match="StateSpace"):
        System.from_statespace(np.eye(1), horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])


def test_the_closed_loop_statespace_stays_discrete_time():
    """dt=0 returned a continuous-time StateSpace of the discrete-time matrix A - B M K (poles read as
    continuous-time ones: a stable loop looks unstable and the reverse); dt=-1 leaked control's ValueError."""
    control = pytest.importorskip("control")
    from packetloss_cvx.closedloop.interop import closed_loop_statespace
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

    from packetloss_cvx.model.statespace import plant_matrices

    monkeypatch.setitem(sys.modules, "control", None)          # import control -> ImportError
    with pytest.raises(InputError, match=r"pip install 'packetloss-cvx\[control\]'") as err:
        closed_loop_statespace(load_example("two_actuator"), np.eye(2), dt=0.1)
    assert err.value.field == "closed_loop_statespace"
    with pytest.raises(InputError, match=r"pip install 'packetloss-cvx\[control\]'") as err:
        plant_matrices(object())
    assert err.value.field == "sys"


def continuous_plant(control):
    """A damped oscillator and an integrator, continuous time: python-control discretises it (zero-order hold)."""
    return control.ss([[0.0, 1.0, 0.0], [-2.0, -0.3, 0.0], [1.0, 0.0, 0.0]], [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
                      np.eye(3), np.zeros((3, 2)))


def fields(**over):
    return {"horizon": 5, "state_weight": [1.0, 1.0, 1.0], "input_weight": [1.0, 2.0], "mu": [0.9, 0.6],
            "x0": [1.0, 0.0, -1.0], **over}


def test_from_statespace_keeps_dt_and_to_statespace_gives_the_same_plant_back(control):
    plant = control.c2d(continuous_plant(control), 0.05)
    s = System.from_statespace(plant, **fields())
    assert s.dt == 0.05
    back = s.to_statespace()
    assert isinstance(back, control.StateSpace)
    assert back.dt == 0.05 and control.isdtime(back, strict=True)
    assert np.array_equal(back.A, plant.A) and np.array_equal(back.B, plant.B)
    assert np.array_equal(back.C, np.eye(3)) and np.array_equal(back.D, np.zeros((3, 2)))
    # python-control simulates both to the same states (its own forced response, 40 steps of random inputs)
    T = np.arange(40) * 0.05
    U = np.random.default_rng(3).normal(size=(2, 40))
    x0 = [0.5, -0.2, 1.0]
    original = control.forced_response(plant, T, U, X0=x0).states
    assert np.allclose(control.forced_response(back, T, U, X0=x0).states, original, rtol=1e-13, atol=1e-13)
    # and the hold-equivalent matrices are python-control's c2d, not a copy of ours: the first state
    # of the continuous oscillator after one step from x0 = e1, by the matrix exponential
    from scipy.linalg import expm
    assert np.allclose(back.A, expm(continuous_plant(control).A * 0.05), rtol=1e-12)
    # a second trip is the identity on the System
    again = System.from_statespace(back, **fields())
    assert again.to_dict() == s.to_dict()


def test_unspecified_discrete_time_is_none_and_back_to_true(control):
    plant = control.ss([[1.1]], [[1.0]], [[1.0]], [[0.0]], True)
    s = System.from_statespace(plant, horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    assert s.dt is None
    assert s.to_statespace().dt is True
    assert "dt" not in s.to_dict()["plant"]         # a file without dt is written as before


def test_dt_survives_toml_pickle_and_copies(control, tmp_path):
    import pickle

    from packetloss_cvx import load_system, save_system
    s = System.from_statespace(control.c2d(continuous_plant(control), 0.2), **fields())
    loaded = load_system(save_system(s, tmp_path / "plant.toml"))
    assert loaded.dt == 0.2 and loaded.to_dict() == s.to_dict()
    assert "dt = 0.2" in (tmp_path / "plant.toml").read_text()
    assert "sampling time dt</th><td style=\"text-align:left\">0.2 s" in s._repr_html_()   # the notebook view
    assert pickle.loads(pickle.dumps(s)).dt == 0.2
    assert s.with_mu([0.5, 0.5]).dt == 0.2 and s.with_x0([0.0, 0.0, 0.0]).dt == 0.2
    # the closed loop's StateSpace takes the system's sampling time unless told otherwise
    K = closed_form(s, "tcp").gain
    assert closed_loop_statespace(s, K).dt == 0.2
    assert closed_loop_statespace(s, K, dt=0.5).dt == 0.5
    assert closed_loop_statespace(s.with_mu([0.5, 0.5]), K).dt == 0.2


@pytest.mark.parametrize("bad", [0, -0.1, float("nan"), float("inf"), True, "0.1"])
def test_bad_sampling_times_are_refused_with_their_field(bad, tmp_path):
    with pytest.raises(InputError) as err:
        System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0], dt=bad)
    assert err.value.field == "dt"
    if not isinstance(bad, str | bool) and np.isfinite(bad):
        from packetloss_cvx import load_system
        path = tmp_path / "bad.toml"
        path.write_text(f'[plant]\nA = [[1.0]]\nB = [[1.0]]\ndt = {bad}\n[cost]\nhorizon = 2\nstate_weight = [1.0]\n'
                        'input_weight = [1.0]\n[channel]\nmu = [0.5]\n[state]\nx0 = [1.0]\n')
        with pytest.raises(InputError) as err:
            load_system(path)
        assert err.value.field == "plant.dt"


def test_from_statespace_takes_dt_from_the_statespace_only(control):
    with pytest.raises(InputError) as err:
        System.from_statespace(control.ss([[1.0]], [[1.0]], [[1.0]], [[0.0]], 0.1), dt=0.2, horizon=2,
                               state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    assert err.value.field == "dt"
