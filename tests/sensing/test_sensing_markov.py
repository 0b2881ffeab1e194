"""Gilbert-Elliott sensor links (sensing.arrivals, sensing.markov_bounds, the chain paths of sensing.kalman and
sensing.montecarlo) against independent references: a brute-force sum over arrival AND hidden-state paths with a
textbook filter written here, sampling, hand values, and the i.i.d. chain (p + r = 1) that must equal the
Bernoulli sensor."""

import itertools

import numpy as np
import pytest

from packetloss_cvx.closedloop.riccati import dp_riccati
from packetloss_cvx.model.sensor import Sensor
from packetloss_cvx.model.system import System
from packetloss_cvx.sensing.arrivals import ChainSampler, sensor_arrivals
from packetloss_cvx.sensing.bounds import covariance_bounds, stable_certificate
from packetloss_cvx.sensing.kalman import expected_covariance
from packetloss_cvx.sensing.loop import estimated_loop
from packetloss_cvx.sensing.markov_bounds import (
    filter_stability,
    markov_certificate,
    markov_covariance_bounds,
)
from packetloss_cvx.sensing.montecarlo import sampled_covariance, simulate_estimated
from tests.references import textbook_filter_path


def path_probability(arrivals, p, r, hg, hb, belief):
    """P(arrival path) for independent Gilbert-Elliott channels: the sum over every hidden good/bad path, by hand."""
    total = 1.0
    for j in range(len(p)):
        chan = 0.0
        for states in itertools.product((True, False), repeat=len(arrivals)):      # True: good
            prob = belief[j] if states[0] else 1 - belief[j]
            for k, good in enumerate(states):
                h = hg[j] if good else hb[j]
                prob *= h if arrivals[k][j] else 1 - h
                if k + 1 < len(states):
                    nxt = states[k + 1]
                    prob *= (1 - p[j] if nxt else p[j]) if good else (r[j] if nxt else 1 - r[j])
            chan += prob
        total *= chan
    return total


def plant(rng, n=3, p=2):
    A = rng.normal(size=(n, n))
    A *= 1.15 / np.max(np.abs(np.linalg.eigvals(A)))
    W = rng.normal(size=(n, n))
    V = rng.normal(size=(p, p))
    return A, W @ W.T / n + 0.1 * np.eye(n), rng.normal(size=(p, n)), V @ V.T / p + 0.1 * np.eye(p)


CHAIN = {"model": "gilbert-elliott", "p": [0.2, 0.1], "r": [0.3, 0.5], "h_good": [0.95, 0.9], "h_bad": [0.1, 0.3],
         "belief": [0.6, 0.2]}


@pytest.mark.parametrize("seed", range(3))
def test_enumeration_equals_the_sum_over_arrival_and_state_paths(seed):
    rng = np.random.default_rng(seed)
    A, Q, C, R = plant(rng)
    sensor = Sensor(C=C, noise_cov=R, channel=CHAIN, groups=[[0], [1]], P0=np.eye(3))
    steps = 3
    out = expected_covariance(A, Q, sensor, steps)
    want_pred, want_filt, total = np.zeros((steps + 1, 3, 3)), np.zeros((steps, 3, 3)), 0.0
    for path in itertools.product(itertools.product((0, 1), repeat=2), repeat=steps):
        w = path_probability(path, CHAIN["p"], CHAIN["r"], CHAIN["h_good"], CHAIN["h_bad"], CHAIN["belief"])
        pred, filt = textbook_filter_path(A, Q, C, R, sensor.groups, np.eye(3), path)
        want_pred += w * np.array(pred)
        want_filt += w * np.array(filt)
        total += w
    assert total == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(out.predicted, want_pred, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(out.filtered, want_filt, rtol=1e-10, atol=1e-12)


def test_enumeration_lies_within_the_sampled_standard_errors_and_the_bernoulli_twin_does_not():
    """Bursty (lambda = 0.85): Monte Carlo of the chain's paths agrees with the enumeration; the Bernoulli link at
    the same long-run rate is many standard errors away, so the comparison can fail."""
    rng = np.random.default_rng(3)
    A, Q, C, R = plant(rng, p=1)
    chain = {"model": "gilbert-elliott", "p": [0.05], "r": [0.1]}
    sensor = Sensor(C=C, noise_cov=R, channel=chain, P0=np.eye(3))
    steps = 12
    exact = expected_covariance(A, Q, sensor, steps)
    sampled = sampled_covariance(A, Q, sensor, steps, samples=4000, seed=1)
    z = (sampled.predicted[-1] - exact.predicted[-1]) / sampled.predicted_stderr[-1]
    assert np.all(np.abs(z) < 4.5)
    zf = (sampled.filtered - exact.filtered) / np.where(sampled.filtered_stderr > 0, sampled.filtered_stderr, 1.0)
    assert np.all(np.abs(zf) < 4.5)
    twin = expected_covariance(A, Q, sensor.with_gamma(sensor.gamma), steps)
    far = (np.trace(twin.predicted[-1]) - np.trace(exact.predicted[-1]))
    assert abs(far) > 10 * np.sqrt(np.sum(sampled.predicted_stderr[-1] ** 2))


def iid_twin(gamma, **kw):
    """A Gilbert-Elliott chain with p + r = 1 (rows of T equal: memoryless) and stationary belief, rate gamma."""
    return {"model": "gilbert-elliott", "p": [1 - gamma], "r": [gamma], **kw}


@pytest.mark.parametrize("gamma", [0.5, 0.7])
def test_an_iid_chain_equals_the_bernoulli_sensor(gamma):
    A = np.array([[1.3, 0.0], [0.0, -1.2]])
    Q = np.eye(2)
    chain = Sensor(C=[[1.0, 1.0]], noise_cov=[[1.0]], channel=iid_twin(gamma), P0=np.eye(2))
    bern = Sensor(C=[[1.0, 1.0]], noise_cov=[[1.0]], gamma=[gamma], P0=np.eye(2))
    np.testing.assert_allclose(expected_covariance(A, Q, chain, 10).predicted,
                               expected_covariance(A, Q, bern, 10).predicted, rtol=1e-12)
    mb, bb = markov_covariance_bounds(A, Q, chain), covariance_bounds(A, Q, bern)
    assert mb.trace_lower == pytest.approx(bb.trace_lower, rel=1e-10)
    if bb.upper is None:
        assert mb.upper is None
    else:
        assert mb.trace_upper == pytest.approx(bb.trace_upper, rel=1e-9)
    bernoulli_certified = stable_certificate(A, bern, np.array([gamma])) is not None
    assert (markov_certificate(A, chain) is not None) == bernoulli_certified
    assert bernoulli_certified == (gamma == 0.7)            # upper bound on the critical rate 0.590 (verdict tests)


def test_a_scalar_gilbert_link_with_a_perfect_sensor_has_its_hand_value():
    """C = 1, R = 0: P = 0 on arrival, so P- = Sigma_W sum_{i <= L} a^{2i} with L the run of losses; with
    P(L >= i) = pi_bad (1 - r)^(i - 1): E[P-] = 1 + pi_bad a^2 / (1 - (1 - r) a^2) = 1 + (1/9) 4 / 0.2, both bounds."""
    chain = {"model": "gilbert-elliott", "p": [0.1], "r": [0.8]}
    sensor = Sensor(C=[[1.0]], channel=chain)
    b = markov_covariance_bounds(np.array([[2.0]]), np.eye(1), sensor)
    want = 1 + (0.1 / 0.9) * 4 / (1 - 0.2 * 4)
    assert b.trace_lower == pytest.approx(want, rel=1e-12)
    assert b.trace_upper == pytest.approx(want, rel=1e-9)
    fs = filter_stability(np.array([[2.0]]), np.eye(1), sensor)
    assert (fs.bounded, fs.exact, fs.by) == (True, True, "one-step observability")
    assert fs.loss_radius == pytest.approx(0.2 * 4)


@pytest.mark.parametrize(("r", "bounded"), [(0.76, True), (0.74, False)])
def test_the_gilbert_threshold_on_the_recovery_rate_is_exact_with_c_invertible(r, bounded):
    """One Gilbert channel, C = 1: E[P] bounded iff (1 - r) a^2 < 1, i.e. r > 0.75 at a = 2, whatever p."""
    for p in (0.05, 0.5, 0.9):
        fs = filter_stability(np.array([[2.0]]), np.eye(1), Sensor(C=[[1.0]], noise_cov=[[1.0]], channel={
            "model": "gilbert-elliott", "p": [p], "r": [r]}))
        assert fs.bounded is bounded


def test_the_upper_bound_holds_along_sampled_paths_of_a_bursty_link():
    """Long horizon (past the enumeration): lower <= the sampled E[P-] <= upper, within standard errors."""
    A = np.array([[1.1, 0.3], [0.0, 0.8]])
    Q = 0.5 * np.eye(2)
    sensor = Sensor(C=[[1.0, 0.0]], noise_cov=[[0.2]], channel={"model": "gilbert-elliott", "p": [0.1], "r": [0.3],
                                                                "h_good": [0.9], "h_bad": [0.2]})
    b = markov_covariance_bounds(A, Q, sensor)
    s = sampled_covariance(A, Q, sensor, 150, samples=3000, seed=2)
    tail = np.trace(s.predicted[-1])
    se = float(np.sqrt(np.sum(s.predicted_stderr[-1] ** 2)))
    assert b.trace_lower - 4 * se <= tail <= b.trace_upper + 4 * se
    assert b.trace_lower < b.trace_upper


def test_sampled_gilbert_states_follow_the_chain():
    ch = {"model": "gilbert-elliott", "p": [0.2], "r": [0.6], "h_good": [1.0], "h_bad": [0.0]}
    sampler = ChainSampler(Sensor(C=[[1.0]], channel=ch), np.random.default_rng(0), 20000)
    arrived = np.array([sampler.step()[:, 0] for _ in range(3)])
    # the runs are independent: standard errors from the runs' own means (4 of them: the tolerance the other
    # sampled checks use)
    per_run = arrived.mean(axis=0)
    assert abs(per_run.mean() - 0.75) < 4 * per_run.std(ddof=1) / np.sqrt(per_run.size)      # r / (p + r)
    given = arrived[2][arrived[1]]                                  # step 2 of the runs good at step 1
    assert abs(given.mean() - 0.8) < 4 * given.std(ddof=1) / np.sqrt(given.size)            # P(good | good) = 1 - p
    arr = sensor_arrivals(Sensor(C=[[1.0]], channel=ch))
    assert arr.loss_matrix().tolist() == [[0.0, 0.0], [0.6, 0.4]]


def loop_plant(channel):
    return System(A=[[1.1, 0.2], [0.0, 0.9]], B=[[0.0], [1.0]], horizon=5, state_weight=[1.0, 1.0],
                  input_weight=[0.5], mu=[0.8], x0=[0.0, 0.0], noise_cov=np.diag([0.1, 0.1]).tolist(),
                  sensor=Sensor(C=[[1.0, 0.0]], noise_cov=[[0.05]], channel=channel))


def test_tcp_like_control_on_the_chain_estimate_splits_its_cost_by_separation():
    """The DP law on the Kalman estimate behind a bursty sensor link: cost = tr(P Sigma_W) + tr(K'HK E[P_k]) (the
    arrivals are independent of the state, so separation holds), on sampled runs."""
    s = loop_plant({"model": "gilbert-elliott", "p": [0.1], "r": [0.3], "h_good": [0.95], "h_bad": [0.1]})
    dp = dp_riccati(s)
    run = simulate_estimated(s, dp.gain, "tcp", "kalman", samples=3000, steps=120, seed=4)
    mu, P, K, B, psi = s.mu, dp.cost_to_go, dp.gain, s.B, s.input_weights[0]
    H = np.diag(mu * psi) + (B * mu).T @ P @ (B * mu) + np.diag(mu * (1 - mu) * np.diag(B.T @ P @ B))
    split = np.trace(P @ s.noise_cov) + np.trace(K.T @ H @ K @ run.mean_filtered_covariance)
    assert abs(run.mean_stage_cost - split) < 4 * run.stderr
    assert run.stable is None
    assert np.isnan(run.exact_stage_cost)


def exact_kalman_loop_cost(system, K, steps):
    """The mean stage cost ``E[x_k'Omega x_k + (V_k u_k)'Psi (V_k u_k)]`` over the kept steps ``k = steps - steps // 2
    .. steps - 1`` of the TCP-like loop ``u = -K xhat`` on the time-varying Kalman estimate behind a Bernoulli sensor,
    exactly: E[P_k] and E[P^-_k] summed over all 2^steps arrival paths (:func:`textbook_filter_path`, no package
    code), then the estimate's second moment ``X_k = E[xhat_k xhat_k']`` forward: ``X_0 = x0 x0' + P0 - E[P_0]``,
    ``X_{k+1} = E[(A - B V K) X_k (A - B V K)'] + E[P^-_{k+1}] - E[P_{k+1}]`` (the innovation adds what the update
    removes from the covariance), and ``E[x_k x_k'] = X_k + E[P_k]`` (the error is orthogonal to the estimate)."""
    A, B, C, R, Q = system.A, system.B, system.sensor.C, system.sensor.noise_cov, system.noise_cov
    gamma, P0, x0 = float(system.sensor.gamma[0]), system.sensor.P0, system.x0
    Pm, Pf = np.zeros((steps + 1, *A.shape)), np.zeros((steps, *A.shape))
    for path in itertools.product((0, 1), repeat=steps):
        w = gamma ** sum(path) * (1 - gamma) ** (steps - sum(path))
        pred, filt = textbook_filter_path(A, Q, C, R, system.sensor.groups, P0, [(a,) for a in path])
        Pm += w * np.array(pred)
        Pf += w * np.array(filt)
    mu, Omega, psi = system.mu, system.state_weights[0], system.input_weights[0]
    D = np.diag(mu)
    X, costs = np.outer(x0, x0) + P0 - Pf[0], []
    for k in range(steps):
        KXK = K @ X @ K.T
        costs.append(np.trace(Omega @ (X + Pf[k])) + np.trace(np.diag(mu * psi) @ KXK))
        if k + 1 < steps:
            VKXKV = D @ KXK @ D + np.diag(mu * (1 - mu) * np.diag(KXK))           # E[V N V], v_i ~ Bernoulli(mu_i)
            M = A @ X @ A.T - A @ X @ K.T @ D @ B.T - B @ D @ K @ X @ A.T + B @ VKXKV @ B.T
            X = M + Pm[k + 1] - Pf[k + 1]
    return float(np.mean(costs[steps - steps // 2:]))


def test_an_iid_chain_loop_costs_what_the_bernoulli_loop_costs():
    """The Kalman-filtered TCP-like loop behind a memoryless chain (p + r = 1) and behind the Bernoulli sensor at its
    rate: both sampled means lie within 4 of their own standard errors of the exact mean stage cost over the kept
    steps (every arrival path enumerated), and of each other."""
    s = loop_plant(iid_twin(0.6))
    twin = s.with_sensor(s.sensor.with_gamma([0.6]))
    gain = dp_riccati(s).gain
    steps = 10
    exact = exact_kalman_loop_cost(twin, gain, steps)
    a = simulate_estimated(s, gain, "tcp", "kalman", samples=40000, steps=steps, seed=1)
    b = simulate_estimated(twin, gain, "tcp", "kalman", samples=40000, steps=steps, seed=2)
    assert abs(a.mean_stage_cost - exact) < 4 * a.stderr
    assert abs(b.mean_stage_cost - exact) < 4 * b.stderr
    assert abs(a.mean_stage_cost - b.mean_stage_cost) < 4 * np.hypot(a.stderr, b.stderr)


def test_the_stationary_filter_behind_a_chain_is_refused_with_its_field():
    s = loop_plant(iid_twin(0.6))
    with pytest.raises(ValueError, match="sensor.model"):
        simulate_estimated(s, dp_riccati(s).gain, "tcp", "stationary", samples=10, steps=4)
    loop = estimated_loop(s, dp_riccati(s).gain, "udp")        # UDP-like: the error depends on the inputs
    assert loop.stable is None
    assert "Gilbert-Elliott" in loop.reason
    assert np.isnan(loop.average_stage_cost)


def test_the_tcp_like_verdict_behind_a_chain_is_proved_by_separation_or_withheld():
    """Scalar a = 2, C = 1 (exact filter verdict): r = 0.8 keeps E[P] bounded ((1 - r) a^2 = 0.8). With mu = 0.9 the
    full-state radius of u = -k x is (2 - 0.9 k)^2 + 0.09 k^2 (hand value): k = 1.8 gives 0.3316 (stable, so the
    loop is proved stable), k = 0.5 gives 2.4025 (not proved either way); r = 0.7 makes E[P] unbounded (False)."""
    def scalar(r):
        return System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[0.0],
                      noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], channel={"model": "gilbert-elliott", "p": [0.1],
                                                                           "r": [r]}))
    assert (2 - 0.9 * 1.8) ** 2 + 0.09 * 1.8**2 < 1 < (2 - 0.9 * 0.5) ** 2 + 0.09 * 0.5**2
    good = estimated_loop(scalar(0.8), np.array([[1.8]]), "tcp")
    assert good.stable is True
    assert "separation" in good.reason
    assert estimated_loop(scalar(0.8), np.array([[0.5]]), "tcp").stable is None
    assert estimated_loop(scalar(0.8), np.array([[1.8]]), "udp").stable is None
    assert estimated_loop(scalar(0.7), np.array([[1.8]]), "tcp").stable is False
    assert estimated_loop(scalar(0.7), np.array([[1.8]]), "udp").stable is False


def test_the_command_line_analyses_a_gilbert_elliott_sensor_file(tmp_path):
    from packetloss_cvx.cli.parser import build_parser
    from packetloss_cvx.cli.region import run as region_run
    from packetloss_cvx.cli.simulate import run as simulate_run
    from packetloss_cvx.cli.solve import run as solve_run
    from packetloss_cvx.model.files import save_system

    chain = {"model": "gilbert-elliott", "p": [0.1], "r": [0.8]}                # C = 1: exact, (1 - 0.8) 4 < 1
    s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0],
               noise_cov=[[1.0]], sensor=Sensor(C=[[1.0]], channel=chain))
    path = str(save_system(s, tmp_path / "gilbert_sensor.toml"))
    parse = build_parser().parse_args
    est = solve_run(parse(["solve", path, "--no-qp"])).data["estimation"]
    assert est["filter_stability"]["bounded"] is True
    want = 1 + (0.1 / 0.9) * 4 / (1 - 0.2 * 4)                              # the hand value above (R = 0)
    assert est["error_covariance_trace"]["lower"] == pytest.approx(want, rel=1e-12)
    assert est["error_covariance_trace"]["upper"] == pytest.approx(want, rel=1e-9)
    assert est["dp"]["stable"] is True
    assert est["dp"]["cost"] is None
    region = region_run(parse(["region", path, "--law", "dp", "-q"])).data["sensor"]
    assert region["tcp"]["filter_stability"]["bounded"] is True
    assert "not derived" in region["reason"]
    sim = simulate_run(parse(["simulate", path, "--closed-loop", "--samples", "200", "--steps", "20",
                              "--json"])).data["estimated_state"]
    assert sim["dp"]["stable"] is True                   # TCP-like: separation (filter bounded, DP loop stable)
    assert "separation" in sim["dp"]["stable_reason"]
    assert sim["udp"]["stable"] is None                  # UDP-like: not derived
    kalman = sim["dp"]["kalman"]
    assert kalman["mean_stage_cost"] > 0
    assert kalman["mean_filtered_trace_stderr"] > 0
    assert "Gilbert-Elliott" in sim["dp"]["stationary"]["reason"]


def test_a_periodic_chain_and_a_chain_too_large_give_no_verdict_and_say_why():
    """p = r = 1 alternates for ever (no limit distribution); four channels on n = 12 need S n^2 = 2304 unknowns
    (over 2048): both are analysed as far as proved, null otherwise, never an error or a guess."""
    from packetloss_cvx.cli.sensing_section import estimation_section

    s = loop_plant({"model": "gilbert-elliott", "p": [1.0], "r": [1.0]})
    est, lines = estimation_section(s)
    assert est["filter_stability"]["bounded"] is None
    assert est["error_covariance_trace"]["lower"] is None
    assert "p = r = 1" in est["error_covariance_trace"]["reason"]
    assert est["dp"]["stable"] is None
    n = 12
    big = System(A=(1.05 * np.eye(n)).tolist(), B=np.eye(n)[:, :1].tolist(), horizon=2, state_weight=[1.0] * n,
                 input_weight=[1.0], mu=[0.9], x0=[0.0] * n, noise_cov=np.eye(n).tolist(),
                 sensor=Sensor(C=np.eye(n)[:4].tolist(), groups=[[0], [1], [2], [3]],
                               channel={"model": "gilbert-elliott", "p": [0.1] * 4, "r": [0.5] * 4}))
    loop = estimated_loop(big, np.zeros((1, n)), "tcp")
    assert loop.stable is None
    assert "2048" in loop.reason
    with pytest.raises(ValueError, match="2048"):
        markov_covariance_bounds(big.A, big.noise_cov, big.sensor)


def test_a_bad_state_the_chain_never_enters_proves_nothing_and_one_it_leaves_late_still_counts():
    """p = 0: the good state is absorbing. Started good (given, or the stationary start), C = 1 and h_good = 1 deliver
    every step, so P- is the Riccati fixed point 1 + 4P/(P + 1) at a = 2, R = Sigma_W = 1: P = 2 + sqrt(5) (hand),
    both bounds, and bounded, though the unreachable bad state has (1 - r) a^2 = 3.6. Started bad with r = 0.1,
    E[P-_k] >= 0.9^(k-1) 4^(k-1) (lost k-1 times in a row, noise alone): unbounded, and the exact enumeration grows."""
    A, one = np.array([[2.0]]), np.eye(1)
    for start in ({"state": ["good"]}, {}):
        sensor = Sensor(C=[[1.0]], noise_cov=[[1.0]], channel={"model": "gilbert-elliott", "p": [0.0], "r": [0.1],
                                                               **start})
        fs = filter_stability(A, one, sensor)
        assert (fs.bounded, fs.by) == (True, "one-step observability")
        assert fs.loss_radius == 0.0                      # no loss in the states it visits
        b = markov_covariance_bounds(A, one, sensor)
        assert b.trace_lower == pytest.approx(1.0, rel=1e-12)
        assert b.trace_upper == pytest.approx(2 + np.sqrt(5), rel=1e-9)
    bad = Sensor(C=[[1.0]], noise_cov=[[1.0]], channel={"model": "gilbert-elliott", "p": [0.0], "r": [0.1],
                                                        "state": ["bad"]}, P0=[[0.0]])
    assert filter_stability(A, one, bad).bounded is False
    path = expected_covariance(A, one, bad, 14).predicted[:, 0, 0]
    assert path[-1] > 0.9 ** 13 * 4 ** 13 > 1e5
    assert np.all(np.diff(path[4:]) > 0)
