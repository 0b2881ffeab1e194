"""The constrained expected-cost QP (qp/constrained.py) and its constraints (model/constraints.py).

References, none taken from the code under test: Theorem 1's closed form where no constraint binds; scipy's SLSQP
on the same expected cost (identified from ``expected_cost`` as a quadratic) with the constraints written here from
matrix powers; the state's moments by enumerating every loss pattern; Cantelli's bound checked by enumeration."""

import itertools
import json

import numpy as np
import pytest
import scipy.optimize as so

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.errors import DimensionError, InfeasibleError, InputError, SolverError
from packetloss_cvx.lq.costs import closed_form, expected_cost
from packetloss_cvx.lq.moments import plan_moments
from packetloss_cvx.model.constraints import Constraints, check_constraints, constraints_from_dict
from packetloss_cvx.model.files import load_constraints, save_system
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.constrained import ConstrainedQP, solve_constrained
from packetloss_cvx.qp.expected_cost import ExpectedCostQP, compare
from packetloss_cvx.tolerances import (
    CONSTRAINED_AGREEMENT_RTOL,
    CONSTRAINED_KKT_RTOL,
    CROSS_CHECK_COST_RTOL,
)


def _system(seed, n=2, m=2, horizon=5, noise=True):
    return random_system(np.random.default_rng(seed), n=n, m=m, horizon=horizon, spectral_radius=0.9,
                         non_stationary=False, noise=noise, time_varying=False, edge_mu=False)


def _chance_values(system, U, a, eps):
    """max_k a'E[x_k] + sqrt((1-eps)/eps) std(a'x_k) under the plan U, from the enumerated-free moment recursion."""
    mom = plan_moments(system, U)
    return max(a @ mom.mean[k] + np.sqrt((1 - eps) / eps * (a @ mom.cov[k] @ a)) for k in range(1, system.horizon + 1))


def _binding_constraints(system, protocol, soft=False, eps=0.2, share=0.7):
    """Input bounds at ``share`` of the unconstrained plan's peak (above 1: they do not bind), a rate bound, and a
    chance constraint on a direction (+-e_i, else a seeded random one) whose value the unconstrained plan raises above
    U = 0's: b halfway between, so that U = 0 is feasible and the unconstrained plan is not (the chance row binds)."""
    free = closed_form(system, protocol).inputs
    peak = share * np.abs(free).max(axis=0)
    zero = np.zeros_like(free)
    directions = np.random.default_rng(0).normal(size=(40, system.n))
    for a in [*(sign * e for e in np.eye(system.n) for sign in (1.0, -1.0)), *directions]:
        low, high = _chance_values(system, zero, a, eps), _chance_values(system, free, a, eps)
        if high > low + 1e-3 * (abs(low) + abs(high)):
            break
    else:  # pragma: no cover - the seeds below all have such a direction
        raise AssertionError("no binding direction")
    return Constraints(u_min=-peak, u_max=peak, du_max=1.2 * peak, chance=[(a, (low + high) / 2, eps)], soft=soft)


def _binding_state_constraints(system, protocol, soft=False):
    """Limits on E[x_k] the unconstrained plan crosses and U = 0 does not: a box entry on the first direction +-e_i
    (if any) whose largest mean the plan raises above U = 0's (x_max or x_min halfway), and one polyhedron row
    F E[x_k] <= g on a seeded random direction chosen the same way."""
    free = closed_form(system, protocol).inputs
    zero = np.zeros_like(free)

    def top(U, f):
        return max(f @ plan_moments(system, U).mean[k] for k in range(1, system.horizon + 1))
    n = system.n
    box = {"x_min": np.full(n, -np.inf), "x_max": np.full(n, np.inf)}
    for i, sign in itertools.product(range(n), (1.0, -1.0)):
        f = sign * np.eye(n)[i]
        low, high = top(zero, f), top(free, f)
        if high > low + 1e-3 * (abs(low) + abs(high)):
            if sign > 0:
                box["x_max"][i] = (low + high) / 2
            else:
                box["x_min"][i] = -(low + high) / 2
            break                   # (no axis the plan pushes out: no box, the polyhedron row alone)
    for f in np.random.default_rng(1).normal(size=(40, n)):
        low, high = top(zero, f), top(free, f)
        if high > low + 1e-3 * (abs(low) + abs(high)):
            break
    else:  # pragma: no cover
        raise AssertionError("no binding row")
    return Constraints(**box, F=[f], g=[(low + high) / 2], soft=soft)


# ------------------------------------------------------------------------------ independent references

def _quadratic(system, protocol):
    """J(U) = u'Hu + 2 f'u + c identified from ``expected_cost`` at 0, +-e_i and e_i + e_j (exact for a quadratic up
    to rounding): the reference's cost, with its exact gradient."""
    k = system.horizon * system.m

    def J(u):
        return expected_cost(system, np.asarray(u).reshape(system.horizon, system.m), protocol)
    c = J(np.zeros(k))
    eye = np.eye(k)
    plus = np.array([J(e) for e in eye])
    minus = np.array([J(-e) for e in eye])
    H = np.diag((plus + minus) / 2 - c)
    for i, j in itertools.combinations(range(k), 2):
        H[i, j] = H[j, i] = (J(eye[i] + eye[j]) - plus[i] - plus[j] + c) / 2
    return H, (plus - minus) / 4, c


def _chance_rows(system, a, b, eps):
    """g_k(u) = b - a'E[x_k] - sqrt((1-eps)/eps) sqrt(Var a'x_k) >= 0, k = 1..N, from A^p directly."""
    N, m = system.horizon, system.m
    A, B, mu, W = system.A, system.B, system.mu_schedule, system.noise_cov
    power = [np.linalg.matrix_power(A, p) for p in range(N + 1)]
    kappa = np.sqrt((1 - eps) / eps)
    rows = []
    for k in range(1, N + 1):
        lin = np.zeros(N * m)
        quad = np.zeros(N * m)
        for j in range(k):
            h = a @ power[k - 1 - j] @ B
            lin[j * m:(j + 1) * m] = h * mu[j]
            quad[j * m:(j + 1) * m] = h**2 * mu[j] * (1 - mu[j])
        noise = sum(a @ power[p] @ W @ power[p].T @ a for p in range(k))
        free = a @ power[k] @ system.x0
        rows.append((lin, quad, noise, free))

    def fun(u):
        return np.array([b - free - lin @ u - kappa * np.sqrt(quad @ u**2 + noise) for lin, quad, noise, free in rows])

    def jac(u):
        return np.array([-lin - kappa * quad * u / np.sqrt(quad @ u**2 + noise) for lin, quad, noise, _ in rows])
    return fun, jac


def _slsqp(system, protocol, c):
    """The constrained minimiser by scipy's SLSQP from U = 0 (feasible), run three times from its own answer."""
    N, m = system.horizon, system.m
    H, f, _ = _quadratic(system, protocol)
    lo = np.tile(c.u_min, N) if c.u_min is not None else np.full(N * m, -np.inf)
    hi = np.tile(c.u_max, N) if c.u_max is not None else np.full(N * m, np.inf)
    D = np.zeros(((N - 1) * m, N * m))
    for t in range(1, N):
        for i in range(m):
            D[(t - 1) * m + i, t * m + i], D[(t - 1) * m + i, (t - 1) * m + i] = 1.0, -1.0
    cons = []
    if c.du_max is not None:
        du = np.tile(c.du_max, N - 1)
        cons += [{"type": "ineq", "fun": lambda u: du - D @ u, "jac": lambda u: -D},
                 {"type": "ineq", "fun": lambda u: du + D @ u, "jac": lambda u: D}]
    rows, rhs = [], []                                   # state limits: E[x_k] = A^k x0 + sum A^{k-1-j} B Vbar_j u_j
    for k in range(1, N + 1):
        M = np.zeros((system.n, N * m))
        for j in range(k):
            M[:, j * m:(j + 1) * m] = np.linalg.matrix_power(system.A, k - 1 - j) @ system.B * system.mu_schedule[j]
        free = np.linalg.matrix_power(system.A, k) @ system.x0
        for sign, bound in ((1.0, c.x_max), (-1.0, c.x_min)):
            for i in [] if bound is None else np.flatnonzero(np.isfinite(bound)):
                rows.append(sign * M[i])
                rhs.append(sign * (bound[i] - free[i]))
        for row, g in zip([] if c.F is None else c.F, [] if c.g is None else c.g, strict=True):
            rows.append(row @ M)
            rhs.append(g - row @ free)
    if rows:
        R, r = np.array(rows), np.array(rhs)
        cons.append({"type": "ineq", "fun": lambda u: r - R @ u, "jac": lambda u: -R})
    for a, b, eps in c.chance:
        fun, jac = _chance_rows(system, a, b, eps)
        cons.append({"type": "ineq", "fun": fun, "jac": jac})
    # Restarted from its own answer (SLSQP's stopping test is on the change of the cost) until it has converged three
    # times. Its line search can stop without descent (status 8) where rounding leaves none, which BLAS kernels decide
    # differently: after a converged run the previous answer stands; before one, it restarts from where it stopped,
    # and where it never converges (seed 4 at 0.7 under Sandybridge, one BLAS thread) scipy's trust-constr answers.
    start, converged = np.zeros(N * m), 0
    for _ in range(6):
        result = so.minimize(lambda u: u @ H @ u + 2 * f @ u, start, jac=lambda u: 2 * H @ u + 2 * f,
                             bounds=list(zip(lo, hi, strict=True)), constraints=cons, method="SLSQP",
                             options={"ftol": 1e-14, "maxiter": 1000})
        if result.status == 8 and converged:
            break
        assert result.success or result.status == 8, result.message
        start, converged = result.x, converged + bool(result.success)
        if converged == 3:
            break
    if not converged:        # SLSQP's line search stalls from every start it reached: scipy's trust-region SQP
        result = so.minimize(lambda u: u @ H @ u + 2 * f @ u, start, jac=lambda u: 2 * H @ u + 2 * f,
                             hess=lambda u: 2 * H, bounds=list(zip(lo, hi, strict=True)), constraints=cons,
                             method="trust-constr", options={"gtol": 1e-13, "xtol": 1e-15, "maxiter": 20000})
        assert result.status in (1, 2), result.message
        start = result.x
    return start.reshape(N, m)


def _enumerated_moments(system, U):
    """E[x_k] and Cov(x_k) by summing over all 2^(k m) loss patterns (noise added: independent, zero mean)."""
    N, n, m = system.horizon, system.n, system.m
    mu = system.mu_schedule
    out_mean, out_cov = [], []
    for k in range(1, N + 1):
        mean, second = np.zeros(n), np.zeros((n, n))
        for pattern in itertools.product((0, 1), repeat=k * m):
            v = np.array(pattern, dtype=float).reshape(k, m)
            prob = np.prod(np.where(v == 1, mu[:k], 1 - mu[:k]))
            x = system.x0.copy()
            for t in range(k):
                x = system.A @ x + system.B @ (v[t] * U[t])
            mean += prob * x
            second += prob * np.outer(x, x)
        noise = sum(np.linalg.matrix_power(system.A, p) @ system.noise_cov @ np.linalg.matrix_power(system.A, p).T
                    for p in range(k))
        out_mean.append(mean)
        out_cov.append(second - np.outer(mean, mean) + noise)
    return np.array(out_mean), np.array(out_cov)


# ------------------------------------------------------------------------------ answers

@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize("formulation", ["condensed", "sparse"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_constraints_that_do_not_bind_give_the_closed_form(protocol, formulation, seed):
    s = _system(seed, n=3, m=2, horizon=6)
    ref = closed_form(s, protocol)
    peak = np.abs(ref.inputs).max(axis=0)
    c = Constraints(u_min=-2 * peak - 1, u_max=2 * peak + 1, du_max=4 * peak + 1, x_max=np.full(s.n, 1e3))
    sol = solve_constrained(s, protocol, c, formulation)
    assert sol.binding == ()
    check = compare(sol.inputs, sol.cost, ref, s)           # CROSS_CHECK_COST_RTOL (1e-7) and the input tolerance
    assert check.cost_rel_diff <= CROSS_CHECK_COST_RTOL
    assert sol.kkt_residual <= CONSTRAINED_KKT_RTOL


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize("seed", [3, 4, 5])
@pytest.mark.parametrize("share", [0.7, 3.0])
def test_a_binding_plan_meets_its_kkt_conditions_and_agrees_with_slsqp(protocol, seed, share):
    s = _system(seed, n=2, m=2, horizon=4)
    c = _binding_constraints(s, protocol, share=share)         # share 3: the input bounds are loose, the chance binds
    sols = [solve_constrained(s, protocol, c, f) for f in ("condensed", "sparse")]
    reference = _slsqp(s, protocol, c)
    for sol in sols:
        assert sol.binding                                          # the test is about binding constraints
        if share > 1:
            assert any(label.startswith("chance") for label in sol.binding)
        assert sol.kkt_residual <= CONSTRAINED_KKT_RTOL
        scale = np.abs(reference).max()
        assert np.abs(sol.inputs - reference).max() <= CONSTRAINED_AGREEMENT_RTOL * scale
        assert abs(sol.cost - expected_cost(s, reference, protocol)) <= CONSTRAINED_AGREEMENT_RTOL * sol.cost
    assert np.abs(sols[0].inputs - sols[1].inputs).max() <= CONSTRAINED_AGREEMENT_RTOL * np.abs(reference).max()


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize("seed", [3, 4, 5])
def test_a_plan_under_binding_state_limits_meets_its_kkt_conditions_and_agrees_with_slsqp(protocol, seed):
    s = _system(seed, n=2, m=2, horizon=4)
    c = _binding_state_constraints(s, protocol)
    reference = _slsqp(s, protocol, c)
    for formulation in ("condensed", "sparse"):
        sol = solve_constrained(s, protocol, c, formulation)
        assert any(label.startswith(("x_m", "F[")) for label in sol.binding)
        assert sol.kkt_residual <= CONSTRAINED_KKT_RTOL
        assert np.abs(sol.inputs - reference).max() <= CONSTRAINED_AGREEMENT_RTOL * np.abs(reference).max()
        np.testing.assert_allclose(sol.states, plan_moments(s, sol.inputs).mean[1:], rtol=1e-12, atol=1e-12)


def test_the_plan_moments_are_the_enumerated_moments():
    s = _system(7, n=2, m=2, horizon=3)
    U = np.random.default_rng(1).normal(size=(3, 2))
    mom = plan_moments(s, U)
    mean, cov = _enumerated_moments(s, U)
    np.testing.assert_allclose(mom.mean[1:], mean, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(mom.cov[1:], cov, rtol=1e-11, atol=1e-12)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_a_chance_constrained_plan_keeps_the_probability_below_eps(protocol):
    """No noise: x_k takes finitely many values, so P(a'x_k > b) is exact by enumeration; Cantelli keeps it <= eps,
    and the binding step shows the bound's slack (conservative: the enumerated probability is below eps)."""
    s = _system(8, n=2, m=1, horizon=4, noise=False)
    c = _binding_constraints(s, protocol, share=3.0)
    a, b, eps = c.chance[0]
    sol = solve_constrained(s, protocol, c)
    assert any(label.startswith("chance") for label in sol.binding)
    mu = s.mu_schedule
    for k in range(1, s.horizon + 1):
        p_exceed = 0.0
        for pattern in itertools.product((0, 1), repeat=k):
            v = np.array(pattern, dtype=float)
            x = s.x0.copy()
            for t in range(k):
                x = s.A @ x + s.B @ (v[t] * sol.inputs[t])
            if a @ x > b + 1e-12:
                p_exceed += np.prod(np.where(v == 1, mu[:k, 0], 1 - mu[:k, 0]))
        assert p_exceed <= eps


def test_an_infeasible_problem_raises_with_the_solvers_status_and_soft_rows_report_their_violation():
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[2.0])
    hard = Constraints(u_min=[-0.5], u_max=[0.5], x_max=[1.0])          # E[x_1] >= 2 - 0.25: no plan
    with pytest.raises(InfeasibleError, match="infeasible") as info:
        solve_constrained(s, "udp", hard)
    assert info.value.status == "infeasible"
    # the solver's Farkas multipliers, checked here by hand: E[x_k] = 2 + sum_{j<k} u_j / 2 with |u_j| <= 1/2, so
    # y >= 0 on (x_max at k, u_min at t) rows with G'y = 0 sums to y'h < 0; the package's own check says verified
    certificate = info.value.certificate
    assert certificate["verdict"] == "verified"
    assert certificate["margin"] > 0
    y_inputs, y_states = (np.array(y) for y in certificate["multipliers"])
    assert np.all(y_inputs >= -1e-9)
    assert np.all(y_states >= -1e-9)
    y_max, y_min = y_inputs[:3], y_inputs[3:]                     # rows u_max (t = 0..2), then u_min
    combo = y_max - y_min + np.array([y_states[k:].sum() / 2 for k in range(3)])    # G'y, u_j enters x_k for k > j
    value = -(0.5 * y_max.sum() + 0.5 * y_min.sum() + (1.0 - 2.0) * y_states.sum())  # y'(G 0 - h) = -y'h
    assert value - np.abs(combo).sum() * 0.5 > 0                                    # no plan on the input box
    with pytest.raises(SolverError) as info:     # a chance row: the certificate is not checkable, so not a proof
        solve_constrained(s, "udp", Constraints(u_min=[-0.5], u_max=[0.5], chance=[([1.0], 1.0, 0.1)]))
    assert not isinstance(info.value, InfeasibleError)
    assert (info.value.status, info.value.certificate["verdict"]) == ("infeasible", "undecided")
    assert "chance rows" in info.value.certificate["reason"]
    soft = Constraints(u_min=[-0.5], u_max=[0.5], x_max=[1.0], soft=True, soft_weight=100.0)
    sol = solve_constrained(s, "udp", soft)
    # weight 100 beats the cost's pull: every input at -0.5, E[x_k] = 2 - 0.25 k, violated by 0.75, 0.5, 0.25
    np.testing.assert_allclose(sol.inputs.ravel(), [-0.5, -0.5, -0.5], atol=1e-9)
    assert [label for label, _ in sol.violations] == ["x_max[0] at k=1", "x_max[0] at k=2", "x_max[0] at k=3"]
    np.testing.assert_allclose([v for _, v in sol.violations], [0.75, 0.5, 0.25], atol=1e-9)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_a_chance_row_at_its_kink_is_checked_with_its_subgradient(protocol):
    """x' = x + v u from 1, mu = 0.15, no noise, N = 1, P(x_1 <= 1/2) >= 0.9 soft (weight 100): the row's value
    1 + 0.15 u + 3 sqrt(0.15 0.85) |u| - 1/2 grows both ways from u = 0 (3 sqrt(0.1275) = 1.07 > 0.15), and the cost's
    slope there, 0.3, is below the penalty's 100 (1.07 - 0.15): u = 0, J = 1 and a violation of 1/2, by hand. At
    u = 0 the norm has no gradient; the KKT check takes its subgradient (a solve found it and was refused once)."""
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.15], x0=[1.0])
    sol = solve_constrained(s, protocol, Constraints(chance=[([1.0], 0.5, 0.1)], soft=True, soft_weight=100.0))
    assert sol.inputs[0, 0] == pytest.approx(0.0, abs=1e-9)
    assert sol.cost == pytest.approx(1.0, abs=1e-9)
    assert sol.violations == (("chance[0] at k=1", pytest.approx(0.5, abs=1e-9)),)
    assert sol.kkt_residual <= CONSTRAINED_KKT_RTOL


def test_a_soft_problem_that_could_be_hard_has_the_hard_answer():
    s = _system(9, n=2, m=2, horizon=4)
    hard = _binding_constraints(s, "udp")
    soft = _binding_constraints(s, "udp", soft=True)
    a, b = solve_constrained(s, "udp", hard), solve_constrained(s, "udp", soft)
    assert b.violations == ()
    np.testing.assert_allclose(b.inputs, a.inputs, atol=CONSTRAINED_AGREEMENT_RTOL * np.abs(a.inputs).max())


# ------------------------------------------------------------------------------ the escape hatch

def test_the_problem_is_dpp_and_reachable_and_re_solves_for_new_x0_and_mu():
    s = _system(10, n=2, m=2, horizon=5)
    c = _binding_constraints(s, "tcp", share=3.0)
    qp = ConstrainedQP(s, "tcp", c)
    assert qp.problem.is_dpp()
    assert qp.U.shape == (5, 2)
    assert qp.states.shape == (5, 2)
    assert qp.x0.shape == (2,)
    assert qp.mu.shape == (5, 2)
    first = qp.solve()
    np.testing.assert_allclose(first.states, plan_moments(s, first.inputs).mean[1:], rtol=1e-12, atol=1e-12)
    again = qp.solve(x0=-s.x0, mu=[0.7, 0.4])
    fresh = ConstrainedQP(s.with_x0(-s.x0).with_mu([0.7, 0.4]), "tcp", c).solve()
    np.testing.assert_allclose(again.inputs, fresh.inputs, atol=1e-12)
    qp.add_constraints([qp.U[0, 0] >= 0.5 * c.u_max[0]])      # the user's own constraint
    mine = qp.solve()
    assert mine.inputs[0, 0] >= 0.5 * c.u_max[0] - 1e-9
    assert mine.kkt_residual is None


def test_the_compiled_chance_rows_are_the_constraints_written_from_matrix_powers():
    """The cvxpy problem a user solves holds the rows themselves (the polish evaluates them on its own moments and
    would hide a wrong compiled row from the plan): each chance row's value at a random plan is the reference's."""
    s = _system(13, n=3, m=2, horizon=5)
    c = _binding_constraints(s, "udp", share=3.0)
    qp = ConstrainedQP(s, "udp", c, "condensed")
    qp.solve()                                                     # sets the Parameters
    U = np.random.default_rng(2).normal(size=(5, 2))
    qp.U.value = U
    fun, _ = _chance_rows(s, *c.chance[0])
    compiled = np.array([float(con.expr.value) for con in qp.problem.constraints[-s.horizon:]])
    np.testing.assert_allclose(compiled, -fun(U.ravel()), rtol=1e-12, atol=1e-12)


def test_the_compiled_soft_problem_prices_a_violation_at_its_weight():
    """x' = x + v u from 2, mu = 1/2, N = 1, Q = R = 1, E[x_1] <= 1 soft with weight rho = 1: the TCP-like cost
    (2 + u/2)^2 + u^2/2 + rho (1 + u/2) is least at u = -(2 + rho/2) / 1.5 = -5/3 (E[x_1] = 7/6: violated), by hand;
    the compiled problem alone (cvxpy, no polish) and the solve agree."""
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[2.0])
    qp = ConstrainedQP(s, "tcp", Constraints(x_max=[1.0], soft=True, soft_weight=1.0))
    sol = qp.solve()
    assert sol.inputs[0, 0] == pytest.approx(-5 / 3, abs=1e-12)
    assert sol.violations == (("x_max[0] at k=1", pytest.approx(1 / 6, abs=1e-12)),)
    qp.problem.solve(solver="CLARABEL")
    assert float(qp.U.value[0, 0]) == pytest.approx(-5 / 3, abs=1e-6)


def test_another_installed_solver_gives_the_same_plan():
    s = _system(11, n=2, m=2, horizon=5)
    free = closed_form(s, "udp").inputs
    c = Constraints(u_min=-0.5 * np.abs(free).max(axis=0), u_max=0.5 * np.abs(free).max(axis=0))
    clarabel = solve_constrained(s, "udp", c)
    osqp = ConstrainedQP(s, "udp", c, solver="OSQP", solver_options={"eps_abs": 1e-9, "eps_rel": 1e-9,
                                                                        "max_iter": 100000}).solve()
    assert osqp.solver == "OSQP"
    assert clarabel.binding
    np.testing.assert_allclose(osqp.inputs, clarabel.inputs, atol=CONSTRAINED_AGREEMENT_RTOL)
    with pytest.raises(InputError, match="solver"):
        ConstrainedQP(s, "udp", c, solver="NO_SUCH_SOLVER")


def test_expected_cost_qp_takes_constraints():
    s = _system(12, n=2, m=2, horizon=4)
    c = _binding_constraints(s, "udp")
    qp = ExpectedCostQP(s, "udp", "sparse", constraints=c)
    sol = qp.solve()
    assert qp.constrained.problem.is_dpp()
    assert sol.formulation == "sparse"
    np.testing.assert_allclose(sol.inputs, solve_constrained(s, "udp", c, "condensed").inputs, atol=1e-9)


# ------------------------------------------------------------------------------ bad input

@pytest.mark.parametrize(("kwargs", "field"), [
    ({"u_min": [0.1]}, "u_min"),                                  # zero input outside the bounds
    ({"u_max": [-0.1]}, "u_max"),
    ({"x_min": [2.0], "x_max": [1.0]}, "x_min"),
    ({"du_max": [-1.0]}, "du_max"),
    ({"chance": [([1.0], 1.0, 0.0)]}, "chance[0].eps"),
    ({"chance": [([1.0], 1.0, 1.0)]}, "chance[0].eps"),
    ({"chance": [([1.0], 1.0, 1.5)]}, "chance[0].eps"),
    ({"chance": [([0.0], 1.0, 0.1)]}, "chance[0].a"),
    ({"F": [[1.0]]}, "g"),
    ({"soft_weight": 0.0}, "soft_weight"),
])
def test_bad_constraints_name_their_field(kwargs, field):
    with pytest.raises(InputError) as info:
        Constraints(**kwargs)
    assert info.value.field == field


def test_shapes_are_checked_against_the_system():
    with pytest.raises(DimensionError, match="u_max: expected 2 numbers"):
        check_constraints(Constraints(u_max=[1.0, 2.0, 3.0]), 3, 2)
    with pytest.raises(DimensionError, match=r"chance\[0\].a"):
        check_constraints(Constraints(chance=[([1.0], 1.0, 0.1)]), 2, 1)
    with pytest.raises(InputError, match="constraints.nope"):
        constraints_from_dict({"nope": 1}, 1, 1)


# ------------------------------------------------------------------------------ files and the command line

def test_the_constraints_table_round_trips(tmp_path):
    s = pl.load_example("two_actuator")
    c = Constraints(u_min=[-1.0, -np.inf], u_max=[1.0, 2.0], du_max=[0.5, np.inf], x_min=[-5.0, -5.0],
                    x_max=[5.0, np.inf], F=[[1.0, 1.0]], g=[8.0], chance=[([0.0, 1.0], 3.0, 0.05)], soft=True,
                    soft_weight=50.0)
    path = save_system(s, tmp_path / "limited.toml", constraints=c)
    again = load_constraints(path)
    assert again == c                                              # field by field (arrays, rows, soft, weight)
    assert again.soft
    assert again.soft_weight == 50.0
    assert load_constraints("two_actuator") is None
    text = path.read_text()
    assert "[constraints]" in text
    assert "-inf" in text


def test_solve_json_adds_the_constrained_answer_per_protocol(tmp_path, capsys):
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    path = save_system(s, tmp_path / "scalar.toml", constraints=Constraints(u_min=[-0.5], u_max=[0.5]))
    assert main(["solve", str(path), "--json", "--no-stability"]) == 0
    out = json.loads(capsys.readouterr().out)
    for protocol, free in (("tcp", -2 / 3), ("udp", -0.5)):       # Theorem 1: u = -2/3 (TCP), -1/2 (UDP)
        entry = out[protocol]["constrained"]
        assert {"status", "cost", "inputs", "binding"} <= set(entry)
        assert entry["status"] == "optimal"
        assert entry["inputs"][0][0] == pytest.approx(max(free, -0.5), abs=1e-9)
        assert entry["binding"] == ["u_min[0] at t=0"]             # UDP's free optimum lies on the bound
        assert out[protocol]["cost"] == pytest.approx(closed_form(s, protocol).cost, rel=1e-12)   # today's keys stay


@pytest.mark.parametrize(("table", "field"), [
    ("chance = [[[1.0], 1.0, 2.0]]", "constraints.chance[0].eps"),
    ("u_min = [0.5]", "constraints.u_min"),                        # zero input outside the bounds
    ("u_min = [-1.0]\nu_max = [-0.5]", "constraints.u_max"),
    ("u_max = [1.0, 2.0]", "constraints.u_max"),                   # m = 1
    ("x_max = [1.0, 2.0]", "constraints.x_max"),                   # n = 1
])
def test_bad_constraints_in_a_file_exit_2_with_one_line(tmp_path, capsys, table, field):
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    path = save_system(s, tmp_path / "bad.toml")
    path.write_text(path.read_text() + f"\n[constraints]\n{table}\n")
    assert main(["solve", str(path), "--json"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert f"error: {field}" in err[0]


def test_solve_json_reports_an_infeasible_table_with_its_certificate(tmp_path, capsys):
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[2.0])
    path = save_system(s, tmp_path / "tight.toml", constraints=Constraints(u_min=[-0.5], u_max=[0.5], x_max=[1.0]))
    assert main(["solve", str(path), "--json", "--no-stability"]) == 0        # the closed forms stand
    out = json.loads(capsys.readouterr().out)
    for protocol in ("tcp", "udp"):
        entry = out[protocol]["constrained"]
        assert entry["status"] == "infeasible"
        assert entry["solver_status"] == "infeasible"
        assert entry["inputs"] is None
        assert entry["certificate"]["verdict"] == "verified"
