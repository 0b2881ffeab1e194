"""Every lossy-sensor loop verdict is proved or withheld (sensing.loop.loop_verdict, no_gains_verdict and the CLI
sections that report them): where the expected-covariance upper-bound iteration diverges and gamma lies between
the certified bounds on the critical rate, no verdict (null with a reason; "undecided" in text); below the
lower bound, "not stable" proved by the diverging lower bound."""

import json

import numpy as np
import pytest

from packetloss_cvx.cli.parser import build_parser
from packetloss_cvx.cli.region import run as region_run
from packetloss_cvx.cli.simulate import run as simulate_run
from packetloss_cvx.cli.solve import run as solve_run
from packetloss_cvx.closedloop.riccati import NO_SOLUTION, dp_riccati
from packetloss_cvx.errors import NumericalError
from packetloss_cvx.model.files import save_system
from packetloss_cvx.model.sensor import Sensor
from packetloss_cvx.model.system import System
from packetloss_cvx.sensing import loop as loop_module
from packetloss_cvx.sensing.bounds import (
    critical_gamma,
    lower_bound_diverges,
    stable_certificate,
    upper_bound_covariance,
)
from packetloss_cvx.sensing.loop import estimated_loop, loop_map, loop_verdict, no_gains_verdict

# x+ = diag(1.3, -1.2) x + B v u + w, y = x1 + x2 + r: one row for two unstable modes. Lower bound on the critical
# rate 1 - 1/1.3^2 = 0.4083 (by hand); no certificate X > g(X) at 0.5 (checked below), so 0.5 is between the bounds.
A = [[1.3, 0.0], [0.0, -1.2]]


def plant(gamma: float, mu: float = 0.9) -> System:
    return System(A=A, B=[[1.0], [1.0]], horizon=3, state_weight=[1.0, 1.0], input_weight=[1.0], mu=[mu],
                  x0=[0.0, 0.0], noise_cov=np.eye(2).tolist(),
                  sensor=Sensor(C=[[1.0, 1.0]], gamma=[gamma], noise_cov=[[1.0]]))


def parse(*argv):
    return build_parser().parse_args(list(argv))


def test_the_case_lies_between_the_bounds():
    """critical_gamma's bounds bracket gamma = 0.5: its lower bound is the hand value 1 - 1/rho(A)^2 (one channel),
    and no certificate exists at 0.5 (so the upper bound lies above it)."""
    s = plant(0.5)
    bounds = critical_gamma(s.A, s.sensor)
    assert bounds.lower == pytest.approx(1 - 1 / 1.3**2, rel=1e-12)        # the hand value, below 0.5
    assert bounds.lower < 0.5 < bounds.upper
    assert not bounds.exact                                                # one row for two modes: bounds only
    assert stable_certificate(s.A, s.sensor, np.array([0.5])) is None      # no certificate: not above the upper
    assert upper_bound_covariance(s.A, s.noise_cov, s.sensor) is None      # the upper-bound iteration diverges
    assert not lower_bound_diverges(s.A, s.noise_cov, s.sensor.P0, 0.5)    # the lower bound is finite


def test_between_the_bounds_the_loop_has_no_verdict():
    s = plant(0.5)
    for protocol in ("tcp", "udp"):
        loop = estimated_loop(s, dp_riccati(s).gain, protocol)
        assert loop.stable is None
        assert loop.reason.startswith("undecided")
        assert np.isnan(loop.average_stage_cost)
        assert loop.to_dict()["stable"] is None
        assert loop.to_dict()["average_stage_cost"] is None


def test_below_the_lower_bound_not_stable_is_proved_by_it():
    s = plant(0.3)                               # (1 - 0.3) 1.3^2 = 1.183 >= 1: E[P-] >= sum 1.183^k Sigma_W-ish
    verdict, why = no_gains_verdict(s)
    assert verdict is False
    assert "proved" in why
    loop = estimated_loop(s, dp_riccati(s).gain, "tcp")
    assert loop.stable is False
    assert loop.average_stage_cost == np.inf


def test_a_noise_free_plant_diverges_through_its_initial_covariance():
    """Sigma_W = 0, P0 = 1, a = 2, gamma = 0.5: E[P-_k] >= 0.5^k 4^k = 2^k (the all-lost paths), proved unbounded."""
    s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0],
               noise_cov=[[0.0]], sensor=Sensor(C=[[1.0]], noise_cov=[[0.0]], gamma=[0.5], P0=[[1.0]]))
    assert no_gains_verdict(s)[0] is False
    assert no_gains_verdict(s.with_sensor(Sensor(C=[[1.0]], noise_cov=[[0.0]], gamma=[0.5])))[0] is None  # P0 = 0


@pytest.mark.parametrize(("radius", "verdict"), [(0.5, True), (1 - 1e-6, True), (1.0, None), (1 + 1e-12, None),
                                                 (1 + 1e-6, False), (np.inf, False), (np.nan, None)])
def test_a_radius_proves_a_verdict_only_outside_the_margin(radius, verdict):
    assert loop_verdict(radius) is verdict


def test_solve_reports_undecided_between_the_bounds(tmp_path):
    path = str(save_system(plant(0.5), tmp_path / "between.toml"))
    result = solve_run(parse("solve", path, "--no-qp"))
    assert result.code == 0
    crit = result.data["estimation"]["critical_gamma"]
    assert crit["lower"] < 0.5 < crit["upper"]
    for protocol in ("tcp", "udp"):
        entry = result.data[protocol]["estimated_state"]
        assert entry["stable"] is None
        assert entry["reason"].startswith("undecided")
    assert result.data["estimation"]["dp"]["stable"] is None
    assert "undecided" in result.text
    assert "NOT stable" not in result.text
    json.dumps(result.data)


def test_simulate_reports_undecided_between_the_bounds(tmp_path):
    path = str(save_system(plant(0.5), tmp_path / "between.toml"))
    data = simulate_run(parse("simulate", path, "--closed-loop", "--samples", "20", "--steps", "4", "--json")).data
    for law in ("dp", "tcp", "udp"):
        entry = data["estimated_state"][law]
        assert entry["stable"] is None
        assert entry["stable_reason"].startswith("undecided")


def test_region_sensor_grid_has_no_verdict_on_the_undecided_row(tmp_path):
    path = str(save_system(plant(0.5), tmp_path / "between.toml"))
    grid = region_run(parse("region", path, "--law", "dp", "--sensor-grid", "2", "-q")).data["sensor"]["grid"]
    assert grid["gamma_scale"] == [0.5, 1.0]        # one channel: gamma = t, so row 0 is gamma = 0.5, between
    for protocol in ("tcp", "udp"):
        assert grid[protocol]["stable"][0] == [None, None]
        assert grid[protocol]["undecided_share"] >= 0.5


@pytest.mark.parametrize(("reason", "radius"), [(NO_SOLUTION + " at mu = [0.5] (proved)", np.inf),
                                                ("modified Riccati equation: undecided at mu = [0.5]", np.nan)])
def test_loop_map_reports_inf_only_where_no_dp_law_is_proved(monkeypatch, reason, radius):
    """The (gamma, mu) map's DP radius is inf ("proved unbounded") only where dp_riccati proves that no law
    stabilises; a DP that fails otherwise (no convergence, an overflow without proof) is no verdict: nan."""
    def failing(system, mu=None, gain=None):
        raise NumericalError(reason)

    monkeypatch.setattr(loop_module, "dp_riccati", failing)
    out, _ = loop_map(plant(0.95), np.array([1.0]), np.array([1.0]), ("dp",))["dp"]
    assert np.array_equal(out, np.full((1, 1), radius), equal_nan=True)
