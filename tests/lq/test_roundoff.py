"""roundoff: the running error bound of a rolled-out plan, against exact rational arithmetic (fractions).

Every quantity the bound rests on is checked against its exact value: the error-free transformations, the residuals
in twice the precision, the propagation by nonnegative matrices (both bases), the blocked scan's rounding of
nonnegative sums, and the bound on the quadratic cost of the rolled-out states, which must hold on every case and
be close to the true error where that error is large (an unstable plant under a plan that cancels its growth).
"""

from fractions import Fraction as F

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.lq.recursion import mean_states, weight_head
from packetloss_cvx.lq.roundoff import (
    SCAN_BLOCK,
    UNIT_ROUNDOFF,
    gamma,
    linear_scan,
    propagation_bound,
    rollout_cost_error,
    step_residuals,
    two_product,
    two_sum,
)
from packetloss_cvx.lq.structure import structure_of
from packetloss_cvx.model.random_systems import random_system

from ..references import exact_mean_states, exact_quadratic


def _spread(rng, size):
    """Doubles of both signs spread over 2^-200 .. 2^200 (products stay far from overflow and underflow)."""
    return rng.choice([-1.0, 1.0], size) * rng.uniform(1.0, 2.0, size) * 2.0 ** rng.integers(-200, 200, size)


def test_two_sum_and_two_product_are_exact():
    rng = np.random.default_rng(0)
    a, b = _spread(rng, 2000), _spread(rng, 2000)
    s, e = two_sum(a, b)
    p, f = two_product(a, b)
    for k in range(a.size):
        assert F(a[k]) + F(b[k]) == F(s[k]) + F(e[k])
        assert F(a[k]) * F(b[k]) == F(p[k]) + F(f[k])
    assert np.array_equal(s, a + b)
    assert np.array_equal(p, a * b)


def _rollout(A, B, x0, mu, U):
    """The float rollout x_{t+1} = A x_t + B (mu_t u_t), step by step (P = 1), as recursion.mean_states runs it."""
    X = np.empty((1, U.shape[1], A.shape[0]))
    x = x0
    for t in range(U.shape[1]):
        x = X[:, t] = x @ A.T + (mu[:, t] * U[:, t]) @ B.T
    return X


@pytest.mark.parametrize("seed", range(4))
def test_step_residuals_are_the_exact_residuals_to_their_bound(seed):
    rng = np.random.default_rng(seed)
    n, m, N = 3, 2, 12
    A, B = rng.normal(size=(n, n)) * 1.7, rng.normal(size=(n, m))
    mu, U = rng.uniform(0.05, 1.0, (1, N, m)), rng.normal(size=(1, N, m)) * 10.0 ** rng.integers(-3, 4)
    x0 = rng.normal(size=(1, n))
    X = _rollout(A, B, x0, mu, U)
    prev = np.concatenate([x0[:, None], X[:, :-1]], axis=1)
    delta, err = step_residuals(A, B, prev, X, mu, U)
    for t in range(N):
        for i in range(n):
            exact = (F(X[0, t, i]) - sum(F(A[i, j]) * F(prev[0, t, j]) for j in range(n))
                     - sum(F(B[i, k]) * F(mu[0, t, k]) * F(U[0, t, k]) for k in range(m)))
            assert abs(F(delta[0, t, i]) - exact) <= F(err[0, t, i])
            # twice the precision: the residual is known to about u of itself (plus u^2 of the terms)
            assert err[0, t, i] <= 4 * UNIT_ROUNDOFF * abs(float(exact)) + 1e-28 * np.abs(X[0, t]).max()


@pytest.mark.parametrize(("N", "block"), [(1, SCAN_BLOCK), (5, SCAN_BLOCK), (SCAN_BLOCK, SCAN_BLOCK),
                                          (SCAN_BLOCK + 1, SCAN_BLOCK), (3 * SCAN_BLOCK + 7, SCAN_BLOCK),
                                          (40, 4), (70, 4)])
def test_linear_scan_of_nonnegative_data_is_within_its_inflation(N, block):
    """propagation_bound inflates the scan by 1 + gamma_{4 (N + 2L)(n + 2)}: the rounding of nonnegative sums
    stays inside it, on both sides (checked against the exact recursion), with the blocks' ends carried one level
    deep and, with blocks of 4 steps, two and three levels deep."""
    rng = np.random.default_rng(N)
    n = 3
    M = rng.uniform(0.0, 0.45, (n, n))
    S = rng.uniform(0.0, 1.0, (2, N, n))
    Y = linear_scan(M, S, block)
    grow = 1.0 + gamma(4 * (N + 2 * SCAN_BLOCK) * (n + 2))
    for p in range(2):
        y = [F(0)] * n
        for t in range(N):
            y = [sum(F(M[i, j]) * y[j] for j in range(n)) + F(S[p, t, i]) for i in range(n)]
            for i in range(n):
                assert F(Y[p, t, i]) <= y[i] * F(grow)
                assert y[i] <= F(Y[p, t, i]) * F(grow)


def _rotation(radius, angle):
    c, s = np.cos(angle), np.sin(angle)
    return radius * np.array([[c, -s], [s, c]])


@pytest.mark.parametrize("schur", [False, True])
@pytest.mark.parametrize("A", [np.array([[1.3, 0.4], [-0.2, 0.7]]), _rotation(0.97, 0.4),
                               np.array([[0.9, 1.0, 0.0], [0.0, 0.9, 1.0], [0.0, 0.0, 0.9]]),
                               np.array([[-1.1, 2.0, 0.3], [0.0, 0.5, -1.0], [0.2, 0.0, 0.8]])])
def test_propagation_bound_holds_for_every_error_within_its_size(A, schur):
    """|sum_s A^(t-s) rho_s| <= eta_t for signed rho_s with |rho_s| = r_s (the worst signs drawn at random)."""
    rng = np.random.default_rng(1)
    N, n = 40, A.shape[0]
    r = rng.uniform(0.0, 1.0, (1, N, n)) * 1e-16
    eta = propagation_bound(A, r, schur=schur)
    Af = [[F(v) for v in row] for row in A]
    for _ in range(3):
        rho = r * rng.choice([-1.0, 1.0], r.shape)
        e = [F(0)] * n
        for t in range(N):
            e = [sum(Af[i][j] * e[j] for j in range(n)) + F(rho[0, t, i]) for i in range(n)]
            assert all(abs(e[i]) <= F(eta[0, t, i]) for i in range(n))


def test_the_schur_basis_follows_a_rotation_where_the_absolute_basis_explodes():
    """A = 0.97 rot(0.4): rho(A) = 0.97 but rho(|A|) = 1.27, so |A|^t bounds A^t by 1.27^t; in the Schur basis the
    bound stays at the size of the true sum (below 1 / (1 - 0.97) times the largest r)."""
    A = _rotation(0.97, 0.4)
    r = np.full((1, 300, 2), 1e-16)
    assert propagation_bound(A, r)[0, -1].max() > 1e13           # 1.27^300 1e-16
    assert propagation_bound(A, r, schur=True)[0, -1].max() < 40 * 1e-16 * 2 / (1 - 0.97)


def _case(seed, rho, N):
    s = random_system(np.random.default_rng(seed), n=3, m=2, horizon=N, spectral_radius=rho)
    return s, pl.closed_form(s, "tcp").inputs


def _rolled_error(s, U, enough=0.0):
    """(bound, exact |sum xhat'Q xhat - sum x'Q x|, exact sum x'Q x) of plan U, rolled out as expected_cost does."""
    mu, x = s.mu_schedule[None], s.x0[None]
    X = mean_states(structure_of(s), mu, U[None], x)
    Q = s.state_weights[0] if len(weight_head(s)) == s.horizon else s.state_weights
    bound = rollout_cost_error(s.A, s.B, mu, U[None], x, X, Q, enough)[0]
    exact = exact_quadratic(exact_mean_states(s.A, s.B, s.x0, s.mu_schedule, U), Q)
    rolled = exact_quadratic(X[0].tolist(), Q)
    return bound, abs(rolled - exact), exact


@pytest.mark.parametrize(("seed", "rho", "N"), [(0, 3.0, 24), (1, 3.0, 30), (5, 2.0, 50), (3, 1.5, 90), (6, 1.3, 150)])
def test_rollout_cost_error_holds_and_is_tight_where_the_plan_cancels_an_unstable_growth(seed, rho, N):
    """The optimal plan of an unstable plant steers x to zero: its rolled-out states carry the rounding amplified by
    rho^t. The bound holds against the exact sums and is within 1 % of the true error (its estimate is the error)."""
    s, U = _case(seed, rho, N)
    bound, error, exact = _rolled_error(s, U)
    assert error <= F(bound) <= error * F(1.01)
    assert error > exact * F(1e-12)                   # a rounding the bound had to see, not a rounding-level one


@pytest.mark.parametrize(("seed", "rho", "N"), [(4, 0.9, 60), (5, 0.3, 20), (6, 1.1, 30), (7, 1.0, 50)])
def test_rollout_cost_error_holds_where_the_rounding_is_small(seed, rho, N):
    """Stable, marginal and mildly unstable plants: the bound holds and stays at rounding level (1e-12 relative)."""
    s = random_system(np.random.default_rng(seed), horizon=N, spectral_radius=rho)
    U = np.random.default_rng(seed + 100).normal(size=(N, s.m))
    for plan in (U, pl.closed_form(s, "udp").inputs):
        bound, error, exact = _rolled_error(s, plan)
        assert error <= F(bound) <= exact * F(1e-12)


def test_a_rotating_stable_plant_is_resolved_over_a_long_horizon():
    """A lightly damped oscillator (|A| grows 1.24 a step, A contracts 0.99): the |A| basis alone would bound the
    cost of a plan by far more than the cost; the Schur basis keeps it at rounding level, and it holds."""
    A = _rotation(0.99, 0.3)
    s = pl.System(A=A, B=[[1.0], [0.5]], horizon=400, state_weight=[1.0, 2.0], input_weight=[1.0], mu=[0.7],
                  x0=[1.0, -1.0])
    U = np.random.default_rng(8).normal(size=(400, 1))
    loose, _, _ = _rolled_error(s, U, enough=np.inf)           # enough = inf: the |A| basis only
    bound, error, exact = _rolled_error(s, U)
    assert loose > float(exact)
    assert error <= F(bound) <= exact * F(1e-12)
