"""The dynamic-programming optimum (closedloop/riccati.py) against scipy's DARE, the scalar critical
probability, the modified Riccati equation written out (Schenato et al. 2007), forward second moments and the
receding-horizon laws."""

import math

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from packetloss_cvx import NumericalError, System, closed_form
from packetloss_cvx.closedloop.moments import closed_loop, finite_horizon_costs, law_cost_to_go
from packetloss_cvx.closedloop.riccati import NO_SOLUTION, dp_finite_horizon, dp_riccati
from packetloss_cvx.closedloop.stability import mean_square_radius
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.tolerances import MOMENT_RESIDUAL_RTOL, RICCATI_DIVERGENCE

from ..references import enumerated_radius


def modified_riccati_residual(P, A, B, mu, Omega, psi):
    """P - (Omega + A'PA - A'PBM (M Psi + M B'PB M + D(P))^-1 M B'PA), written out term by term (mu > 0)."""
    M = np.diag(mu)
    BPB = B.T @ P @ B
    D = np.diag(mu * (1 - mu) * np.diag(BPB))
    H = M @ np.diag(psi) + M @ BPB @ M + D
    return P - (Omega + A.T @ P @ A - A.T @ P @ B @ M @ np.linalg.solve(H, M @ B.T @ P @ A))


@pytest.mark.parametrize("seed", range(8))
def test_equals_scipy_dare_at_mu_one(seed):
    s = random_system(np.random.default_rng(seed), non_stationary=False, edge_mu=False)
    s = s.with_mu(np.ones(s.m))
    dp = dp_riccati(s)
    P = solve_discrete_are(s.A, s.B, s.state_weights[0], np.diag(s.input_weights[0]))
    assert np.allclose(dp.cost_to_go, P, rtol=1e-8, atol=1e-10 * np.abs(P).max())


@pytest.mark.parametrize("seed", range(8))
def test_solves_the_modified_riccati_equation_written_out_and_stabilises(seed):
    s = random_system(np.random.default_rng(100 + seed), non_stationary=False, edge_mu=False)
    dp = dp_riccati(s)
    r = modified_riccati_residual(dp.cost_to_go, s.A, s.B, s.mu, s.state_weights[0], s.input_weights[0])
    assert np.abs(r).max() <= 1e-9 * np.abs(dp.cost_to_go).max()
    assert dp.spectral_radius < 1
    assert dp.spectral_radius == pytest.approx(mean_square_radius(s.A, s.B, dp.gain, s.mu))


@pytest.mark.parametrize("a", [1.2, 2.0, 3.0])
def test_scalar_critical_probability(a):
    critical = 1 - 1 / a ** 2

    def system(mu):
        return System(A=[[a]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[0.5], mu=[mu], x0=[1.0])
    dp = dp_riccati(system(critical + 0.01))
    assert dp.spectral_radius < 1
    with pytest.raises(NumericalError, match="no stabilising solution"):
        dp_riccati(system(critical - 0.01))
    # no gain at all stabilises below it: min_k (a - mu k)^2 + mu (1 - mu) k^2 = a^2 (1 - mu) at k = a
    mu = critical - 0.01
    assert min(mean_square_radius([[a]], [[1.0]], [[k]], [mu]) for k in np.linspace(0, 2 * a, 401)) > 1


@pytest.mark.parametrize(("q", "b"), [(1.0, 1.0), (1e-200, 1.0), (1e-300, 1.0), (1e-300, 1e100), (1.0, 1e-100),
                                    (1e-20, 1e-100)])
def test_scalar_solution_by_hand_at_any_scale(q, b):
    """a = 1.2, mu = 0.8, psi = 1: G = psi + b^2 P, so P = q + a^2 P - mu a^2 b^2 P^2 / (psi + b^2 P), the positive
    root of b^2 (1 - a^2 + mu a^2) P^2 + (psi (1 - a^2) - q b^2) P - q psi = 0 (no cancellation: both terms of the
    numerator are positive). A state weight of 1e-200 once stopped the iteration at its first step (the Frobenius
    norm of a 1e-200 matrix squared its entries to 0.0); B = 1e-100 (P about 1e200) was called "no stabilising
    solution" (the divergence test ignored B)."""
    a, mu, psi = 1.2, 0.8, 1.0
    alpha, beta = b * b * (1 - a * a + mu * a * a), psi * (1 - a * a) - q * b * b
    P = (-beta + math.sqrt(beta * beta + 4 * alpha * q * psi)) / (2 * alpha)
    s = System(A=[[a]], B=[[b]], horizon=1, state_weight=[q], input_weight=[psi], mu=[mu], x0=[1.0])
    dp = dp_riccati(s)
    assert dp.cost_to_go[0, 0] == pytest.approx(P, rel=MOMENT_RESIDUAL_RTOL)
    assert dp.gain[0, 0] == pytest.approx(a * b * P / (psi + b * b * P), rel=MOMENT_RESIDUAL_RTOL)
    assert dp.spectral_radius < 1


def test_a_cost_to_go_beyond_double_precision_is_refused_not_called_unstabilisable():
    """B = 1e-160 puts P near 1e320: no room to tell divergence from convergence, which is not "no solution"."""
    s = System(A=[[1.2]], B=[[1e-160]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.8], x0=[1.0])
    with pytest.raises(NumericalError, match="leaves no room in double precision") as err:
        dp_riccati(s)
    assert not str(err.value).startswith(NO_SOLUTION)


def test_unobserved_unstable_mode_has_no_stabilising_solution():
    s = System(A=[[1.5, 0], [0, 0.5]], B=[[0.0], [1.0]], horizon=2, state_weight=[0.0, 1.0],
               input_weight=[1.0], mu=[0.9], x0=[1.0, 1.0])
    with pytest.raises(NumericalError, match="stabilising"):
        dp_riccati(s)


def test_dp_no_worse_than_receding_horizon_laws_on_random_systems():
    rng = np.random.default_rng(2026)
    compared = 0
    for _ in range(300):
        s = random_system(rng, non_stationary=False, time_varying=False)     # a loop's cost has one weight
        try:
            dp = dp_riccati(s)
        except NumericalError:
            continue   # no stabilising law exists: every law has infinite cost
        for p in ("tcp", "udp"):
            loop = closed_loop(s, closed_form(s, p, method="recursion").gain)
            if not loop.stable:
                continue
            gap = np.linalg.eigvalsh(loop.cost_to_go - dp.cost_to_go).min()   # P_K - P >= 0
            assert gap >= -1e-9 * np.abs(dp.cost_to_go).max()
            assert loop.average_stage_cost >= dp.average_stage_cost * (1 - 1e-9)
            compared += 1
    assert compared > 300


def test_finite_horizon_cost_equals_forward_moments_and_beats_other_gains():
    s = random_system(np.random.default_rng(5), n=3, m=2, non_stationary=False, noise=True, spectral_radius=1.1)
    T = 25
    gains, P0, cost = dp_finite_horizon(s, T)
    stage, terminal = finite_horizon_costs(s, gains, T)
    assert stage.sum() + terminal == pytest.approx(cost, rel=1e-10)
    stationary = dp_riccati(s).gain
    for K in (stationary, stationary * 1.05, closed_form(s, "udp").gain):
        other, term = finite_horizon_costs(s, K, T)
        assert other.sum() + term >= cost * (1 - 1e-12)
    # the time-varying gains approach the stationary one far from the end
    long, _, _ = dp_finite_horizon(s, 300)
    assert np.allclose(long[0], stationary, rtol=1e-8, atol=1e-10)


def test_policy_cost_to_go_of_dp_gain_is_its_solution(two_actuator):
    dp = dp_riccati(two_actuator)
    P = law_cost_to_go(two_actuator.A, two_actuator.B, dp.gain, two_actuator.mu, two_actuator.state_weights[0],
                       two_actuator.input_weights[0])
    assert np.allclose(P, dp.cost_to_go, rtol=1e-10)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dp_input_hessian_is_the_expectation_over_the_delivery_patterns(seed):
    """dp_input_hessian against E[V Psi V + V B'PB V] enumerated over the 2^m delivery patterns V = diag(v), each v_i
    delivered with probability mu_i independently (the expectation written out, not the closed form)."""
    import itertools

    from packetloss_cvx.closedloop.riccati import dp_input_hessian

    rng = np.random.default_rng(seed)
    n, m = 3, 3
    B = rng.normal(size=(n, m))
    X = rng.normal(size=(n, n))
    P = X @ X.T + np.eye(n)
    mu = rng.uniform(0.05, 0.95, size=m)
    psi = rng.uniform(0.1, 2.0, size=m)
    expected = np.zeros((m, m))
    for v in itertools.product([0.0, 1.0], repeat=m):
        V = np.diag(v)
        probability = np.prod(np.where(np.array(v) == 1.0, mu, 1.0 - mu))
        expected += probability * (V @ np.diag(psi) @ V + V @ B.T @ P @ B @ V)
    assert np.allclose(dp_input_hessian(B, P, mu, psi), expected, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("gap", [1e-2, 1e-3, 1e-4])
def test_started_from_a_stabilising_gain_is_the_same_solution(gap):
    # scalar a = 2, b = w = psi = 1, mu = 3/4 + gap: by hand p solves b^2 (1 - a^2 + mu a^2) p^2
    # + (psi (1 - a^2) - w b^2) p - w psi = 0 (the equation times psi + b^2 p); the gain k = a is stabilising
    # (radius a^2 (1 - mu) = 1 - 4 gap), and the policy iteration from it skips the value iteration
    a, mu = 2.0, 0.75 + gap
    s = System(A=[[a]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])
    c2, c1, c0 = 1 - a * a + mu * a * a, (1 - a * a) - 1, -1.0
    p = (-c1 + np.sqrt(c1 * c1 - 4 * c2 * c0)) / (2 * c2)
    cold, started = dp_riccati(s), dp_riccati(s, gain=[[a]])
    assert started.cost_to_go[0, 0] == pytest.approx(p, rel=1e-9)
    assert cold.cost_to_go[0, 0] == pytest.approx(p, rel=1e-9)
    assert started.iterations < cold.iterations
    assert started.spectral_radius == pytest.approx(mean_square_radius(s.A, s.B, started.gain, s.mu))


def test_a_start_that_is_not_stabilising_or_sees_no_unstable_mode_is_ignored():
    # k = 0.5 leaves radius (2 - 0.9 * 0.5)^2 + 0.09 * 0.25 > 1: the value iteration runs as without it
    s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    assert dp_riccati(s, gain=[[0.5]]).cost_to_go[0, 0] == dp_riccati(s).cost_to_go[0, 0]
    # Omega does not see the unstable mode: the DP optimum leaves it alone (no stabilising solution), and a
    # stabilising start must not turn that into Hewer's stabilising solution
    s = System(A=[[1.5, 0], [0, 0.5]], B=[[1.0], [1.0]], horizon=2, state_weight=[0.0, 1.0],
               input_weight=[1.0], mu=[0.9], x0=[1.0, 1.0])
    K = np.array([[1.5, 0.0]])
    assert mean_square_radius(s.A, s.B, K, s.mu) < 1
    with pytest.raises(NumericalError, match="stabilising"):
        dp_riccati(s, gain=K)


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_final_residual_check_refuses_3_and_keeps_0_3_times_moment_residual_rtol(monkeypatch, factor, kept):
    """The check after the iterations, one more step of the modified Riccati map from the answer P, sees a relative
    residual ||step(P) - P|| / ||P|| of factor MOMENT_RESIDUAL_RTOL (planted on that step; the iterations stop at
    RICCATI_RTOL, 1000 times below): NumericalError at 3, the hand value at 0.3 (scalar a = 2, mu = 0.8: p solves the
    quadratic of test_started_from_a_stabilising_gain_is_the_same_solution)."""
    import packetloss_cvx.closedloop.riccati as riccati_module
    from packetloss_cvx.tolerances import MOMENT_RESIDUAL_RTOL

    a, mu = 2.0, 0.8
    s = System(A=[[a]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[mu], x0=[1.0])
    c2, c1, c0 = 1 - a * a + mu * a * a, (1 - a * a) - 1, -1.0
    p = (-c1 + np.sqrt(c1 * c1 - 4 * c2 * c0)) / (2 * c2)
    answer = dp_riccati(s).cost_to_go.copy()
    real = riccati_module.modified_riccati_step

    def step(P, *args):
        K, new = real(P, *args)
        if np.array_equal(P, answer):                   # the check's step (no iteration starts from the answer)
            new = new + factor * MOMENT_RESIDUAL_RTOL * np.linalg.norm(P)
        return K, new

    monkeypatch.setattr(riccati_module, "modified_riccati_step", step)
    if kept:
        got = dp_riccati(s)
        assert got.cost_to_go[0, 0] == pytest.approx(p, rel=1e-9)
        assert got.residual == pytest.approx(factor * MOMENT_RESIDUAL_RTOL, rel=0.01)
    else:
        with pytest.raises(NumericalError, match="modified Riccati equation: relative residual 3.0e-09"):
            dp_riccati(s)


def test_a_large_optimum_past_the_divergence_check_is_solved_not_denied():
    """A = 1.001 I4 + N (one Jordan block), b = e4, mu = 0.0186: mu is in S (Elia: (1 - mu) 1.001^8 < 1), and the
    DP optimum has ||P|| = 2e16, past RICCATI_DIVERGENCE times the weights (2e14), where growth had been read as "no
    stabilising solution". Growth proves nothing: the iteration goes on until its greedy law stabilises and the
    policy iteration ends it. Checked: the gain's radius by enumeration, and the equation's own residual."""
    A = 1.001 * np.eye(4) + np.eye(4, k=1)
    s = System(A=A, B=np.eye(4)[:, 3:], horizon=2, state_weight=[1.0] * 4, input_weight=[1.0], mu=[0.0186],
               x0=[1.0] * 4)
    dp = dp_riccati(s)
    assert float(np.linalg.norm(dp.cost_to_go)) > RICCATI_DIVERGENCE * 2.0
    assert enumerated_radius(s.A, s.B, dp.gain, [0.0186]) < 1.0
    residual = modified_riccati_residual(dp.cost_to_go, s.A, s.B, np.array([0.0186]), np.eye(4), np.ones(1))
    assert float(np.linalg.norm(residual)) <= 1e-9 * float(np.linalg.norm(dp.cost_to_go))


@pytest.mark.parametrize(("A", "B", "mu"), [
    ([[2.0]], [[1.0]], 0.5),                                  # every law's radius >= a^2 (1 - mu) = 2
    ([[2.0, 1.0], [0.0, 0.5]], [[0.6], [-0.2]], 0.3),         # x'A = 2 x' for x = (3, 2): radius >= 4 (0.7) = 2.8
    ([[0.5, 1.0], [0.0, 1.2]], [[1.0], [0.0]], 0.9),          # x2+ = 1.2 x2 whatever the law: radius >= 1.44
])
def test_no_stabilising_solution_is_said_with_its_proof(A, B, mu):
    """Below the critical probability (hand bounds in the parameters) the value iteration diverges and its direction
    proves every law's radius >= 1 in exact arithmetic (certificates.no_law_proved; the rank-one direction of the
    second plant only tilted, the third's only with its exact zeros): the reason starts with NO_SOLUTION."""
    n = len(A)
    s = System(A=A, B=B, horizon=2, state_weight=[1.0] * n, input_weight=[1.0], mu=[mu], x0=[1.0] * n)
    with pytest.raises(NumericalError, match="exact arithmetic") as err:
        dp_riccati(s)
    assert str(err.value).startswith(NO_SOLUTION)
