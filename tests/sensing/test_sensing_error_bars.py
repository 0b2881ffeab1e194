"""A sampled cost of a law on an estimated state has an error bar only where the loop's fourth moments are proved
bounded (closedloop.tails), as the full-state loop's does. The reference below builds the loop's one-step maps
G_{a,v} of z = (xhat, e) by running the simulator's own equations (sensing.montecarlo: predict, measure, update,
apply v u) on unit vectors, for every arrival pattern a and delivery pattern v, and takes the spectral radius of
sum p_a P(v) G^{(k)} (k = 2: the second moments, k = 4: the fourth) densely."""

import itertools
import json

import numpy as np
import pytest

from packetloss_cvx import System
from packetloss_cvx.cli import main
from packetloss_cvx.model.sensor import Sensor
from packetloss_cvx.sensing.loop import estimated_loop, filter_gains, loop_error_bar_reason
from packetloss_cvx.sensing.montecarlo import simulate_estimated


def scalar(a: float, mu: float, gamma: float) -> System:
    return System(A=[[a]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0],
                  noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], gamma=[gamma], noise_cov=[[1.0]]))


def step_matrix(s: System, K: np.ndarray, La: np.ndarray, v: np.ndarray, protocol: str) -> np.ndarray:
    """The noise-free step z -> z+ of the simulator with the gain La received and the deliveries v."""
    n, mu = s.n, s.mu_schedule[0]
    columns = []
    for j in range(2 * n):
        z = np.eye(2 * n)[j]
        xhat, e = z[:n], z[n:]
        u = -K @ xhat
        x_next = s.A @ (xhat + e) + s.B @ (v * u)
        predicted = s.A @ xhat + s.B @ (v * u if protocol == "tcp" else mu * u)
        xhat_next = predicted + La @ (s.sensor.C @ x_next - s.sensor.C @ predicted)
        columns.append(np.concatenate([xhat_next, x_next - xhat_next]))
    return np.array(columns).T


def moment_radius(s: System, K: np.ndarray, protocol: str, power: int) -> float:
    mu = s.mu_schedule[0]
    _, gains, prob = filter_gains(s)
    d = 2 * s.n
    total = np.zeros((d ** power, d ** power))
    for La, pa in zip(gains, prob, strict=True):
        for v in itertools.product([0.0, 1.0], repeat=s.m):
            v = np.array(v)
            G = step_matrix(s, K, La, v, protocol)
            Gk = G
            for _ in range(power - 1):
                Gk = np.kron(Gk, G)
            total += pa * np.prod(np.where(v == 1.0, mu, 1.0 - mu)) * Gk
    return float(np.abs(np.linalg.eigvals(total)).max())


# (a, mu, gamma, k): a = 2, k = 2, mu = 0.98 has a full-state loop with bounded fourth moments ((1 - mu) a^4 =
# 0.32), yet the filter's error e+ = (1 - L_a) a e at gamma = 0.9 has (1 - gamma) a^4 = 1.6 > 1: only the (xhat, e)
# loop shows the fourth moments grow; a = 1.5, k = 1.5, mu = gamma = 0.9 has them bounded in both
CASES = [(2.0, 0.98, 0.9, 2.0), (1.5, 0.9, 0.9, 1.5)]


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_the_error_bar_follows_the_fourth_moments_of_xhat_and_e(case, protocol):
    a, mu, gamma, k = case
    s, K = scalar(a, mu, gamma), np.array([[k]])
    assert moment_radius(s, K, protocol, 2) == pytest.approx(estimated_loop(s, K, protocol).spectral_radius,
                                                             rel=1e-12)       # the reference is the loop's
    rho4 = moment_radius(s, K, protocol, 4)
    assert abs(rho4 - 1.0) > 0.05                        # each case is clear of the margin
    reason = loop_error_bar_reason(s, K, protocol, filter_gains(s))
    assert (reason == "") == (rho4 < 1.0)
    if rho4 >= 1.0:
        assert f"rho_4 = {rho4:.4g}" in reason


def test_a_run_on_growing_fourth_moments_has_no_error_bar():
    """The first case: mean-square stable, fourth moments growing through the filter's error only. The stationary
    filter's run withholds its error bar; the time-varying filter's, judged by the law's full-state loop (bounded
    here), keeps it."""
    s, K = scalar(2.0, 0.98, 0.9), np.array([[2.0]])
    assert estimated_loop(s, K, "tcp").stable is True
    run = simulate_estimated(s, K, "tcp", "stationary", samples=200, steps=20, seed=1)
    assert np.isnan(run.stderr)
    assert "fourth moments grow" in run.stderr_reason
    assert run.to_dict()["stderr"] is None
    assert run.to_dict()["stderr_reason"] == run.stderr_reason
    kalman = simulate_estimated(s, K, "tcp", "kalman", samples=200, steps=20, seed=1)
    assert np.isfinite(kalman.stderr)
    assert kalman.stderr_reason == ""
    assert "stderr_reason" not in kalman.to_dict()


def test_simulate_withholds_the_error_bar_of_a_diverging_estimated_loop(capsys):
    """pendulum_sensor: the paper's TCP-like and UDP-like laws are not mean-square stable on the estimate (radius of
    (xhat, e) 1.00645 and 1.06699), so neither filter's line shows +-, their JSON stderr is null with the reason;
    the DP law's loop is stable with bounded fourth moments and keeps its error bar."""
    assert main(["simulate", "pendulum_sensor", "--closed-loop", "--samples", "60", "--steps", "20", "-q"]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "filter: mean stage cost" in line]
    assert len(lines) == 6
    for line in lines:
        assert ("+-" in line) == line.lstrip().startswith("DP law"), line
    assert main(["simulate", "pendulum_sensor", "--closed-loop", "--samples", "60", "--steps", "20", "-q",
                 "--json"]) == 0
    data = json.loads(capsys.readouterr().out)["estimated_state"]
    for law in ("tcp", "udp"):
        for entry in (data[law]["kalman"], data[law]["stationary"], data[law]):
            assert entry["stderr"] is None
            assert entry["stderr_reason"].startswith("no error bar")
    assert data["dp"]["stationary"]["stderr"] > 0
