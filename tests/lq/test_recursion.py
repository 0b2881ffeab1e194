"""The O(N) recursion against the dense closed form, and long horizons."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import packetloss_cvx as pl
from packetloss_cvx.lq.structure import structure_of
from packetloss_cvx.model.random_systems import random_system

PROTOCOLS = ("tcp", "udp")


def _agree(system, protocol, rtol=1e-9):
    dense = pl.closed_form(system, protocol, method="dense")
    rec = pl.closed_form(system, protocol, method="recursion")
    scale_u = max(1.0, np.abs(dense.inputs).max())
    scale_k = max(1.0, np.abs(dense.gain).max())
    assert abs(rec.cost - dense.cost) <= rtol * abs(dense.cost)
    assert np.abs(rec.inputs - dense.inputs).max() <= rtol * scale_u
    assert np.abs(rec.gain - dense.gain).max() <= rtol * scale_k
    assert rec.method == "recursion"
    assert dense.method == "dense"


@given(seed=st.integers(0, 2**32 - 1), protocol=st.sampled_from(PROTOCOLS))
@settings(max_examples=150, deadline=None)
def test_recursion_equals_dense_on_random_systems(seed, protocol):
    system = random_system(np.random.default_rng(seed))
    _agree(system, protocol)


@pytest.mark.parametrize("horizon", [30, 60])
@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_recursion_equals_dense_longer_horizons(horizon, protocol):
    rng = np.random.default_rng(horizon)
    system = random_system(rng, n=4, m=2, horizon=horizon, spectral_radius=0.98, non_stationary=True,
                           noise=True, time_varying=True)
    _agree(system, protocol)


@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_recursion_on_the_examples(pendulum, two_actuator, protocol):
    _agree(pendulum, protocol)
    _agree(two_actuator, protocol)


def _unstable(horizon, noise=False):
    rng = np.random.default_rng(7)
    A = rng.normal(size=(4, 4))
    A *= 1.2 / max(abs(np.linalg.eigvals(A)))
    return pl.System(A=A, B=rng.normal(size=(4, 2)), horizon=horizon, state_weight=[1, 1, 1, 1],
                     input_weight=[1, 1], mu=[0.9, 0.6], x0=[1, 0, 0, 0],
                     noise_cov=np.eye(4) * 0.01 if noise else None)


def test_long_unstable_tcp_recursion_is_finite_and_stabilising():
    system = _unstable(2000)
    sol = pl.closed_form(system, "tcp", method="recursion")
    assert np.isfinite(sol.cost)
    assert np.all(np.isfinite(sol.inputs))
    # the mean closed loop A - B M K of the receding-horizon law is stable
    mean_loop = system.A - system.B @ np.diag(system.mu) @ sol.gain
    assert max(abs(np.linalg.eigvals(mean_loop))) < 1
    # at N = 60 it agrees with the (well-conditioned) sparse QP, while the dense form
    # has already lost about 1e-7 of the gain to the conditioning of Omega_g ~ 1.2^120
    short = _unstable(60)
    rec = pl.closed_form(short, "tcp", "recursion")
    qp = pl.solve_qp(short, "tcp", "sparse", cross_check=False)
    assert np.allclose(rec.gain, qp.gain, rtol=1e-9, atol=1e-12)
    assert abs(rec.cost - qp.cost) <= 1e-9 * rec.cost


def test_long_unstable_dense_raises_instead_of_overflowing():
    """Refused up front by the condition estimate, before the 8000×4000 Gamma is built."""
    with pytest.raises(pl.NumericalError, match="condition estimate .* exceeds"):
        pl.closed_form(_unstable(2000), "tcp", method="dense")


@pytest.mark.parametrize(("protocol", "noise"), [("udp", False), ("tcp", True)])
def test_long_unstable_out_of_range_costs_raise(protocol, noise):
    """The exact cost is ~1.2^(2N) ~ 1e316 here: it cannot be returned as a double."""
    with pytest.raises(pl.NumericalError, match="double-precision range"):
        pl.closed_form(_unstable(2000, noise), protocol, method="recursion")


def test_auto_method_and_formulation(two_actuator, pendulum):
    assert pl.closed_form(two_actuator, "tcp", method="auto").method == "dense"
    assert pl.closed_form(_unstable(60), "tcp", method="auto").method == "recursion"  # 1.2^120
    assert pl.closed_form(_unstable(200).with_mu([0.5, 0.5]), "tcp", method="auto").method == "recursion"
    assert pl.solve_qp(two_actuator, "tcp", with_gain=False).method == "qp-condensed"
    assert pl.solve_qp(pendulum, "tcp", with_gain=False).method == "qp-sparse"
    with pytest.raises(pl.InputError, match="formulation: expected"):
        pl.solve_qp(two_actuator, "tcp", formulation="dense")
    with pytest.raises(pl.InputError, match="method: expected"):
        pl.closed_form(two_actuator, "tcp", method="fast")


# ---------------------------------------------------------------- the one Riccati step (recursion.riccati_step)

def _enumerated_dp_step(P, A, B, mu, psi, Omega):
    """The DP step with the expectation over the 2^m delivery patterns enumerated:
    min_u sum_v p(v) [(A x + B V u)' P (A x + B V u) + (V u)' Psi (V u)] + x' Omega x."""
    import itertools

    m = B.shape[1]
    H, L = np.zeros((m, m)), np.zeros((m, A.shape[0]))
    for v in itertools.product([0, 1], repeat=m):
        V = np.diag(v).astype(float)
        prob = np.prod([mu[i] if v[i] else 1 - mu[i] for i in range(m)])
        H += prob * V @ (B.T @ P @ B + np.diag(psi)) @ V
        L += prob * V @ B.T @ P @ A
    K = np.linalg.solve(H, L)
    return K, Omega + A.T @ P @ A - L.T @ K


@pytest.mark.parametrize("points", [1, 3, 70])          # 70 >= FLAT_MIN: the flattened products
def test_riccati_step_with_variance_is_the_enumerated_dp_step(points):
    from packetloss_cvx.lq.recursion import riccati_step

    rng = np.random.default_rng(points)
    n, m = 3, 3
    A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
    F = rng.normal(size=(points, n, n))
    P = F @ F.transpose(0, 2, 1) + np.eye(n)
    mu, psi = rng.uniform(0.05, 1.0, (points, m)), rng.uniform(0.2, 2.0, (points, m))
    Omega = np.diag(rng.uniform(0.5, 2.0, n))
    K, P_prev = riccati_step(P, A, B, mu, psi, Omega, variance=True)
    for k in range(points):
        K_ref, P_ref = _enumerated_dp_step(P[k], A, B, mu[k], psi[k], Omega)
        np.testing.assert_allclose(K[k], K_ref, rtol=1e-11, atol=1e-12 * np.abs(K_ref).max())
        np.testing.assert_allclose(P_prev[k], P_ref, rtol=1e-11, atol=1e-12 * np.abs(P_ref).max())


def _minimised_stage(P, A, B, mu, added, Omega, variance):
    """Theorem 1's step from the stage quadratic it minimises, written out here: at x, the expected
    ``(A x + B M u)' P (A x + B M u) + u' M diag(added) u [+ u' diag(mu (1 - mu) diag(B'PB)) u] + x' Omega x``
    has Hessian H = M B'PB M + M diag(added) [+ diag(mu (1 - mu) diag(B'PB))] and linear term L = M B'PA x; its
    minimiser u = -H^-1 L (every mu > 0) and minimum x'(Omega + A'PA - L' H^-1 L) x."""
    M = np.diag(mu)
    BPB = B.T @ P @ B
    H = M @ BPB @ M + M @ np.diag(added) + (np.diag(mu * (1 - mu) * np.diag(BPB)) if variance else 0.0)
    L = M @ B.T @ P @ A
    K = np.linalg.solve(H, L)
    return K, Omega + A.T @ P @ A - L.T @ K


@pytest.mark.parametrize("variance", [False, True])
def test_riccati_step_is_one_kernel_for_a_point_a_stack_and_a_flat_stack(variance):
    """riccati_step's algebra is written once for every rank: one point (2-D products, LAPACK's gesv directly), a
    batch of one (taken as that point), a point of a small stack (stacked products and solve) and of a stack of
    FLAT_MIN points or more (flattened products) all meet the stage quadratic's minimiser (written out above); the
    point, the batch of one and the small stack to the bit. A change to the step is seen on every path; a path
    that drifts from the others breaks the bit-for-bit equalities."""
    from packetloss_cvx.lq.recursion import FLAT_MIN, riccati_step

    rng = np.random.default_rng(29 + variance)
    n, m, k = 4, 3, FLAT_MIN + 2
    A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
    F = rng.normal(size=(k, n, n))
    P = F @ F.transpose(0, 2, 1) + 0.1 * np.eye(n)
    mu, added = rng.uniform(0.05, 1.0, (k, m)), rng.uniform(0.2, 2.0, (k, m))
    mu[1, 0] = 1.0                                                     # a perfect channel
    Omega = np.diag(rng.uniform(0.5, 2.0, n))
    K_flat, P_flat = riccati_step(P, A, B, mu, added, Omega, variance=variance)
    K_stack, P_stack = riccati_step(P[:4], A, B, mu[:4], added[:4], Omega, variance=variance)
    for j in range(4):
        K_ref, P_ref = _minimised_stage(P[j], A, B, mu[j], added[j], Omega, variance)
        K_point, P_point = riccati_step(P[j], A, B, mu[j], added[j], Omega, variance=variance)
        assert K_point.shape == (m, n)
        assert P_point.shape == (n, n)
        np.testing.assert_allclose(K_point, K_ref, rtol=1e-10, atol=1e-11 * np.abs(K_ref).max())
        np.testing.assert_allclose(P_point, P_ref, rtol=1e-10, atol=1e-11 * np.abs(P_ref).max())
        np.testing.assert_allclose(K_flat[j], K_ref, rtol=1e-10, atol=1e-11 * np.abs(K_ref).max())
        np.testing.assert_allclose(P_flat[j], P_ref, rtol=1e-10, atol=1e-11 * np.abs(P_ref).max())
        K_one, P_one = riccati_step(P[j:j + 1], A, B, mu[j:j + 1], added[j:j + 1], Omega, variance=variance)
        for point, one, stacked in ((K_point, K_one, K_stack), (P_point, P_one, P_stack)):
            np.testing.assert_array_equal(point, one[0])
            np.testing.assert_array_equal(point, stacked[j])
    # the least-squares form on one point is the stack's row (the homogeneous maps: no weights, no Omega)
    zero = np.zeros_like(mu[:4])
    K_ls, R_ls = riccati_step(P[:4], A, B, mu[:4], zero, variance=True, least_squares=True)
    for j in range(4):
        K_point, R_point = riccati_step(P[j], A, B, mu[j], zero[j], variance=True, least_squares=True)
        np.testing.assert_array_equal(K_point, K_ls[j])
        np.testing.assert_array_equal(R_point, R_ls[j])


def test_riccati_step_open_loop_udp_is_the_dense_theorem_1_at_n_1():
    # N = 1: the open-loop UDP-like law is eq:opt-law-2 with Omega_g = B'Omega_1 B, Omega_d its diagonal:
    # u = -(Omega_g Vbar + Psi + Omega_d (I - Vbar))^{-1} B'Omega_1 A x, written out here
    from packetloss_cvx.lq.recursion import input_weight, riccati_step

    rng = np.random.default_rng(5)
    s = random_system(rng, n=3, m=2, horizon=1, time_varying=False, non_stationary=False)
    mu, psi, W = s.mu_schedule[0], s.input_weights[0], s.state_weights[0]
    Og = s.B.T @ W @ s.B
    G = Og * mu[None, :] + np.diag(psi + np.diag(Og) * (1 - mu))
    K_ref = np.linalg.solve(G, s.B.T @ W @ s.A)
    d = np.diag(Og)[None]
    K, P0 = riccati_step(W[None], s.A, s.B, mu[None], input_weight(s, "udp", mu[None], d))
    np.testing.assert_allclose(K[0], K_ref, rtol=1e-12)
    # the cost-to-go: min over u of the UDP-like cost at x is x'P0 x (brute check at a random x)
    x = rng.normal(size=3)
    u = -K_ref @ x
    mean = s.A @ x + s.B @ (mu * u)
    value = mean @ W @ mean + np.sum(mu * psi * u * u) + np.sum(mu * (1 - mu) * np.diag(Og) * u * u)
    assert x @ P0[0] @ x == pytest.approx(value, rel=1e-12)


# ---------------------------------------------------------------- stationary long horizons

def _full_pass(monkeypatch, fn):
    """``fn()`` with the stationary closure switched off: every step of every backward pass and rollout."""
    import packetloss_cvx.lq.recursion as recursion

    with monkeypatch.context() as patch:
        patch.setattr(recursion, "STATIONARY_RUN", 10**9)
        return fn()


def _long(seed, N, **kw):
    s = random_system(np.random.default_rng(seed), n=4, m=2, horizon=N, spectral_radius=0.95, full_weights=True,
                      time_varying=False, non_stationary=False, edge_mu=False, **kw)
    return s


@pytest.mark.parametrize("protocol", PROTOCOLS)
@pytest.mark.parametrize(("mu", "noise"), [((1.0, 1.0), False), ((0.7, 0.3), True), ((1.0, 0.0), False)])
def test_stationary_tail_equals_the_full_pass(monkeypatch, protocol, mu, noise):
    s = System_with_mu = _long(3, 3000, noise=noise).with_mu(list(mu))
    closed = pl.closed_form(System_with_mu, protocol, "recursion")
    full = _full_pass(monkeypatch, lambda: pl.closed_form(s.with_mu(list(mu)), protocol, "recursion"))
    assert closed.cost == pytest.approx(full.cost, rel=1e-12, abs=0)
    np.testing.assert_allclose(closed.gain, full.gain, rtol=1e-12, atol=1e-13 * np.abs(full.gain).max())
    np.testing.assert_allclose(closed.inputs, full.inputs, rtol=0, atol=1e-12 * np.abs(full.inputs).max())
    # the plan rolled forward again (expected_cost's forward pass) gives its cost
    assert pl.expected_cost(s, closed.inputs, protocol) == pytest.approx(closed.cost, rel=1e-12)


def test_stationary_tail_gain_is_the_dare_gain():
    from scipy.linalg import solve_discrete_are

    s = _long(4, 10_000).with_mu([1.0, 1.0])
    sol = pl.closed_form(s, "tcp", "recursion")
    R = np.diag(s.input_weights[0])
    P = solve_discrete_are(s.A, s.B, s.state_weights[0], R)
    K = np.linalg.solve(R + s.B.T @ P @ s.B, s.B.T @ P @ s.A)
    np.testing.assert_allclose(sol.gain, K, rtol=1e-10)
    # J* = x0'(Q + A'PA - A'PB K) x0 up to the terminal effect, which has died out after 10^4 steps
    P0 = s.A.T @ P @ s.A - s.A.T @ P @ s.B @ K
    assert sol.cost == pytest.approx(float(s.x0 @ (s.initial_weight + P0) @ s.x0), rel=1e-10)


@pytest.mark.parametrize("which", ["weights", "mu", "input_weights"])
def test_time_varying_data_keep_the_full_pass(monkeypatch, which):
    """A step that differs (here the first, t = 0..2) forbids the closure: bit-equal to the full pass."""
    s = _long(5, 1000)
    data = s.to_dict()
    N = s.horizon
    if which == "weights":
        W = np.repeat(s.state_weights[:1], N, axis=0)
        W[1] *= 1.0 + 1e-9
        data["cost"].pop("state_weight", None)
        data["cost"]["state_weights"] = W.tolist()
    elif which == "input_weights":
        psi = np.repeat(s.input_weights[:1], N, axis=0)
        psi[2] *= 1.0 + 1e-9
        data["cost"].pop("input_weight", None)
        data["cost"]["input_weights"] = psi.tolist()
    else:
        mu = np.repeat(s.mu_schedule[:1], N, axis=0)
        mu[2, 0] *= 1.0 - 1e-9
        data["channel"].pop("mu", None)
        data["channel"]["mu_schedule"] = mu.tolist()
    from packetloss_cvx.lq.recursion import backward_pass, udp_variance_weights
    from packetloss_cvx.model.files import system_from_dict

    varying = system_from_dict(data)
    weights = udp_variance_weights(varying)                 # the same Lyapunov weights on both sides
    for protocol in PROTOCOLS:
        K, P0, _ = backward_pass(varying, protocol, weights)
        K_full, P0_full, _ = _full_pass(monkeypatch, lambda protocol=protocol: backward_pass(
            system_from_dict(varying.to_dict()), protocol, weights))
        np.testing.assert_array_equal(K, K_full)
        np.testing.assert_array_equal(P0, P0_full)
    K, _, _ = backward_pass(s, "tcp")                       # the stationary twin does close its tail:
    assert np.array_equal(K[1], K[N // 2])                  # one gain, copied
    assert not np.array_equal(K[1], K[-1])


def test_optimal_plan_is_the_backward_pass_rolled_out(monkeypatch):
    """optimal_plan (the rollout told where the closed run of one gain is) gives the floats of backward_pass then
    mean_trajectory (which search K for that run), with and without a closed tail; and with the closure switched
    off the same plan to 1e-12 (full pass, every step rolled out one by one). An unstable A (its stationary closed
    loop stable: rolled out by powers and a scan) included."""
    from packetloss_cvx.lq.recursion import backward_pass, mean_trajectory, optimal_plan
    from packetloss_cvx.model.files import system_from_dict

    unstable = random_system(np.random.default_rng(12), n=3, m=2, horizon=600, spectral_radius=1.05,
                             full_weights=True, time_varying=False, non_stationary=False, edge_mu=False)
    for s in (_long(8, 4000).with_mu([1.0, 1.0]), _long(9, 3000).with_mu([0.8, 0.4]), _long(10, 200),
              unstable.with_mu([0.9, 0.9])):
        for protocol in PROTOCOLS:
            K0, P0, noise, U, X = optimal_plan(s, protocol)
            K_ref, P0_ref, noise_ref = backward_pass(s, protocol)
            U_ref, X_ref = mean_trajectory(s, K_ref)
            np.testing.assert_array_equal(K0, K_ref[0])
            np.testing.assert_array_equal(P0, P0_ref)
            np.testing.assert_array_equal(U, U_ref)
            np.testing.assert_array_equal(X, X_ref)
            assert noise == noise_ref
            _, P0_full, _, U_full, _ = _full_pass(
                monkeypatch, lambda s=s, protocol=protocol: optimal_plan(system_from_dict(s.to_dict()), protocol))
            np.testing.assert_allclose(P0, P0_full, rtol=1e-12)
            np.testing.assert_allclose(U, U_full, rtol=0, atol=1e-12 * np.abs(U_full).max())


def test_a_state_that_underflowed_to_zero_stays_zero_only_under_finite_gains(monkeypatch):
    """A stable closed loop's mean state rolled out by powers underflows to exactly 0 after some hundreds of steps,
    and the rollout then writes zeros for the rest of the horizon: the plan and states of every step rolled out one
    by one (which linger in subnormal numbers, 1e-323, instead of reaching 0).
    A gain that is not finite after that point must still poison the plan (0 * inf is nan), never leave zeros."""
    from packetloss_cvx.lq.recursion import backward_pass, mean_states

    s = _long(11, 5000).with_mu([1.0, 1.0])
    K, _, _ = backward_pass(s, "tcp")
    mu, x = s.mu_schedule[None], s.x0[None]
    U = np.empty((1, s.horizon, s.m))
    X = mean_states(structure_of(s), mu, U, x, K[None])
    assert not X[0, -100:].any()                                 # the case in question: the state reached 0
    assert X[0, 0].any()
    U_steps = np.empty_like(U)
    X_steps = _full_pass(monkeypatch, lambda: mean_states(structure_of(s), mu, U_steps, x, K[None]))
    assert np.abs(X_steps[0, -100:]).max() < 1e-300             # step by step, the tail lingers in subnormals
    np.testing.assert_allclose(X, X_steps, rtol=0, atol=1e-13 * np.abs(X_steps).max())
    np.testing.assert_allclose(U, U_steps, rtol=0, atol=1e-13 * np.abs(U_steps).max())
    K_bad = K.copy()
    K_bad[-3] = np.inf
    X_bad = mean_states(structure_of(s), mu, np.empty_like(U), x, K_bad[None])
    assert np.isnan(X_bad[0, -2:]).all()
    assert not np.isnan(X_bad[0, :-3]).any()


#: The slowly converging plant: the paper's pendulum A (rho(A) = 1.06) with two inputs; its Riccati pass contracts
#: by about 0.98 a step and settles after about 1,600 steps.
SLOW_A = [[1.001, 0.005, 0.000, 0.000], [0.35, 1.001, -0.135, 0.000], [-0.001, 0.000, 1.001, 0.005],
          [-0.375, -0.001, 0.590, 1.001]]
SLOW_B = [[0.001, 0.2], [0.540, 0.0], [-0.002, 0.1], [-1.066, 0.3]]


def _slow(N, mu=(1.0, 1.0)):
    return pl.System(A=SLOW_A, B=SLOW_B, horizon=N, state_weight=[5, 1, 1, 1], input_weight=[2, 1], mu=list(mu),
                     x0=[0.1, 0, 0.1, 0])


def _solve_80bit(G, R):
    """G X = R by Gauss-Jordan elimination with partial pivoting, in the arrays' own precision."""
    m = G.shape[0]
    T = np.concatenate([G, R], axis=1)
    for k in range(m):
        p = k + int(np.argmax(np.abs(T[k:, k])))
        T[[k, p]] = T[[p, k]]
        T[k] = T[k] / T[k, k]
        for i in range(m):
            if i != k:
                T[i] = T[i] - T[i, k] * T[k]
    return T[:, m:]


def _tcp_riccati_80bit(s):
    """The TCP-like backward pass of Theorem 1 written out step by step in np.longdouble (80-bit on x86), every
    step: G = B'PB M + Psi, K = G^-1 B'PA, P- = A'PA - (B'PA)' M K + Omega. An independent reference."""
    ld = np.longdouble
    A, B = s.A.astype(ld), s.B.astype(ld)
    M, Psi = np.diag(s.mu_schedule[0].astype(ld)), np.diag(s.input_weights[0].astype(ld))
    P = s.state_weights[-1].astype(ld)
    K = np.empty((s.horizon, s.m, s.n), dtype=ld)
    for t in range(s.horizon - 1, -1, -1):
        rhs = B.T @ P @ A
        K[t] = _solve_80bit(B.T @ P @ B @ M + Psi, rhs)
        P = A.T @ P @ A - rhs.T @ M @ K[t] + (s.state_weights[t - 1].astype(ld) if t > 0 else 0)
        P = (P + P.T) / 2
    return K.astype(float), P.astype(float)


def _doubling_spy(monkeypatch):
    """Count the backward passes that went on by doubling (recursion._doubled_backward returning a result)."""
    import packetloss_cvx.lq.recursion as recursion

    calls = []
    original = recursion._doubled_backward

    def spy(*args):
        out = original(*args)
        calls.append(out is not None)
        return out

    monkeypatch.setattr(recursion, "_doubled_backward", spy)
    return calls


@pytest.mark.parametrize("mu", [(1.0, 1.0), (1.0, 0.0), (0.9, 0.6)])
@pytest.mark.parametrize("N", [300, 2000])
def test_doubled_backward_pass_meets_an_80_bit_pass(monkeypatch, mu, N):
    """The slowly converging plant's pass goes on by doubling after its first steps (at N = 300 it never settles:
    every step 1..N-1 by doubling and batched steps; at N = 2000 its tail closes after about 1,600): every gain
    and P_0 within PATH_AGREEMENT_RTOL of the 80-bit step-by-step pass (measured: 2.7e-14, 4.2e-14 under
    OPENBLAS_CORETYPE=Prescott; the float step-by-step pass is within 8.3e-14, 8.6e-14). mu = (1, 0) leaves one usable
    input: G = B M B' formed in floats would give every direction some control, 3.9e-13 (the reason the doubling keeps G
    as a factor)."""
    from packetloss_cvx.lq.recursion import backward_pass
    from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

    calls = _doubling_spy(monkeypatch)
    s = _slow(N, mu)
    K, P0, _ = backward_pass(s, "tcp")
    assert calls == [True]
    K_ref, P0_ref = _tcp_riccati_80bit(s)
    assert np.abs(K - K_ref).max() <= PATH_AGREEMENT_RTOL * np.abs(K_ref).max()
    assert np.abs(P0 - P0_ref).max() <= PATH_AGREEMENT_RTOL * np.abs(P0_ref).max()



@pytest.mark.parametrize("seed", range(12))
def test_doubling_composes_the_riccati_map_with_itself(seed):
    """recursion._doubling of Phi(P) = H + A'P (I + F F'P)^-1 A, four times over: the map it returns, applied to a
    random PSD P, is Phi applied 2^k times (Phi written out with a general solve), to PATH_AGREEMENT_RTOL of the
    largest entry (measured: 8.7e-15). Plants of one to five states and one to three columns of F (the factor
    compressed to n columns once it has more), stable and unstable A."""
    from packetloss_cvx.lq.recursion import _doubling
    from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

    def phi(A, F, H, P):
        return H + A.T @ P @ np.linalg.solve(np.eye(A.shape[0]) + F @ F.T @ P, A)

    rng = np.random.default_rng(seed)
    n, r = int(rng.integers(1, 6)), int(rng.integers(1, 4))
    A = rng.normal(size=(n, n))
    A *= rng.uniform(0.5, 1.2) / max(abs(np.linalg.eigvals(A)))
    F, X = rng.normal(size=(n, r)), rng.normal(size=(n, n))
    H = X @ X.T
    maps, steps = (A, F, H), 1
    for _ in range(4):
        maps, steps = _doubling(*maps), 2 * steps
        assert maps[1].shape[1] <= max(n, r)
        Y = rng.normal(size=(n, n))
        ref = P = Y @ Y.T
        for _ in range(steps):
            ref = phi(A, F, H, ref)
        assert np.abs(phi(*maps, P) - ref).max() <= PATH_AGREEMENT_RTOL * np.abs(ref).max()


def test_doubled_backward_pass_that_overflows_gives_the_pass_back(monkeypatch):
    """A pass of one map that cannot settle (mu = 0: no input reaches the plant, P grows like 4^t) is handed to
    doubling, whose powers overflow: it gives the pass back (None) and the step-by-step pass raises the overflow,
    as a NumericalError, instead of returning a cost that is not finite."""
    calls = _doubling_spy(monkeypatch)
    s = pl.System(A=[[2.0, 1.0], [0.0, 1.5]], B=[[1.0], [0.0]], horizon=2000, state_weight=[1.0, 1.0],
                  input_weight=[1.0], mu=[0.0], x0=[1.0, 1.0])
    with pytest.raises(pl.NumericalError, match="cost-to-go matrix overflowed"):
        pl.closed_form(s, "tcp", "recursion")
    assert calls == [False]

@pytest.mark.parametrize("seed", range(8))
def test_doubled_backward_pass_equals_the_step_by_step_pass(monkeypatch, seed):
    """Long horizons of one map (stable and unstable plants, mu at 0, fractional and 1, noise): backward_pass and
    closed_form by doubling (handed over at the pass's first chance, whatever it predicts) against the full
    step-by-step pass, to PATH_AGREEMENT_RTOL of each array's largest entry (costs, plans, every gain)."""
    import packetloss_cvx.lq.recursion as recursion
    from packetloss_cvx.lq.recursion import backward_pass
    from packetloss_cvx.model.files import system_from_dict
    from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

    monkeypatch.setattr(recursion, "DOUBLING_AFTER", -1)

    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 5)), int(rng.integers(1, 4))
    s = random_system(rng, n=n, m=m, horizon=int(rng.choice([300, 1500, 4000])), full_weights=True,
                      spectral_radius=float(rng.uniform(0.97, 1.08)), time_varying=False, non_stationary=False,
                      noise=seed % 2 == 1, edge_mu=seed % 4 == 2)
    if seed % 3 == 0:
        s = s.with_mu(np.ones(m))
    calls = _doubling_spy(monkeypatch)

    def close(a, b):
        return np.abs(np.asarray(a) - b).max() <= PATH_AGREEMENT_RTOL * np.abs(b).max()

    for protocol in PROTOCOLS:
        K, P0, _ = backward_pass(s, protocol)
        sol = pl.closed_form(s, protocol, "recursion")
        K_ref, P0_ref, _ = _full_pass(monkeypatch, lambda p=protocol: backward_pass(system_from_dict(s.to_dict()), p))
        ref = _full_pass(monkeypatch, lambda p=protocol: pl.closed_form(system_from_dict(s.to_dict()), p, "recursion"))
        for a, b in ((K, K_ref), (P0, P0_ref), (sol.cost, ref.cost), (sol.inputs, ref.inputs), (sol.gain, ref.gain)):
            assert close(a, b)
    assert calls
    assert all(calls)


def test_unstable_plant_under_a_stable_loop_is_rolled_out_by_powers_and_a_scan(monkeypatch):
    """The slowly converging plant (rho(A) = 1.06) at N = 2000: its tail closes after about 1,600 steps, so the
    plan is steps 1..~400 by powers of the stationary closed loop (stable) and the ~1,600 time-varying steps after
    them by a scan of their closed-loop products: plan, states and cost against every step rolled out one by one,
    to PATH_AGREEMENT_RTOL."""
    from packetloss_cvx.lq.recursion import optimal_plan
    from packetloss_cvx.model.files import system_from_dict
    from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

    s = _slow(2000)
    K0, P0, _, U, X = optimal_plan(s, "tcp")
    K0_ref, P0_ref, _, U_ref, X_ref = _full_pass(monkeypatch, lambda: optimal_plan(system_from_dict(s.to_dict()),
                                                                                   "tcp"))
    for a, b in ((K0, K0_ref), (P0, P0_ref), (U, U_ref), (X, X_ref)):
        assert np.abs(a - b).max() <= PATH_AGREEMENT_RTOL * np.abs(b).max()
    assert max(abs(np.linalg.eigvals(s.A))) > 1.05


@pytest.mark.parametrize("L", [1, 2, 5, 37, 64, 100])
def test_scan_of_time_varying_gains_equals_the_steps(L):
    """recursion._scanned_run (Blelloch's scan of the closed-loop products) against x_{t+1} = A x_t + B M_t u_t,
    u_t = -K_t x_t written out step by step, for three points at once, lengths that are and are not powers of two,
    time-varying channels and gains."""
    from packetloss_cvx.lq.recursion import _scanned_run
    from packetloss_cvx.tolerances import PATH_AGREEMENT_RTOL

    rng = np.random.default_rng(L)
    s = random_system(rng, n=3, m=2, horizon=L + 3, spectral_radius=1.1, time_varying=False)
    P, a, b = 3, 2, L + 2
    mu = rng.uniform(0.0, 1.0, (P, s.horizon, s.m))
    K = 0.3 * rng.normal(size=(P, s.horizon, s.m, s.n))
    x = rng.normal(size=(P, s.n))
    X, U = np.full((P, s.horizon, s.n), np.nan), np.full((P, s.horizon, s.m), np.nan)
    last = _scanned_run(s, mu, K, X, U, x.copy(), a, b)
    X_ref, U_ref, state = np.empty((P, L, s.n)), np.empty((P, L, s.m)), x
    for i, t in enumerate(range(a, b)):
        U_ref[:, i] = -np.einsum("pij,pj->pi", K[:, t], state)
        state = X_ref[:, i] = state @ s.A.T + (mu[:, t] * U_ref[:, i]) @ s.B.T
    assert np.abs(X[:, a:b] - X_ref).max() <= PATH_AGREEMENT_RTOL * np.abs(X_ref).max()
    assert np.abs(U[:, a:b] - U_ref).max() <= PATH_AGREEMENT_RTOL * np.abs(U_ref).max()
    np.testing.assert_array_equal(last, X[:, b - 1])
    assert np.isnan(X[:, :a]).all()                 # nothing outside steps a..b-1 written
    assert np.isnan(X[:, b:]).all()
    assert np.isnan(U[:, b:]).all()


def test_unstable_plant_under_an_unstable_run_is_rolled_out_step_by_step():
    """A run of one gain whose closed loop is unstable, on an unstable plant, is rolled out step by step: the
    plan rolled forward again open loop (mean_states without gains, as expected_cost does) meets its states to
    the bit. (A gain of zero: the run's loop is A itself.)"""
    from packetloss_cvx.lq.recursion import mean_states

    s = random_system(np.random.default_rng(3), n=3, m=2, horizon=400, spectral_radius=1.02, time_varying=False)
    mu, x = s.mu_schedule[None], s.x0[None]
    K = np.zeros((1, s.horizon, s.m, s.n))
    K[0, 0] = K[0, -1] = 0.1                       # a run of one gain over steps 1..N-2
    U = np.empty((1, s.horizon, s.m))
    X = mean_states(structure_of(s), mu, U, x, K)
    np.testing.assert_array_equal(mean_states(structure_of(s), mu, U, x), X)


def test_lyapunov_weights_close_their_tail_only_for_a_stable_plant(monkeypatch):
    from packetloss_cvx.lq.recursion import udp_variance_weights
    from packetloss_cvx.model.files import system_from_dict

    stable = _long(6, 2000, noise=True)
    d, noise = udp_variance_weights(stable)
    d_full, noise_full = _full_pass(monkeypatch, lambda: udp_variance_weights(system_from_dict(stable.to_dict())))
    np.testing.assert_allclose(d, d_full, rtol=1e-13)
    assert noise == pytest.approx(noise_full, rel=1e-12)
    # by hand: far from the end, S_t is the Lyapunov solution S = Omega + A'SA
    from scipy.linalg import solve_discrete_lyapunov

    S = solve_discrete_lyapunov(stable.A.T, stable.state_weights[0])
    np.testing.assert_allclose(d[0], np.diag(stable.B.T @ S @ stable.B), rtol=1e-10)
    unstable = random_system(np.random.default_rng(7), n=3, m=2, horizon=300, spectral_radius=1.02,
                             time_varying=False, noise=True)
    d, noise = udp_variance_weights(unstable)
    d_full, noise_full = _full_pass(monkeypatch, lambda: udp_variance_weights(system_from_dict(unstable.to_dict())))
    np.testing.assert_array_equal(d, d_full)
    assert noise == noise_full


def test_drift_is_weighed_only_where_a_tail_can_close(monkeypatch):
    """The Lyapunov sums of an unstable plant never settle (q = rho(A)^2 >= 1) and the UDP-like pass of an unstable
    plant with mu < 1 has a different added diagonal at every step (it grows with the sums): neither weighs its
    drift at any step. Their stable twins (and the TCP-like pass, one map) do."""
    import packetloss_cvx.lq.recursion as recursion
    import packetloss_cvx.lq.structure as structure
    from packetloss_cvx.model.files import system_from_dict


    weighed = {"sum": 0, "pass": 0}
    small_change, drift = structure.small_change, recursion._drift

    def count(name, fn):
        def counted(*args):
            weighed[name] += 1
            return fn(*args)
        return counted

    monkeypatch.setattr(structure, "small_change", count("sum", small_change))
    monkeypatch.setattr(recursion, "_drift", count("pass", drift))
    for rho, protocol, expected in ((1.05, "udp", 0), (1.05, "tcp", 1), (0.95, "udp", 1)):
        s = random_system(np.random.default_rng(1), n=4, m=2, horizon=1000, spectral_radius=rho, time_varying=False,
                          non_stationary=False, noise=True).with_mu([0.8, 0.5])
        weighed.update({"sum": 0, "pass": 0})
        pl.closed_form(system_from_dict(s.to_dict()), protocol, "recursion")
        assert (weighed["pass"] > 0) == bool(expected)
        if protocol == "udp":
            assert (weighed["sum"] > 0) == bool(expected)


def test_lyapunov_cross_weights_share_the_variance_weights_kernel():
    """``B'S_tA`` (the exact Markov cost's cross term) from the same backward sum as ``diag(B'S_tB)``: the dense
    ``Omega_gp`` block t is ``B'S_t A^(t+1)`` (time-varying weights), and a long stable horizon closes to the
    Lyapunov solution."""
    from scipy.linalg import solve_discrete_lyapunov

    from packetloss_cvx.lq.prediction import prediction
    from packetloss_cvx.lq.recursion import lyapunov_cross_weights, udp_variance_weights

    short = random_system(np.random.default_rng(11), n=3, m=2, horizon=12, spectral_radius=1.05, time_varying=True,
                          noise=True)
    d, noise, BSA = lyapunov_cross_weights(short)
    d_ref, noise_ref = udp_variance_weights(short)
    np.testing.assert_array_equal(d, d_ref)
    assert noise == noise_ref
    Ogp = prediction(short).Omega_gp
    for t in range(short.horizon):
        np.testing.assert_allclose(BSA[t] @ np.linalg.matrix_power(short.A, t), Ogp[2 * t:2 * t + 2], rtol=1e-10,
                                   atol=1e-12 * np.abs(Ogp).max())
    stable = _long(6, 2000, noise=True)
    d, _, BSA = lyapunov_cross_weights(stable)
    S = solve_discrete_lyapunov(stable.A.T, stable.state_weights[0])
    np.testing.assert_allclose(BSA[0], stable.B.T @ S @ stable.A, rtol=1e-10, atol=1e-12 * np.abs(BSA[0]).max())
    np.testing.assert_array_equal(d, udp_variance_weights(stable)[0])


def test_a_point_answers_the_same_in_any_batch_below_flat_min():
    """The brute-force allocator reads a repeated point back instead of evaluating it again: a point's gains
    and cost-to-go must not depend on the batch it is in (a batch of one takes LAPACK's gesv directly)."""
    from packetloss_cvx.lq.recursion import FLAT_MIN, backward_batch, input_weight

    rng = np.random.default_rng(11)
    for _ in range(20):
        s = random_system(rng)
        mus = rng.uniform(0.0, 1.0, (5, s.horizon, s.m))
        d = np.abs(rng.normal(size=(s.horizon, s.m)))
        added = input_weight(s, "udp", mus, d)
        K5, P5 = backward_batch(structure_of(s), "udp", mus, added)
        for k in range(5):
            K1, P1 = backward_batch(structure_of(s), "udp", mus[k:k + 1], added[k:k + 1])
            np.testing.assert_array_equal(K1[0], K5[k])
            np.testing.assert_array_equal(P1[0], P5[k])
    assert FLAT_MIN > 5


@pytest.mark.parametrize("seed", range(4))
def test_least_squares_riccati_step_against_delivery_pattern_enumeration(seed):
    """The homogeneous step (no weights, loss variance weighted by P, Hessian possibly singular) that
    simulation.region runs through riccati_step: against
    E_v[(A - BVK)'P(A - BVK)] enumerated over the 2^m delivery patterns (its Hessian and linear term summed pattern
    by pattern, the minimum-norm minimiser by lstsq, the minimum evaluated as that sum). Points with mu_i in {0, 1}
    and rank-deficient P make the Hessian singular."""
    import itertools

    from packetloss_cvx.lq.recursion import riccati_step
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 4)), int(rng.integers(1, 4))
    A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
    points = []
    for case in range(6):
        root = rng.normal(size=(n, n if case % 2 else 1))
        mu = rng.uniform(size=m)
        if case >= 2:
            mu[rng.integers(m)] = float(case % 3 == 0)
        points.append((root @ root.T, mu))
    P = np.array([p for p, _ in points])
    mu = np.array([u for _, u in points])
    K, R = riccati_step(P, A, B, mu, np.zeros_like(mu), variance=True, least_squares=True)
    for g, (Pg, mug) in enumerate(points):
        H, rhs = np.zeros((m, m)), np.zeros((m, n))
        patterns = []
        for v in itertools.product([0.0, 1.0], repeat=m):
            v = np.array(v)
            prob = float(np.prod(np.where(v == 1, mug, 1 - mug)))
            BV = B * v
            H += prob * BV.T @ Pg @ BV
            rhs += prob * BV.T @ Pg @ A
            patterns.append((prob, BV))
        K_ref = np.linalg.lstsq(H, rhs, rcond=None)[0]

        def cost(gain, Pg=Pg, patterns=patterns):
            return sum(prob * (A - BV @ gain).T @ Pg @ (A - BV @ gain) for prob, BV in patterns)

        scale = max(1.0, float(np.abs(cost(K_ref)).max()), float(np.abs(K_ref).max()) ** 2)
        assert np.allclose(R[g], cost(K_ref), atol=1e-10 * scale)
        assert np.allclose(cost(K[g]), cost(K_ref), atol=1e-10 * scale)
        assert np.allclose(K[g], K_ref, atol=1e-8 * max(1.0, float(np.abs(K_ref).max())))


@pytest.mark.parametrize("q", [0.01, 0.5, 0.99])
@pytest.mark.parametrize(("factor", "closed"), [(3.0, False), (0.3, True)])
def test_a_stationary_tail_closes_when_its_remaining_drift_is_below_stationary_rtol(q, factor, closed):
    """stationary_close's band: the last change times the remaining geometric sum q / (1 - q) against
    STATIONARY_RTOL times the iterate's size. A change that leaves factor STATIONARY_RTOL to come (by hand: change
    = factor STATIONARY_RTOL size (1 - q) / q) closes at 0.3 and not at 3, for slow and fast contractions alike, in
    a batch as for one point; never at q >= 1."""
    from packetloss_cvx.lq.recursion import stationary_close
    from packetloss_cvx.tolerances import STATIONARY_RTOL

    size = 7.0
    change = factor * STATIONARY_RTOL * size * (1 - q) / q
    new = np.diag([size, 1.0])
    old = new.copy()
    old[0, 1] = old[1, 0] = change
    assert stationary_close(new, old, q) is closed
    batch_new, batch_old = np.stack([new, 2 * new]), np.stack([old, 2 * new])
    assert stationary_close(batch_new, batch_old, np.array([q, q])) is closed
    assert stationary_close(new, new, 1.0) is False
