"""Mean-square stability and exact closed-loop costs (simulation/stability.py, simulation/moments.py).

References: the second-moment operator built by enumerating every delivery pattern (2^m of them),
scalar hand formulas, fixed-point sums, and plain sampled loops (within 4 standard errors).
"""

import itertools

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx import InputError, System, closed_form, load_example
from packetloss_cvx.closedloop.critical import critical_mu
from packetloss_cvx.closedloop.moments import (
    closed_loop,
    finite_horizon_costs,
    law_cost_to_go,
    stationary_second_moment,
)
from packetloss_cvx.closedloop.riccati import dp_finite_horizon, dp_riccati
from packetloss_cvx.closedloop.stability import is_mean_square_stable, mean_square_radius
from packetloss_cvx.model.twins import bursty_twin
from packetloss_cvx.tolerances import ROUNDING_ORDER_RTOL

from ..references import enumerated_operator


def random_law(rng, n, m, scale=0.3):
    A = rng.normal(size=(n, n)) / np.sqrt(n)
    B = rng.normal(size=(n, m))
    K = rng.normal(size=(m, n)) * scale
    return A, B, K, rng.uniform(0.05, 1.0, m)


@pytest.mark.parametrize("seed", range(6))
def test_radius_matches_enumerated_kronecker(seed):
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 6)), int(rng.integers(1, 4))
    A, B, K, mu = random_law(rng, n, m)
    reference = float(np.max(np.abs(np.linalg.eigvals(enumerated_operator(A, B, K, mu)))))
    assert mean_square_radius(A, B, K, mu, method="kronecker") == pytest.approx(reference, rel=1e-10)
    if n >= 3:
        assert mean_square_radius(A, B, K, mu, method="krylov") == pytest.approx(reference, rel=1e-10)


@pytest.mark.parametrize("seed", range(3))
def test_krylov_matches_kronecker_at_n_25(seed):
    A, B, K, mu = random_law(np.random.default_rng(10 + seed), 25, 3, scale=0.2)
    assert mean_square_radius(A, B, K, mu, "krylov") == pytest.approx(mean_square_radius(A, B, K, mu, "kronecker"),
                                                                       rel=1e-10)


def test_scalar_radius_hand_formula():
    a, k, mu = 1.5, 1.0, 0.3
    assert mean_square_radius([[a]], [[1.0]], [[k]], [mu]) == pytest.approx((a - mu * k) ** 2 + mu * (1 - mu) * k ** 2)


def test_bad_shapes_are_named():
    with pytest.raises(InputError, match="gain"):
        mean_square_radius(np.eye(2), np.ones((2, 1)), np.ones((2, 2)), [0.5])
    with pytest.raises(InputError, match="mu"):
        mean_square_radius(np.eye(2), np.ones((2, 1)), np.ones((1, 2)), [1.5])


def test_stationary_moment_and_cost_to_go_against_fixed_point_sums():
    rng = np.random.default_rng(3)
    for n in (3, 32):   # dense LU and GMRES
        A, B, K, mu = random_law(rng, n, 2, scale=0.1)
        A *= 0.8 / max(1e-9, mean_square_radius(A, B, K, mu)) ** 0.5
        F = rng.normal(size=(n, n))
        Sigma = F @ F.T / n
        S = stationary_second_moment(A, B, K, mu, Sigma)
        term, total = Sigma.copy(), Sigma.copy()
        Lmat = enumerated_operator(A, B, K, mu) if n <= 4 else None
        for _ in range(400):   # sum_k L^k(Sigma), radius <= 0.8
            Abar = A - B @ np.diag(mu) @ K
            c = mu * (1 - mu) * np.einsum("ij,jk,ik->i", K, term, K)
            term = Abar @ term @ Abar.T + B @ np.diag(c) @ B.T
            total += term
        assert np.allclose(S, total, rtol=1e-9, atol=1e-12 * np.abs(total).max())
        if Lmat is not None:
            assert np.allclose(S.ravel(), np.linalg.solve(np.eye(n * n) - Lmat, Sigma.ravel()), rtol=1e-10)
        Omega, psi = np.eye(n), np.ones(2)
        P = law_cost_to_go(A, B, K, mu, Omega, psi)
        # duality: tr(P Sigma) = tr((Omega + K'M Psi K) S)
        assert np.sum(P * Sigma) == pytest.approx(np.sum((Omega + K.T @ np.diag(mu * psi) @ K) * S), rel=1e-9)


def test_pendulum_loops_are_not_mean_square_stable(pendulum):
    for p in ("tcp", "udp"):
        loop = closed_loop(pendulum, closed_form(pendulum, p).gain, p)
        assert not loop.stable
        assert loop.spectral_radius > 1
        assert loop.average_stage_cost == np.inf
        assert "not mean-square stable" in loop.reason


def test_non_stationary_channel_is_refused():
    s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0],
               mu_schedule=[[0.5], [0.9]], x0=[1.0])
    with pytest.raises(InputError, match="mu_schedule"):
        closed_loop(s, [[0.5]])


def sampled_stage_costs(system, K, steps, samples, seed):
    """A plain sampled loop (one array op per step): per-run mean stage cost over t < steps."""
    rng = np.random.default_rng(seed)
    Omega, psi, mu = system.state_weights[0], system.input_weights[0], system.mu
    L = np.linalg.cholesky(system.noise_cov + 1e-300 * np.eye(system.n)) if system.noise_cov.any() else None
    X = np.repeat(system.x0[None], samples, axis=0)
    total = np.zeros(samples)
    for _ in range(steps):
        V = rng.random((samples, system.m)) < mu
        applied = V * (-X @ K.T)
        total += np.einsum("si,ij,sj->s", X, Omega, X) + np.sum(psi * applied ** 2, axis=1)
        X = X @ system.A.T + applied @ system.B.T
        if L is not None:
            X = X + rng.standard_normal((samples, system.n)) @ L.T
    return total / steps


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_exact_finite_cost_against_sampling(two_actuator, protocol):
    s = System(A=two_actuator.A, B=two_actuator.B, horizon=two_actuator.horizon, state_weight=[1.0, 1.0],
               input_weight=[1.0, 1.0], mu=[0.9, 0.5], x0=[1.0, -1.0], noise_cov=[[0.2, 0.05], [0.05, 0.1]])
    K = closed_form(s, protocol).gain
    steps, samples = 30, 40000
    stage, _ = finite_horizon_costs(s, K, steps)
    sampled = sampled_stage_costs(s, K, steps, samples, seed=7)
    se = sampled.std(ddof=1) / np.sqrt(samples)
    assert abs(sampled.mean() - stage.mean()) < 4 * se
    # long horizons approach the stationary cost, computed by a linear solve
    long, _ = finite_horizon_costs(s, K, 400)
    assert long[-1] == pytest.approx(closed_loop(s, K).average_stage_cost, rel=1e-9)


def test_verdict_against_sampling_stable_and_unstable():
    a = 1.5
    base = System(A=[[a]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.3], x0=[1.0])
    K = np.array([[1.0]])
    unstable = closed_loop(base, K)                  # (1.5 - 0.3)^2 + 0.21 = 1.65
    stable = closed_loop(base.with_mu([0.9]), K)     # (0.6)^2 + 0.09 = 0.45
    assert unstable.spectral_radius == pytest.approx(1.65)
    assert not unstable.stable
    assert stable.spectral_radius == pytest.approx(0.45)
    assert stable.stable
    rng = np.random.default_rng(0)
    for loop, system in ((unstable, base), (stable, base.with_mu([0.9]))):
        x = np.ones(20000)
        for _ in range(12):
            x = (a - (rng.random(x.size) < system.mu[0]) * K[0, 0]) * x
        second = np.mean(x ** 2)
        se = np.std(x ** 2, ddof=1) / np.sqrt(x.size)
        assert abs(second - loop.spectral_radius ** 12) < 4 * se   # scalar: E x_t^2 = radius^t
        assert (second > 1) == (not loop.stable)


def test_margin_near_one_is_not_called_stable():
    assert not is_mean_square_stable(1.0 - 1e-12)
    assert is_mean_square_stable(0.999)
    assert not is_mean_square_stable(float("nan"))


def test_to_dict_has_no_inf():
    s = load_example("pendulum")
    d = closed_loop(s, np.zeros((1, 4))).to_dict()
    assert d["average_stage_cost"] is None
    assert d["stable"] is False


def test_critical_mu_scalar_fixed_gain_and_redesigned():
    from packetloss_cvx.closedloop.critical import critical_mu
    a = 2.0
    s = System(A=[[a]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    # fixed k = a: radius a^2 (1 - mu) < 1 iff mu > 1 - 1/a^2
    assert critical_mu(s, [[a]]).mu == pytest.approx([1 - 1 / a ** 2], abs=2e-6)
    assert critical_mu(s, "dp").t == pytest.approx(1 - 1 / a ** 2, abs=2e-6)
    # a receding-horizon law is one law: it cannot need less than the DP law
    for p in ("tcp", "udp"):
        assert critical_mu(s, p).t >= 1 - 1 / a ** 2 - 1e-6
    assert critical_mu(s, [[0.0]]).t == np.inf


def test_critical_mu_and_finite_costs_reject_bad_input():
    from packetloss_cvx.closedloop.critical import critical_mu
    s = System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    with pytest.raises(InputError, match="direction"):
        critical_mu(s, "dp", direction=[0.0])
    with pytest.raises(InputError, match="law"):
        critical_mu(s, "mpc")
    with pytest.raises(InputError, match="steps"):
        finite_horizon_costs(s, [[1.0]], 0)
    with pytest.raises(InputError, match="gains"):
        finite_horizon_costs(s, np.ones((3, 1, 1)), 4)


@pytest.mark.parametrize(("shift", "expected"), [(0.0, 0.0), (1.01, 1.01 ** 2)])
def test_krylov_on_defective_and_vanishing_operators(shift, expected):
    """A Jordan block (a chain of integrators) makes the Perron root defective, which Arnoldi resolves only
    to eps^(1/size): the proven bounds catch it and the exact answer is returned (K = 0: radius rho(A)^2)."""
    n = 22
    A = np.diag(np.ones(n - 1), 1) + shift * np.eye(n)
    B, K, mu = np.ones((n, 2)), np.zeros((2, n)), np.array([0.5, 0.5])
    assert mean_square_radius(A, B, K, mu, "krylov") == pytest.approx(expected, abs=1e-12)


def _gilbert_radius(A: np.ndarray, B: np.ndarray, K: np.ndarray, p: np.ndarray, r: np.ndarray) -> float:
    """Mean-square radius of x+ = (A - B V K) x behind independent Gilbert channels (h_good 1, h_bad 0):
    the mode is the joint state, v_i = [channel i good]; block (b, a) of the operator is T_ab kron(A_a, A_a)."""
    modes = list(itertools.product((1, 0), repeat=B.shape[1]))     # 1 = good
    n = A.shape[0]
    op = np.zeros((len(modes) * n * n, len(modes) * n * n))
    for ia, a in enumerate(modes):
        Aa = A - B @ np.diag(a) @ K
        for ib, b in enumerate(modes):
            T = np.prod([(1 - p[i] if b[i] else p[i]) if a[i] else (r[i] if b[i] else 1 - r[i])
                         for i in range(len(a))])
            op[ib * n * n:(ib + 1) * n * n, ia * n * n:(ia + 1) * n * n] = T * np.kron(Aa, Aa)
    return float(max(abs(np.linalg.eigvals(op))))



def test_bernoulli_closed_loop_is_refused_behind_a_gilbert_elliott_chain():
    """closed_loop() on a bursty system refuses rather than answer with the Bernoulli radius (0.47, "stable") where
    the loop behind the chain has radius 1.06 (not mean-square stable)."""
    system = bursty_twin(pl.load_example("two_actuator"), 0.95)
    gain = pl.closed_form(system, "tcp").gain
    ch = system.channel
    assert _gilbert_radius(system.A, system.B, gain, np.asarray(ch.p), np.asarray(ch.r)) > 1.02
    twin = closed_loop(system, gain, "tcp", mu=system.mu_schedule[0])      # the Bernoulli twin, asked for
    assert twin.stable
    assert twin.spectral_radius < 0.5
    for call in (lambda: closed_loop(system, gain, "tcp"), lambda: dp_riccati(system),
                 lambda: critical_mu(system, "tcp"), lambda: finite_horizon_costs(system, gain, 5)):
        with pytest.raises(InputError) as err:
            call()
        assert err.value.field == "channel"



@pytest.mark.parametrize("call", [
    lambda s: dp_finite_horizon(s, 10**9),
    lambda s: finite_horizon_costs(s, np.zeros((1, 1)), 10**9),
])
def test_a_billion_steps_is_refused_before_it_is_allocated(call):
    """A billion steps (8 GB of gains, minutes of work) is refused by the budget before anything is allocated."""
    scalar = pl.System(A=[[2.0]], B=[[1.0]], horizon=5, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    with pytest.raises(InputError) as err:
        call(scalar)
    assert err.value.field == "steps"



def test_an_overflowing_gain_is_not_stable_and_not_a_linalg_crash():
    """A finite gain of 1e200 squared to inf in the second-moment operator: np.linalg raised LinAlgError
    (Kronecker path, n = 2) or 'SVD did not converge' with LAPACK noise on stderr (ARPACK path, n = 25).
    The operator is quadratic in (A, K), so the radius of the scaled loop times c^2 is exact: about 1e400."""
    from packetloss_cvx.closedloop.stability import is_mean_square_stable, mean_square_radius
    for n in (2, 25):
        A, B = np.diag([2.0] + [1.0] * (n - 1)), np.ones((n, 1))
        radius = mean_square_radius(A, B, np.full((1, n), 1e200), [0.5])
        assert radius > 1e300
        assert not is_mean_square_stable(radius)
    # the scalar reference: (a - mu k)^2 + mu (1 - mu) k^2
    expected = (2 - 0.5e120) ** 2 + 0.25e240
    assert mean_square_radius([[2.0]], [[1.0]], [[1e120]], [0.5]) == pytest.approx(expected, rel=1e-12)



def test_critical_mu_with_a_tolerance_below_double_spacing_ends():
    """tol=1e-20 bisected for ever: the bracket cannot shrink below the spacing of doubles near 0.75."""
    s = pl.System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    from packetloss_cvx.tolerances import MEAN_SQUARE_MARGIN
    t = critical_mu(s, [[2.0]], tol=1e-20).t   # fixed k = a = 2: proved stable iff 4 (1 - mu) < 1 - margin
    assert t == pytest.approx(0.75 + MEAN_SQUARE_MARGIN / 4, abs=1e-15)


def test_second_moment_matrix_of_a_stack_of_laws_is_each_laws_matrix():
    """simulation.stability.second_moment_matrix over a stack (K (G, m, n), mu (G, m); the batched homogeneous
    Riccati's policy step) gives each law's matrix (to rounding: ROUNDING_ORDER_RTOL, the stack's products summed
    in the order the BLAS kernel picks), and each is the operator enumerated over the 2^m patterns."""
    from packetloss_cvx.closedloop.stability import second_moment_matrix

    rng = np.random.default_rng(11)
    for n, m in [(1, 1), (2, 2), (3, 1), (2, 3)]:
        A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
        K, mu = rng.normal(size=(4, m, n)), rng.uniform(size=(4, m))
        mu[0, 0] = 1.0                                         # a perfect channel: c_i = 0 in part of the stack
        stack = second_moment_matrix(A, B, K, mu)
        assert stack.shape == (4, n * n, n * n)
        for g in range(4):
            one = second_moment_matrix(A, B, K[g], mu[g])
            np.testing.assert_allclose(stack[g], one, rtol=0, atol=ROUNDING_ORDER_RTOL * np.abs(one).max())
            assert np.allclose(stack[g], enumerated_operator(A, B, K[g], mu[g]), rtol=1e-12, atol=1e-12)


# ---------------------------------------------------------------- the bands, pinned on both sides

@pytest.mark.parametrize(("factor", "stable"), [(3.0, True), (0.3, False)])
def test_a_radius_3_margins_below_one_is_stable_and_0_3_margins_is_not(factor, stable):
    """is_mean_square_stable's band: stable iff radius < 1 - MEAN_SQUARE_MARGIN."""
    from packetloss_cvx.tolerances import MEAN_SQUARE_MARGIN

    assert is_mean_square_stable(1.0 - factor * MEAN_SQUARE_MARGIN) is stable


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_fixed_point_residual_check_refuses_3_and_keeps_0_3_times_moment_residual_rtol(monkeypatch, factor, kept):
    """X = X / 2 + C solved by a dense LU that returns 2 C + e E (E symmetric, ||E||_F = 1): the residual
    ||X - X/2 - C|| is e / 2 and the scale max(||X||, ||C||) is 2 ||C|| (to e), so the relative residual is
    e / (4 ||C||) (by hand); e = 4 factor MOMENT_RESIDUAL_RTOL ||C||: NumericalError at 3, X returned at 0.3."""
    from packetloss_cvx.closedloop.moments import solve_fixed_point
    from packetloss_cvx.tolerances import MOMENT_RESIDUAL_RTOL

    C = np.array([[2.0, 0.5], [0.5, 1.0]])
    E = np.array([[0.0, 1.0], [1.0, 0.0]]) / np.sqrt(2.0)
    off = 2.0 * C + 4.0 * factor * MOMENT_RESIDUAL_RTOL * np.linalg.norm(C) * E
    monkeypatch.setattr(np.linalg, "solve", lambda a, b: off.ravel())
    if kept:
        assert np.array_equal(solve_fixed_point(lambda X: 0.5 * X, lambda: 0.5 * np.eye(4), C, "a test"), off)
    else:
        with pytest.raises(pl.NumericalError, match="a test: the linear solve lost its digits"):
            solve_fixed_point(lambda X: 0.5 * X, lambda: 0.5 * np.eye(4), C, "a test")


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_average_cost_cross_check_refuses_3_and_keeps_0_3_times_moment_residual_rtol(monkeypatch, factor, kept):
    """closed_loop's two computations of the average stage cost, tr(P_K Sigma_W) and tr((Omega + K'M Psi K) S),
    made to disagree by factor MOMENT_RESIDUAL_RTOL (the cost-to-go solve's answer scaled): CrossCheckError at 3, the
    loop at 0.3 with its cost by hand (scalar a = 2, k = 2, mu = 0.8, sigma = 1: radius r = (2 - 0.8 * 2)^2
    + 0.8 * 0.2 * 4 = 0.8, moment S = sigma / (1 - r) = 5, cost (1 + 0.8 * 4) S = 21)."""
    import packetloss_cvx.closedloop.moments as moments_module
    from packetloss_cvx.tolerances import MOMENT_RESIDUAL_RTOL

    s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.8], x0=[1.0],
               noise_cov=[[1.0]])
    real = moments_module.solve_fixed_point

    def solve(apply, matrix, C, what):
        X = real(apply, matrix, C, what)
        return X * (1 + factor * MOMENT_RESIDUAL_RTOL) if what == "the cost-to-go of the law" else X

    monkeypatch.setattr(moments_module, "solve_fixed_point", solve)
    if kept:
        loop = closed_loop(s, [[2.0]])
        assert loop.average_stage_cost == pytest.approx(21.0, rel=1e-12)
    else:
        with pytest.raises(pl.CrossCheckError, match="average stage cost"):
            closed_loop(s, [[2.0]])
