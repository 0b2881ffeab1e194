"""solve, simulate --closed-loop and region on a file with lossy sensor links (cli.sensing_section), and the
shipped pendulum_sensor example."""

import numpy as np
import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.cli.parser import build_parser
from packetloss_cvx.cli.region import run as region_run
from packetloss_cvx.cli.simulate import run as simulate_run
from packetloss_cvx.cli.solve import run as solve_run
from packetloss_cvx.model.files import load_example, save_system
from packetloss_cvx.model.sensor import Sensor
from packetloss_cvx.model.system import System
from packetloss_cvx.sensing.loop import estimated_loop


@pytest.fixture
def scalar_file(tmp_path):
    """x' = 2x + v u + w, y = x (R = 0): the filter's critical rate is 1 - 1/a^2 = 0.75 exactly."""
    s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0],
               noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], gamma=[0.9]))
    return str(save_system(s, tmp_path / "scalar.toml"))


def parse(*argv):
    return build_parser().parse_args(list(argv))


def test_solve_reports_estimation_and_each_law_on_its_estimate(scalar_file):
    data = solve_run(parse("solve", scalar_file, "--no-qp")).data
    crit = data["estimation"]["critical_gamma"]
    assert crit["exact"]
    assert crit["lower"] == crit["upper"]
    assert crit["lower"] == pytest.approx(0.75)       # one channel: d = gamma / max gamma = 1, t = gamma
    trace = data["estimation"]["error_covariance_trace"]
    # scalar, R = 0: P = 0 on arrival, so E[P-] = 1 + 0.1 * 4 E[P-]: lower = upper = 1 / (1 - 0.4)
    assert trace["lower"] == pytest.approx(1 / 0.6)
    assert trace["upper"] == pytest.approx(1 / 0.6)
    for protocol in ("tcp", "udp"):
        entry = data[protocol]["estimated_state"]
        s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0],
                   noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], gamma=[0.9]))
        want = estimated_loop(s, np.array(data[protocol]["gain"]), protocol).average_stage_cost
        assert entry["cost"] == pytest.approx(want, rel=1e-12)
        assert entry["stable"]
    assert data["estimation"]["dp"]["cost"] <= data["tcp"]["estimated_state"]["cost"]   # separation: DP is optimal


def test_full_state_files_have_no_estimation_keys():
    data = solve_run(parse("solve", "two_actuator", "--no-qp")).data
    assert "estimation" not in data
    assert "estimated_state" not in data["tcp"]


def test_simulate_closed_loop_reports_each_law_on_the_estimate(scalar_file):
    data = simulate_run(parse("simulate", scalar_file, "--closed-loop", "--samples", "400", "--steps", "60")).data
    section = data["estimated_state"]
    assert set(section) == {"tcp", "udp", "dp"}
    for entry in section.values():
        assert entry["exact_stage_cost"] is None
        assert entry["exact_reason"]
        assert entry["stable"] is True
        # mean-square stable, yet no law's fourth moments stay bounded: an undelivered step multiplies x^4 by
        # a^4 = 16, so rho_4 >= (1 - mu) a^4 = 1.6 (closedloop.tails); neither filter's sample has an error bar
        for run in (entry, entry["kalman"], entry["stationary"]):
            assert run["stderr"] is None
            assert run["stderr_reason"].startswith("no error bar")
            assert "fourth moments grow" in run["stderr_reason"]


def test_region_separates_the_tcp_thresholds_and_maps_the_coupled_region(scalar_file):
    data = region_run(parse("region", scalar_file, "--law", "dp", "--sensor-grid", "4", "-q")).data
    tcp = data["sensor"]["tcp"]
    assert tcp["critical_gamma"]["lower"] == pytest.approx(0.75)
    assert tcp["critical_mu_dp"] == pytest.approx(0.75, abs=1e-5)
    grid = data["sensor"]["grid"]
    # scales 0.25..1 of gamma = mu = 0.9: only the last row/column (0.9 > 0.75) can be stable (TCP: separate)
    stable = np.array(grid["tcp"]["stable"])
    assert not stable[:-1].any()
    assert not stable[:, :-1].any()


def test_sensor_grid_needs_a_sensor_and_is_budgeted(capsys):
    # in process (the command's exit code and its stderr; the process itself is test_cli's and test_budgets')
    code = main(["region", "two_actuator", "--sensor-grid", "3"])
    err = capsys.readouterr().err
    assert code == 2
    assert "--sensor-grid" in err
    assert err.count("\n") == 1


def test_pendulum_sensor_example_reads_and_its_dp_loop_is_stable():
    s = load_example("pendulum_sensor")
    assert s.sensor.C.shape == (2, 4)
    assert s.sensor.gamma.tolist() == [0.8]
    plain = load_example("pendulum")
    assert np.array_equal(s.A, plain.A)
    assert np.array_equal(s.B, plain.B)


def test_gilbert_elliott_sensor_file_is_valid_and_analysed(tmp_path):
    """A Gilbert channel (h_good = 1, h_bad = 0) with r = 0.4 on x' = 2x: its all-lost runs last (1 - r)^k, and
    (1 - r) a^2 = 2.4 >= 1, so E[P] is unbounded (proved), though the long-run rate 0.8 is above 1 - 1/a^2 = 0.75."""
    s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0],
               noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], channel={"model": "gilbert-elliott", "p": [0.1],
                                                                    "r": [0.4]}))
    path = str(save_system(s, tmp_path / "bursty_sensor.toml"))
    result = solve_run(parse("solve", path, "--no-qp"))
    assert result.code == 0
    crit = result.data["estimation"]["critical_gamma"]
    assert (crit["lower"], crit["upper"]) == (None, None)
    assert "Gilbert-Elliott" in crit["reason"]
    assert result.data["estimation"]["filter_stability"]["bounded"] is False
    assert result.data["estimation"]["filter_stability"]["loss_radius"] == pytest.approx(0.6 * 4)
    assert result.data["tcp"]["estimated_state"]["cost"] is None
    assert result.data["tcp"]["estimated_state"]["stable"] is False
    sim = simulate_run(parse("simulate", path, "--closed-loop", "--samples", "50", "--steps", "5")).data
    assert sim["estimated_state"]["dp"]["stable"] is False
    assert sim["estimated_state"]["dp"]["kalman"]["mean_stage_cost"] is not None      # the runs do happen


def test_sensor_grid_gives_no_verdict_where_the_stationary_gains_are_undetermined(tmp_path):
    """A noise-free plant with a noiseless full sensor (a = 2, C = 1, R = 0, Sigma_W = 0): the stationary filter's
    covariance is 0 and its gains undetermined, so no verdict at gamma = 1 (null; it read 'not
    stable', radius 4, at gamma = mu = 1 where the loop is the full-state DP's, radius < 1 by hand:
    (2 - k)^2 < 1 for the DP gain k = 2P/(1 + P) in (1, 2))."""
    s = System(A=[[2.0]], B=[[1.0]], horizon=5, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0],
               noise_cov=[[0.0]], sensor=Sensor(C=[[1.0]], noise_cov=[[0.0]], gamma=[1.0], P0=[[1.0]]))
    path = tmp_path / "noise_free.toml"
    save_system(s, path)
    grid = region_run(parse("region", str(path), "--law", "dp", "--sensor-grid", "2", "-q")).data["sensor"]["grid"]
    for protocol in ("tcp", "udp"):
        # row gamma = 0.5 < 1 - 1/a^2: E[e^2] grows by a^2 (1 - gamma) = 2 a step, not stable; row gamma = 1: null
        assert grid[protocol]["stable"] == [[False, False], [None, None]]
        assert grid[protocol]["stable_share"] == 0.0          # the share proved stable


@pytest.mark.parametrize("mu", [[0.9, 0.9], [0.9, 0.45]])
def test_region_reports_the_dp_critical_mu_along_the_file_mu(tmp_path, mu):
    """cli.sensing_section takes the DP's critical mu from the region map's points when one lies along the file's
    mu direction (mu = 0.9 on both channels: the map's default direction, ones), and bisects afresh otherwise
    (0.9, 0.45: the map's ray is not the file's): either way the number critical_mu gives along mu / max mu."""
    from packetloss_cvx.closedloop.critical import critical_mu
    s = System(A=[[1.5]], B=[[1.0, 0.5]], horizon=3, state_weight=[1.0], input_weight=[1.0, 1.0], mu=mu, x0=[1.0],
               noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], gamma=[0.9]))
    path = str(save_system(s, tmp_path / "two_inputs.toml"))
    data = region_run(parse("region", path, "--law", "dp", "-q")).data
    direction = np.array(mu) / max(mu)
    assert data["sensor"]["tcp"]["critical_mu_dp"] == critical_mu(s, "dp", direction).t
    assert (data["dp"]["t"] == data["sensor"]["tcp"]["critical_mu_dp"]) == (mu[0] == mu[1])   # the map's ray: ones
