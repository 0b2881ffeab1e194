"""The Kalman filter with intermittent observations (sensing.kalman), the bounds on its expected error
covariance and the critical arrival rate (sensing.bounds, sensing.lmi), against independent references:
a plain per-path filter written here with np.linalg.inv, sampling, scipy's DARE and the scalar thresholds."""

import itertools

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from packetloss_cvx.model.sensor import Sensor
from packetloss_cvx.sensing.bounds import (
    covariance_bounds,
    critical_gamma,
    expected_riccati_map,
    lower_bound_covariance,
    stable_certificate,
    upper_bound_covariance,
)
from packetloss_cvx.sensing.kalman import (
    ENUMERATION_MAX_PATHS,
    actuation_covariance,
    expected_covariance,
    hermitian_pinv,
    measurement_update,
    pattern_rows,
    predict,
)
from packetloss_cvx.tolerances import ROUNDING_ORDER_RTOL
from tests.references import textbook_filter_path


def assert_same_to_rounding(actual, desired):
    """Two orders of one computation: within ROUNDING_ORDER_RTOL of the largest entry (tolerances.py)."""
    desired = np.asarray(desired)
    np.testing.assert_allclose(actual, desired, rtol=0, atol=ROUNDING_ORDER_RTOL * np.abs(desired).max(initial=0.0))


def plant(rng, n=3, p=2):
    A = rng.normal(size=(n, n))
    A *= 1.15 / np.max(np.abs(np.linalg.eigvals(A)))
    W = rng.normal(size=(n, n))
    C = rng.normal(size=(p, n))
    V = rng.normal(size=(p, p))
    return A, W @ W.T / n + 0.1 * np.eye(n), C, V @ V.T / p + 0.1 * np.eye(p)


@pytest.mark.parametrize("seed", range(3))
def test_enumeration_equals_the_weighted_sum_over_paths_of_the_plain_filter(seed):
    rng = np.random.default_rng(seed)
    A, Q, C, R = plant(rng)
    sensor = Sensor(C=C, noise_cov=R, gamma=[0.7, 0.4], groups=[[0], [1]], P0=np.eye(3))
    steps = 3
    out = expected_covariance(A, Q, sensor, steps)
    want_pred, want_filt = np.zeros((steps + 1, 3, 3)), np.zeros((steps, 3, 3))
    for path in itertools.product(itertools.product((0, 1), repeat=2), repeat=steps):
        weight = np.prod([0.7 if a[0] else 0.3 for a in path]) * np.prod([0.4 if a[1] else 0.6 for a in path])
        pred, filt = textbook_filter_path(A, Q, C, R, sensor.groups, np.eye(3), path)
        want_pred += weight * np.array(pred)
        want_filt += weight * np.array(filt)
    assert out.paths == 2 ** (2 * steps)
    np.testing.assert_allclose(out.predicted, want_pred, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(out.filtered, want_filt, rtol=1e-10, atol=1e-12)


def test_enumeration_equals_monte_carlo():
    rng = np.random.default_rng(7)
    A, Q, C, R = plant(rng)
    sensor = Sensor(C=C, noise_cov=R, gamma=[0.6], P0=np.eye(3))
    steps, samples = 8, 4000
    exact = np.trace(expected_covariance(A, Q, sensor, steps).predicted[-1])
    draws = []
    for _ in range(samples):
        arrivals = rng.random((steps, 1)) < 0.6
        draws.append(np.trace(textbook_filter_path(A, Q, C, R, sensor.groups, np.eye(3), arrivals)[0][-1]))
    mean, stderr = np.mean(draws), np.std(draws, ddof=1) / np.sqrt(samples)
    assert abs(mean - exact) < 4 * stderr


def test_too_many_paths_are_refused():
    sensor = Sensor(C=[[1.0]], gamma=[0.5])
    with pytest.raises(ValueError, match="steps: .*arrival paths"):
        expected_covariance(np.eye(1), np.eye(1), sensor, int(np.log2(ENUMERATION_MAX_PATHS)) + 1)


@pytest.mark.parametrize("seed", range(3))
def test_bounds_hold_at_every_step(seed):
    """lower_k <= E[P^-_k] <= V_k (V_k the expected Riccati map iterated from P0, S_k the all-lost series)."""
    rng = np.random.default_rng(seed)
    A, Q, C, R = plant(rng)
    sensor = Sensor(C=C, noise_cov=R, gamma=[0.8, 0.5], groups=[[0], [1]], P0=2 * np.eye(3))
    out = expected_covariance(A, Q, sensor, 6)
    q = 0.2 * 0.5
    S, V = sensor.P0.copy(), sensor.P0.copy()
    for k in range(1, 7):
        S = q * A @ S @ A.T + Q
        V = expected_riccati_map(V, A, Q, sensor)
        assert np.linalg.eigvalsh(out.predicted[k] - S)[0] > -1e-10
        assert np.linalg.eigvalsh(V - out.predicted[k])[0] > -1e-10


def test_stationary_bounds_at_full_arrival_are_the_filter_dare():
    rng = np.random.default_rng(3)
    A, Q, C, R = plant(rng)
    sensor = Sensor(C=C, noise_cov=R, gamma=[1.0])
    want = solve_discrete_are(A.T, C.T, Q, R)          # the predicted covariance of the stationary filter
    bounds = covariance_bounds(A, Q, sensor)
    np.testing.assert_allclose(bounds.upper, want, rtol=1e-9)
    np.testing.assert_allclose(bounds.lower, Q, rtol=1e-12)  # q = 0: one step of noise


def test_full_state_limit_has_no_error():
    A = np.array([[1.2, 0.3], [0.0, 0.8]])
    sensor = Sensor(C=np.eye(2), gamma=[1.0])            # C = I, R = 0, gamma = 1
    out = expected_covariance(A, np.eye(2), sensor, 3)
    np.testing.assert_allclose(out.filtered, 0.0, atol=ROUNDING_ORDER_RTOL * np.abs(out.predicted).max())
    assert np.abs(out.predicted).max() == 1.0                      # P^-_k = Sigma_W = I: the scale is not zero
    np.testing.assert_allclose(covariance_bounds(A, np.eye(2), sensor).upper, np.eye(2), atol=1e-14)


def test_scalar_lower_bound_by_hand():
    assert float(lower_bound_covariance(np.array([[2.0]]), np.array([[1.0]]), 0.2)[0, 0]) == pytest.approx(5.0)
    assert lower_bound_covariance(np.array([[2.0]]), np.array([[1.0]]), 0.3) is None
    # the noise does not excite the unstable mode: the series converges although q rho^2 >= 1
    S = lower_bound_covariance(np.diag([2.0, 0.5]), np.diag([0.0, 1.0]), 0.5)
    np.testing.assert_allclose(S, np.diag([0.0, 1.0 / (1.0 - 0.5 * 0.25)]), rtol=1e-12)


@pytest.mark.parametrize("a", [1.5, 2.0, 4.0])
def test_scalar_critical_rate_is_one_minus_one_over_a_squared(a):
    cg = critical_gamma(np.array([[a]]), Sensor(C=[[1.0]], gamma=[0.5], noise_cov=[[1.0]]))
    assert cg.exact
    assert cg.lower == pytest.approx(1 - 1 / a**2, abs=1e-15)
    assert cg.upper == cg.lower


def test_invertible_C_makes_the_lower_bound_exact():
    A = np.array([[1.4, 0.2], [0.0, 0.5]])
    cg = critical_gamma(A, Sensor(C=[[1.0, 1.0], [0.0, 1.0]], gamma=[0.5], noise_cov=np.eye(2)))
    assert cg.exact
    assert cg.lower == pytest.approx(1 - 1 / 1.4**2)


def test_two_channels_lower_bound_by_hand():
    """gamma = (t, t): every channel lost with probability (1 - t)^2, so t_low = 1 - 1/rho(A)."""
    A = np.array([[1.5, 0.1], [0.0, 0.3]])
    sensor = Sensor(C=[[1.0, 0.0], [0.0, 1.0]], gamma=[0.5, 0.5], groups=[[0], [1]], noise_cov=np.eye(2))
    cg = critical_gamma(A, sensor)
    assert cg.lower == pytest.approx(1 - 1 / 1.5, abs=1e-12)
    assert not cg.exact
    assert cg.upper >= cg.lower


def test_certified_rate_agrees_with_sinopoli_lmi():
    """The certificate's bisection and the LMI decide the same set {exists X > g(X)}: an independent solver."""
    from packetloss_cvx.sensing.lmi import FilterLmi
    A = np.array([[1.3, 0.2], [0.0, 0.5]])
    sensor = Sensor(C=[[1.0, 1.0]], gamma=[0.5], noise_cov=[[1.0]])
    cg = critical_gamma(A, sensor, tol=1e-6)
    lmi = FilterLmi(A, sensor)
    assert lmi.margin(np.array([cg.upper + 2e-3]))[0] > 1e-6
    assert lmi.margin(np.array([cg.lower - 2e-3]))[0] < 1e-9          # not certified (margin 0 to rounding)
    assert stable_certificate(A, sensor, np.array([cg.lower - 1e-3])) is None


def test_upper_bound_is_none_when_no_bound_exists():
    sensor = Sensor(C=[[1.0]], gamma=[0.5], noise_cov=[[1.0]])
    assert upper_bound_covariance(np.array([[2.0]]), np.array([[1.0]]), sensor) is None   # 0.5 < 0.75


def test_udp_actuation_covariance_by_sampling():
    rng = np.random.default_rng(0)
    B, mu, u = rng.normal(size=(3, 2)), np.array([0.3, 0.8]), np.array([1.5, -2.0])
    v = rng.random((200_000, 2)) < mu
    err = ((v - mu) * u) @ B.T                        # B (V - M) u
    np.testing.assert_allclose(err.T @ err / len(err), actuation_covariance(B, mu, u), atol=0.05)


def test_one_row_update_equals_the_pseudoinverse_form():
    """A single received row takes 1/s instead of pinv(S): the general form's values to rounding
    (ROUNDING_ORDER_RTOL), a zero S (R = 0, the row blind to P) giving a zero gain, on a stack as on one matrix."""
    rng = np.random.default_rng(5)
    C, R = rng.normal(size=(2, 3)), np.diag([0.7, 0.0])
    G = rng.normal(size=(4, 3, 3))
    Pm = G @ np.swapaxes(G, -1, -2)
    Pm[3] = np.diag([0.0, 2.0, 1.0])                        # row 1 below sees only the first state: S = 0
    C[1] = [1.0, 0.0, 0.0]
    for row in (0, 1):
        Cr, Rr = C[[row]], R[[row]][:, [row]]
        PCt = Pm @ Cr.T
        S = Cr @ PCt + Rr
        Lr = PCt @ np.linalg.pinv(0.5 * (S + np.swapaxes(S, -1, -2)), rcond=1e-13, hermitian=True)
        P = Pm - Lr @ np.swapaxes(PCt, -1, -2)
        got, L = measurement_update(Pm, C, R, np.array([row]))
        assert_same_to_rounding(got, 0.5 * (P + np.swapaxes(P, -1, -2)))
        assert_same_to_rounding(L[..., row:row + 1], Lr)
        assert not L[..., 1 - row].any()
        for k in range(4):
            assert_same_to_rounding(measurement_update(Pm[k], C, R, np.array([row]))[0], got[k])
    assert not measurement_update(Pm[3], C, R, np.array([1]))[1].any()


def test_hermitian_pinv_is_numpys_pinv():
    """sensing.kalman.hermitian_pinv against NumPy's hermitian pinv (the same eigen-decomposition and cut-off, its
    products in another order: ROUNDING_ORDER_RTOL) on full-rank, singular (an exact zero and a rounding-level
    eigenvalue), indefinite, zero and badly scaled symmetric matrices of sizes 1 to 5."""
    rng = np.random.default_rng(11)
    for k in range(400):
        p = int(rng.integers(1, 6))
        F = rng.normal(size=(p, p)) * 10.0 ** rng.uniform(-6, 6)
        if k % 5 == 0 and p > 1:
            F[:, -1] = F[:, 0]                       # rank-deficient: an eigenvalue at rounding level, cut off
        S = F @ F.T
        if k % 3 == 0:
            S[:, 0] = S[0, :] = 0.0                  # singular: a zero singular value cut off
        if k % 7 == 0:
            S = S - 2.0 * np.diag(np.diag(S))        # indefinite: signs move into v
        if k % 50 == 0:
            S = np.zeros((p, p))
        S = 0.5 * (S + S.T)
        assert_same_to_rounding(hermitian_pinv(S), np.linalg.pinv(S, rcond=1e-13, hermitian=True))


def test_expected_riccati_map_is_the_pattern_sum_of_stacked_updates():
    """sensing.bounds.riccati_map (the rows of each pattern selected once, one matrix at a time) against the sum
    over the arrival patterns of measurement_update on a stack of one matrix (NumPy's pinv route), then predict:
    the same values to rounding (ROUNDING_ORDER_RTOL)."""
    from packetloss_cvx.sensing.arrivals import arrival_patterns
    rng = np.random.default_rng(12)
    A, W, C, R = plant(rng, n=3, p=3)
    sensor = Sensor(C=C, gamma=[0.6, 0.3], groups=[[0, 2], [1]], noise_cov=R)
    arrived, prob = arrival_patterns(sensor.gamma)
    for _ in range(5):
        G = rng.normal(size=(3, 3))
        V = G @ G.T
        parts = [pk * measurement_update(V[None], C, R, pattern_rows(sensor, a))[0][0]
                 for a, pk in zip(arrived, prob, strict=True)]
        assert_same_to_rounding(expected_riccati_map(V, A, W, sensor), predict(sum(parts), A, W))


def test_measurement_update_of_one_row_is_the_pinv_route():
    """sensing.kalman.measurement_update divides by the 1 x 1 innovation covariance instead of calling pinv (the
    audit's Monte Carlo and Riccati iteration): numpy's pinv route to rounding (ROUNDING_ORDER_RTOL) on a stack with
    s = 0 and a tiny s, and the hand update L = P c' / (c P c' + r), P+ = P - L c P."""
    from packetloss_cvx.sensing.kalman import measurement_update

    rng = np.random.default_rng(4)
    n = 3
    C, R = rng.normal(size=(2, n)), np.diag([0.5, 0.0])
    F = rng.normal(size=(6, n, n))
    Pm = F @ np.swapaxes(F, -1, -2)
    Pm[4] = 0.0                                  # row 1 with r = 0: s = 0, pinv gives 0
    Pm[5] *= 1e-300                              # a tiny s
    for row in (0, 1):
        rows = np.array([row])
        P, L = measurement_update(Pm, C, R, rows)
        PCt = Pm @ C[rows].T
        S = C[rows] @ PCt + R[np.ix_(rows, rows)]
        S = 0.5 * (S + np.swapaxes(S, -1, -2))
        Lr = PCt @ np.linalg.pinv(S, rcond=1e-13, hermitian=True)
        update = Pm - Lr @ np.swapaxes(PCt, -1, -2)
        for k in range(len(Pm)):                 # each matrix at its own scale (Pm[5] is 1e-300 of the others)
            assert_same_to_rounding(L[k][:, rows], Lr[k])
            assert_same_to_rounding(P[k], 0.5 * (update[k] + update[k].T))
        assert not L[4].any()                    # P = 0: no gain (s = 0 for row 1, where pinv gives 0)
        for k in range(4):                       # the hand update
            c = C[row]
            s = c @ Pm[k] @ c + R[row, row]
            assert np.allclose(L[k, :, row], Pm[k] @ c / s, rtol=1e-12)
            assert np.allclose(P[k], Pm[k] - np.outer(Pm[k] @ c, Pm[k] @ c) / s, rtol=1e-10, atol=1e-12)
