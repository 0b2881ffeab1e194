"""The sampled cost of a law on the stationary filter's estimate averages steps T - T//2 .. T-1 of runs that start at
x0; the exact value it is checked against is the expectation of that same average (sensing.loop.window_costs), not
the stationary cost of the law run for ever. The reference enumerates every arrival and delivery path over the window
and propagates the second moment of (x, xm) (the state and the filter's prior mean) along each path with the
simulator's own equations: another algorithm, in other coordinates, than the averaged operator of (xhat, e)."""

import itertools
import json

import numpy as np
import pytest

from packetloss_cvx import System
from packetloss_cvx.cli import main
from packetloss_cvx.closedloop.riccati import dp_riccati
from packetloss_cvx.model.sensor import Sensor
from packetloss_cvx.model.system import loop_weights
from packetloss_cvx.sensing.loop import estimated_loop, filter_gains, window_costs
from packetloss_cvx.sensing.montecarlo import simulate_estimated

#: a two-state plant, one actuator, one sensor link measuring the first state, far from x0 = 0
PLANT = System(A=[[1.1, 0.2], [0.0, 0.9]], B=[[0.0], [1.0]], horizon=5, state_weight=[1.0, 2.0], input_weight=[0.5],
               mu=[0.7], x0=[30.0, -20.0], noise_cov=np.diag([0.1, 0.2]),
               sensor=Sensor(C=[[1.0, 0.0]], gamma=[0.6], noise_cov=[[0.05]], P0=np.diag([0.3, 0.1])))


def enumerated_costs(s: System, K: np.ndarray, protocol: str, steps: int) -> np.ndarray:
    """E[stage cost at k], k < steps, summed over the 4^steps paths of (arrival a_k, delivery v_k)."""
    n, mu, C, R = s.n, s.mu_schedule[0], s.sensor.C, s.sensor.noise_cov
    _, gains, _ = filter_gains(s)
    Omega, psi = loop_weights(s)
    eye, Z = np.eye(n), np.zeros((n, n))
    gamma = float(s.sensor.gamma[0])
    total = np.zeros(steps)
    for path in itertools.product(itertools.product((0, 1), (0.0, 1.0)), repeat=steps):
        weight = np.prod([(gamma if a else 1 - gamma) * (mu[0] if v else 1 - mu[0]) for a, v in path])
        mean = np.concatenate([s.x0, s.x0])                      # (x, xm): x_0 ~ N(x0, P0), xm_0 = x0
        M = np.outer(mean, mean) + np.block([[s.sensor.P0, Z], [Z, Z]])
        for k, (a, v) in enumerate(path):
            L = gains[a]                                          # pattern index: 0 nothing arrived, 1 the link
            H = np.hstack([L @ C, eye - L @ C])                     # xhat = H (x, xm) + L r
            Xhat = H @ M @ H.T + L @ R @ L.T
            X = M[:n, :n]
            total[k] += weight * (np.trace(Omega @ X) + v * float(psi[0]) * (K @ Xhat @ K.T).item())
            applied = -v * K                                      # applied = v u = -v K xhat
            prior = -(v if protocol == "tcp" else mu[0]) * K
            Gs = np.vstack([np.hstack([s.A, Z]) + s.B @ applied @ H, s.A @ H + s.B @ prior @ H])
            Gr = np.vstack([s.B @ applied @ L, s.A @ L + s.B @ prior @ L])
            M = Gs @ M @ Gs.T + Gr @ R @ Gr.T + np.block([[s.noise_cov, Z], [Z, Z]])
    return total


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_window_costs_are_the_enumerated_paths(protocol):
    K = dp_riccati(PLANT).gain
    steps = 5
    np.testing.assert_allclose(window_costs(PLANT, K, protocol, steps), enumerated_costs(PLANT, K, protocol, steps),
                               rtol=1e-10)


def test_the_sample_is_checked_against_its_own_window_not_the_stationary_cost():
    """Steps 10..19 from x0 = (30, -20): the transient keeps the window's expectation well above the stationary cost, so
    only the window's exact value is a fair reference: the sample sits within 4 standard errors of it and many from
    the stationary one."""
    K = dp_riccati(PLANT).gain
    steps = 20
    run = simulate_estimated(PLANT, K, "udp", "stationary", samples=4000, steps=steps, seed=5, law="dp")
    assert run.averaged_steps == (10, 19)
    window = float(np.mean(window_costs(PLANT, K, "udp", steps)[10:]))
    assert run.exact_window_cost == pytest.approx(window, rel=1e-12)
    assert run.stderr_reason == ""
    assert abs(run.z) < 4
    assert run.z == pytest.approx((run.mean_stage_cost - window) / run.stderr, rel=1e-12)
    stationary = estimated_loop(PLANT, K, "udp").average_stage_cost
    assert run.exact_stage_cost == pytest.approx(stationary, rel=1e-12)
    assert abs(run.mean_stage_cost - stationary) > 10 * run.stderr
    entry = run.to_dict()
    assert (entry["averaged_steps"], entry["exact_stage_cost_window"]) == ([10, 19], "stationary")
    assert entry["exact_window_cost"] == run.exact_window_cost
    kalman = simulate_estimated(PLANT, K, "udp", "kalman", samples=50, steps=steps, seed=5, law="dp")
    assert np.isnan(kalman.exact_window_cost)
    assert kalman.to_dict()["z"] is None


def test_simulate_names_each_window(capsys):
    """pendulum_sensor, 40 steps: the full-state lines average steps 0..39 (sample and exact), the estimated-state
    lines steps 20..39 beside the exact value on those steps, and the stationary cost is named as the law run for
    ever; the JSON says the same."""
    argv = ["simulate", "pendulum_sensor", "--closed-loop", "--samples", "60", "--steps", "40", "--law", "dp", "-q"]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    full = next(line for line in lines if "DP optimum, closed loop" in line)
    assert "over steps 0..39 from x0, exact" in full
    assert "on those steps [basis: loop]" in full
    stationary = next(line for line in lines if "stationary filter:" in line)
    assert "over steps 20..39 from x0, exact " in stationary
    assert "on those steps (z = " in stationary
    assert "stationary cost (the law run for ever) 6.83257 [basis: loop]" in stationary
    kalman = next(line for line in lines if "kalman filter:" in line)
    assert "over steps 20..39 from x0 [basis: loop]; no exact value" in kalman
    assert main([*argv, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["dp"]["closed_loop"]["averaged_steps"] == [0, 39]
    runs = data["estimated_state"]["dp"]
    assert runs["averaged_steps"] == runs["kalman"]["averaged_steps"] == runs["stationary"]["averaged_steps"] == [
        20, 39]
    assert runs["stationary"]["exact_stage_cost_window"] == "stationary"
    assert runs["stationary"]["exact_window_cost"] > 10 * runs["stationary"]["exact_stage_cost"]   # the transient
