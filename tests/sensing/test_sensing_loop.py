"""The loop (xhat, e) with an estimated state (sensing.loop) and its Monte Carlo (sensing.montecarlo), against
the full-state loop (simulation.moments), standard LQG from scipy's two DAREs, the separation of the TCP-like
radius, the scalar thresholds and sampling."""

import itertools

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from packetloss_cvx import System
from packetloss_cvx.closedloop.moments import closed_loop
from packetloss_cvx.closedloop.riccati import dp_riccati
from packetloss_cvx.closedloop.stability import mean_square_radius
from packetloss_cvx.errors import InputError
from packetloss_cvx.model.sensor import Sensor
from packetloss_cvx.sensing.loop import estimated_loop, filter_gains
from packetloss_cvx.sensing.montecarlo import simulate_estimated


def random_plant(rng, n=3, m=2, p=2, mu=None, gamma=(0.8,), groups=None, C=None, R=None):
    A = rng.normal(size=(n, n))
    A *= 1.1 / np.max(np.abs(np.linalg.eigvals(A)))
    W = rng.normal(size=(n, n))
    sensor = Sensor(C=rng.normal(size=(p, n)) if C is None else C, gamma=list(gamma), groups=groups,
                    noise_cov=0.05 * np.eye(p) if R is None else R)
    return System(A=A, B=rng.normal(size=(n, m)), horizon=5, state_weight=rng.uniform(0.5, 2, n),
                  input_weight=rng.uniform(0.5, 2, m), mu=rng.uniform(0.7, 1.0, m) if mu is None else mu,
                  x0=np.zeros(n), noise_cov=W @ W.T / n + 0.05 * np.eye(n), sensor=sensor)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_full_state_limit_reproduces_the_full_state_loop(seed, protocol):
    """C = I, R = 0, gamma = 1: the estimate is the state, so every law costs what simulation.moments says."""
    rng = np.random.default_rng(seed)
    s = random_plant(rng, C=np.eye(3), R=np.zeros((3, 3)), gamma=(1.0,), p=3)
    gain = dp_riccati(s).gain
    want = closed_loop(s, gain)
    got = estimated_loop(s, gain, protocol, "dp")
    assert got.average_stage_cost == pytest.approx(want.average_stage_cost, rel=1e-10)
    assert got.spectral_radius == pytest.approx(want.spectral_radius, rel=1e-9)


def lqg_by_two_dares(s):
    """The loss-free reference from scipy: the control DARE's X and gain K, the filter DARE's
    predicted Pp and filtered Pf."""
    A, B, C, Q, R = s.A, s.B, s.sensor.C, s.noise_cov, s.sensor.noise_cov
    Omega, Psi = s.state_weights[0], np.diag(s.input_weights[0])
    X = solve_discrete_are(A, B, Omega, Psi)
    K = np.linalg.solve(Psi + B.T @ X @ B, B.T @ X @ A)
    Pp = solve_discrete_are(A.T, C.T, Q, R)
    Pf = Pp - Pp @ C.T @ np.linalg.solve(C @ Pp @ C.T + R, C @ Pp)
    return A, B, Q, Psi, X, K, Pp, Pf


@pytest.mark.parametrize("seed", range(3))
def test_no_losses_is_standard_lqg_from_two_dares(seed):
    rng = np.random.default_rng(seed)
    s = random_plant(rng, mu=np.ones(2), gamma=(1.0,), p=1)
    A, B, Q, Psi, X, K, Pp, Pf = lqg_by_two_dares(s)
    want = np.trace(X @ Q) + np.trace(K.T @ (Psi + B.T @ X @ B) @ K @ Pf)
    for protocol in ("tcp", "udp"):
        got = estimated_loop(s, K, protocol, "lqg")
        assert got.average_stage_cost == pytest.approx(want, rel=1e-9)
    np.testing.assert_allclose(filter_gains(s)[0], Pp, rtol=1e-9)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_cost_is_control_part_plus_estimation_part(seed, protocol):
    rng = np.random.default_rng(seed)
    s = random_plant(rng, gamma=(0.9, 0.7), groups=[[0], [1]])
    for gain in (dp_riccati(s).gain, dp_riccati(s).gain * 0.8):
        loop = estimated_loop(s, gain, protocol)
        assert loop.stable
        assert loop.control_part + loop.estimation_part == pytest.approx(loop.average_stage_cost, rel=1e-9)
        assert loop.control_part == pytest.approx(dp_riccati(s).average_stage_cost, rel=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_tcp_radius_separates_into_actuator_and_filter_parts(seed):
    """TCP-like: z+ is block triangular in (xhat, e), so its radius is the larger of the full-state law's and the
    filter error's (sum_a p_a ((I - L_a C) A) ⊗ ((I - L_a C) A), enumerated here)."""
    rng = np.random.default_rng(seed)
    s = random_plant(rng, gamma=(0.6, 0.5), groups=[[0], [1]], mu=np.array([0.6, 0.9]))
    gain = dp_riccati(s).gain
    _, L, prob = filter_gains(s)
    error = sum(pa * np.kron((np.eye(3) - La @ s.sensor.C) @ s.A, (np.eye(3) - La @ s.sensor.C) @ s.A)
                for La, pa in zip(L, prob, strict=True))
    want = max(mean_square_radius(s.A, s.B, gain, s.mu), float(np.max(np.abs(np.linalg.eigvals(error)))))
    assert estimated_loop(s, gain, "tcp").spectral_radius == pytest.approx(want, rel=1e-9)


@pytest.mark.parametrize(("mu", "gamma", "stable"), [(0.8, 0.8, True), (0.7, 0.8, False), (0.8, 0.7, False)])
def test_scalar_thresholds_of_the_tcp_loop(mu, gamma, stable):
    """a = 2, C = 1, R = 0: the DP law needs mu > 1 - 1/a^2 = 0.75 and the filter gamma > 0.75 (e+ = 0 on
    arrival, a e otherwise)."""
    s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[0.0],
               noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], gamma=[gamma]))
    if stable:
        assert estimated_loop(s, dp_riccati(s).gain, "tcp").stable
    elif mu < 0.75:
        assert estimated_loop(s, np.array([[2.0]]), "tcp").spectral_radius == pytest.approx(4 * (1 - mu))
    else:
        assert estimated_loop(s, dp_riccati(s).gain, "tcp").average_stage_cost == np.inf


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_monte_carlo_of_the_stationary_filter_matches_the_exact_cost(protocol):
    rng = np.random.default_rng(11)
    s = random_plant(rng, n=2, m=1, p=1, gamma=(0.7,), mu=np.array([0.8]))
    gain = dp_riccati(s).gain
    run = simulate_estimated(s, gain, protocol, "stationary", samples=4000, steps=120, seed=3)
    assert run.stable
    assert abs(run.mean_stage_cost - run.exact_stage_cost) < 4 * run.stderr


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_cost_split_holds_for_the_time_varying_filter_by_simulation(protocol):
    """The audit's claim: cost = tr(P Sigma_W) + tr(K'HK E[P_k]) with the Kalman filter's own covariance, checked
    on sampled runs (the DP law on the estimate)."""
    rng = np.random.default_rng(5)
    s = random_plant(rng, n=2, m=1, p=1, gamma=(0.7,), mu=np.array([0.8]))
    dp = dp_riccati(s)
    run = simulate_estimated(s, dp.gain, protocol, "kalman", samples=4000, steps=120, seed=4)
    mu, P, K, B, psi = s.mu, dp.cost_to_go, dp.gain, s.B, s.input_weights[0]
    BPB = B.T @ P @ B
    H = np.diag(mu * psi) + (B * mu).T @ P @ (B * mu) + np.diag(mu * (1 - mu) * np.diag(BPB))
    split = np.trace(P @ s.noise_cov) + np.trace(K.T @ H @ K @ run.mean_filtered_covariance)
    assert np.isnan(run.exact_stage_cost)
    assert run.reason
    assert abs(run.mean_stage_cost - split) < 4 * run.stderr


def test_a_system_without_sensor_is_refused():
    s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[0.0])
    with pytest.raises(InputError, match="sensor"):
        estimated_loop(s, np.array([[1.0]]), "tcp")


def test_pattern_gains_follow_the_pattern_order():
    """Pattern k is the binary digits of k (channel 0 first): its gain has non-zero columns on its rows only."""
    rng = np.random.default_rng(0)
    s = random_plant(rng, gamma=(0.9, 0.7), groups=[[0], [1]])
    _, L, _ = filter_gains(s)
    for k, a in enumerate(itertools.product((False, True), repeat=2)):
        assert [bool(np.any(L[k][:, j])) for j in range(2)] == list(a)


def scalar_sensor_loop(W, R, P0=1.0, gamma=1.0, mu=0.9):
    """x+ = 2x + v u + w, y = x + r: a = 2, Omega = Psi = 1."""
    return System(A=[[2.0]], B=[[1.0]], horizon=5, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0],
                  noise_cov=[[W]], sensor=Sensor(C=[[1.0]], noise_cov=[[R]], gamma=[gamma], P0=[[P0]]))


def test_noise_free_perfect_sensor_gives_no_verdict_from_undetermined_gains():
    """Sigma_W = 0, R = 0, C = 1, gamma = 1: Pbar = 0, so the update gain is not fixed by it; the pseudo-inverse's
    zero gain read as radius a^2 = 4, "not mean-square stable", for a perfect sensor. Now no verdict, a reason."""
    s = scalar_sensor_loop(W=0.0, R=0.0)
    K = dp_riccati(s).gain
    loop = estimated_loop(s, K, "tcp")
    assert not np.isfinite(loop.spectral_radius)
    assert loop.stable is None                         # no verdict, neither way
    assert "not determined" in loop.reason


def test_noise_free_plant_with_measurement_noise_is_exact_against_hand_values():
    """Sigma_W = 0, R = 1, gamma = 1: the filter DARE's stabilising root (scipy) is Pbar = 3, L = 3/4, so the
    error's radius is ((1 - L) a)^2 = 1/4; the DP gain at mu = 0.9 solves 0.6 P^2 - 4P - 1 = 0 (by hand),
    k = 2P/(1 + P), radius (2 - mu k)^2 + mu (1 - mu) k^2; the TCP-like loop's radius is the larger."""
    s = scalar_sensor_loop(W=0.0, R=1.0)
    Pf = solve_discrete_are(np.array([[2.0]]), np.array([[1.0]]), np.array([[0.0]]), np.array([[1.0]]))[0, 0]
    assert np.isclose(Pf, 3.0)
    P = (4 + np.sqrt(16 + 2.4)) / 1.2
    k = 2 * P / (1 + P)
    dp_radius = (2 - 0.9 * k) ** 2 + 0.09 * k ** 2
    loop = estimated_loop(s, np.array([[k]]), "tcp")
    assert loop.reason == ""
    assert np.isclose(loop.spectral_radius, max(dp_radius, (0.25 * 2) ** 2), rtol=1e-9)


@pytest.mark.parametrize("seed", range(2))
def test_a_callers_dp_solution_is_used_and_gives_the_split_of_two_dares(seed):
    """estimated_loop(..., dp=...) takes the caller's DP solution instead of solving it again (the cost-split claim
    passes the one it has): no losses, the split is scipy's two DAREs' (control tr(X Q), estimation
    tr(K'(Psi + B'XB)K P_f)); a different caller's solution is the one whose P enters the control part."""
    rng = np.random.default_rng(10 + seed)
    s = random_plant(rng, mu=np.ones(2), gamma=(1.0,), p=1)
    A, B, Q, Psi, X, K, Pp, Pf = lqg_by_two_dares(s)
    dp = dp_riccati(s)
    given = estimated_loop(s, dp.gain, "tcp", "dp", dp=dp)
    solved = estimated_loop(s, dp.gain, "tcp", "dp")
    assert (given.average_stage_cost, given.control_part, given.estimation_part) == \
        (solved.average_stage_cost, solved.control_part, solved.estimation_part)
    assert given.control_part == pytest.approx(np.trace(X @ Q), rel=1e-9)
    assert given.estimation_part == pytest.approx(np.trace(K.T @ (Psi + B.T @ X @ B) @ K @ Pf), rel=1e-8)
    other = dp_riccati(s.with_mu([0.9, 0.95]))
    assert estimated_loop(s, dp.gain, "tcp", "dp", dp=other).control_part == pytest.approx(
        float(np.sum(other.cost_to_go * Q)), rel=1e-14)
    assert estimated_loop(s, dp.gain, "tcp", "dp", dp=dp, split=False).control_part != given.control_part  # nan


@pytest.mark.parametrize(("radius", "verdict"), [(-3.0, True), (-0.3, None), (0.3, None), (3.0, False)])
def test_a_loop_verdict_needs_the_radius_a_margin_away_from_one(radius, verdict):
    """loop_verdict's band on both sides of 1: a radius 3 MEAN_SQUARE_MARGIN below 1 proves stable, 3 above proves
    unstable, 0.3 either side proves nothing (the eigenvalue solvers agree to about 1e-12 only)."""
    from packetloss_cvx.sensing.loop import loop_verdict
    from packetloss_cvx.tolerances import MEAN_SQUARE_MARGIN

    assert loop_verdict(1.0 + radius * MEAN_SQUARE_MARGIN) is verdict
