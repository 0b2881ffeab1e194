"""A constrained QP re-solved on its compiled program (qp/constrained.py's default Clarabel path through qp/convex.py's
ClarabelProgram, kept solvers updated with each re-solve's data) against cvxpy's own path (``problem.solve``, the
same problem).

References, none taken from the code under test: cvxpy's unpacking of the same Clarabel solution
(``problem.unpack_results``), and a ConstrainedQP whose solves go through ``problem.solve`` (the path every other
solver takes), each point solved by a fresh object as well."""

import cvxpy as cp
import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.errors import InfeasibleError, SolverError
from packetloss_cvx.lq.costs import closed_form
from packetloss_cvx.lq.moments import plan_moments
from packetloss_cvx.model.constraints import Constraints
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.constrained import ConstrainedQP
from packetloss_cvx.qp.convex import ClarabelPoint, ClarabelProgram
from packetloss_cvx.tolerances import (
    CLARABEL_DEFAULT,
    CONSTRAINED_AGREEMENT_RTOL,
    CONSTRAINED_KKT_RTOL,
)


def _system(seed, n=3, m=2, horizon=6):
    return random_system(np.random.default_rng(seed), n=n, m=m, horizon=horizon, spectral_radius=0.9,
                         non_stationary=False, noise=True, time_varying=False, edge_mu=False)


def _constraints(system, protocol, kind):
    """Bounds the unconstrained plan crosses ("binding": inputs at 0.6 of its peak, a rate bound, a chance row on
    the first direction +-e_i whose value the plan raises, halfway; "state": E[x] limits halfway, soft) or does not
    ("free": everything at twice the peak)."""
    free = closed_form(system, protocol).inputs
    peak = np.abs(free).max(axis=0)
    if kind == "free":
        return Constraints(u_min=-2 * peak - 1, u_max=2 * peak + 1, du_max=4 * peak + 1)
    if kind == "state":
        top = np.abs(plan_moments(system, free).mean[1:]).max(axis=0)
        return Constraints(x_min=-0.5 * top, x_max=0.5 * top, soft=True, soft_weight=10.0)
    eps, kappa = 0.2, 2.0
    zero = np.zeros_like(free)

    def value(U, a):
        mom = plan_moments(system, U)
        return max(a @ mom.mean[k] + kappa * np.sqrt(a @ mom.cov[k] @ a) for k in range(1, system.horizon + 1))
    for a in (sign * e for e in np.eye(system.n) for sign in (1.0, -1.0)):
        low, high = value(zero, a), value(free, a)
        if high > low + 1e-3 * (abs(low) + abs(high)):
            return Constraints(u_min=-0.6 * peak, u_max=0.6 * peak, du_max=peak, chance=[(a, (low + high) / 2, eps)])
    return Constraints(u_min=-0.6 * peak, u_max=0.6 * peak, du_max=peak)


def _through_cvxpy(qp):
    """The same controller, every solve through ``problem.solve`` (as for any solver other than Clarabel)."""
    qp.fast_path_refused = "the test's reference: cvxpy's own path"
    return qp


def _points(system, rng, count=3):
    return [(np.clip(system.mu_schedule[0] * (1 + 0.1 * rng.normal(size=system.m)), 0.05, 1.0),
             system.x0 * (1 + 0.2 * rng.normal(size=system.n))) for _ in range(count)]


def _agree(a, b):
    scale = max(1.0, float(np.abs(b.inputs).max()))
    assert np.abs(a.inputs - b.inputs).max() <= CONSTRAINED_AGREEMENT_RTOL * scale
    assert abs(a.cost - b.cost) <= CONSTRAINED_AGREEMENT_RTOL * abs(b.cost)
    assert a.binding == b.binding
    assert [label for label, _ in a.violations] == [label for label, _ in b.violations]


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize(("seed", "kind", "formulation"), [(0, "free", "condensed"), (1, "binding", "condensed"),
                                                           (2, "binding", "sparse"), (3, "state", "condensed"),
                                                           (4, "binding", "condensed")])
def test_a_re_solve_on_the_compiled_program_is_the_cvxpy_paths_answer(protocol, seed, kind, formulation):
    """One controller re-solved for new (mu, x0) gives, point by point, what cvxpy's path gives on its own
    controller and what a fresh controller gives; cvxpy's public state (status, value, multipliers) is set as
    ``problem.solve`` sets it (the raw multipliers of two Clarabel solves differ by up to 2e-6 of the largest here,
    so the unpacking itself is compared on one solution, below)."""
    s = _system(seed)
    c = _constraints(s, protocol, kind)
    fast = ConstrainedQP(s, protocol, c, formulation)
    slow = _through_cvxpy(ConstrainedQP(s, protocol, c, formulation))
    solved = 0
    for mu, x0 in _points(s, np.random.default_rng(seed)):
        try:
            reference = slow.solve(mu, x0)
        except InfeasibleError:
            with pytest.raises(InfeasibleError):
                fast.solve(mu, x0)
            continue
        answer = fast.solve(mu, x0)
        solved += 1
        assert fast._program is not None
        assert fast.fast_path_refused == ""
        _agree(answer, reference)
        _agree(answer, _through_cvxpy(ConstrainedQP(s.with_mu(mu).with_x0(x0), protocol, c, formulation)).solve())
        assert answer.kkt_residual <= CONSTRAINED_KKT_RTOL
        assert fast.problem.status == slow.problem.status == "optimal"
        # the solvers' raw objectives, each to Clarabel's gap: within the band of a second formulation of the
        # constrained program (1.7e-7 relative on an objective of 0.0048 under Prescott, 2-binding-sparse-udp)
        assert abs(fast.problem.value - slow.problem.value) <= CONSTRAINED_AGREEMENT_RTOL * abs(slow.problem.value)
        assert fast.problem.value == fast.problem.objective.value              # as problem.solve sets it
        assert all(con.dual_value is not None for con in fast.problem.constraints)   # (their values: bit for bit below)
    assert solved >= 2
    if kind != "free":
        assert answer.binding or answer.violations


def _raw_clarabel(problem):
    """Clarabel's own solution object for ``problem`` as cvxpy builds and solves it, and cvxpy's chain."""
    data, chain, inverse = problem.get_problem_data(cp.CLARABEL, solver_opts={})
    raw = chain.solver.solve_via_data(data, False, False, {})
    return raw, chain, inverse


@pytest.mark.parametrize(("seed", "kind", "formulation"), [(1, "binding", "condensed"), (2, "binding", "sparse"),
                                                           (3, "state", "condensed"), (3, "state", "sparse")])
def test_the_compiled_programs_unpacking_is_cvxpys_bit_for_bit(seed, kind, formulation):
    """Given one Clarabel solution, ``ClarabelProgram.primals`` and ``duals`` are cvxpy's ``unpack_results`` of it,
    every variable and every multiplier to the last bit (soft slacks, declared nonneg, included)."""
    s = _system(seed)
    qp = ConstrainedQP(s, "udp", _constraints(s, "udp", kind), formulation)
    qp.solve()                                                    # the Parameters hold values
    qp.add_constraints([qp.U[0, 0] >= -10.0, cp.norm(qp.U[1]) <= 50.0])     # a user's rows, one a cone
    raw, chain, inverse = _raw_clarabel(qp.problem)
    program = ClarabelProgram(qp.problem, duals=True)
    point = ClarabelPoint(np.asarray(raw.x), {}, 0.0, np.asarray(raw.z))
    primals, duals = program.primals(point), program.duals(point)
    qp.problem.unpack_results(raw, chain, inverse)
    for variable in qp.problem.variables():
        assert np.array_equal(primals[variable.id], variable.value)
    for constraint in qp.problem.constraints:
        assert np.array_equal(duals[constraint.id], np.asarray(constraint.dual_value).reshape(np.shape(
            duals[constraint.id])))


def test_an_infeasible_re_solve_raises_with_the_certificate_cvxpys_path_gives():
    """x' = x + v u from 2, |u| <= 1/2, E[x_k] <= 1: no plan (the package's certificate, checked by hand in
    test_qp_constrained). The compiled path raises as cvxpy's does, with a verified certificate; the next, feasible
    re-solve on the same controller is the cvxpy path's answer."""
    s = pl.System(A=[[1.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[2.0])
    hard = Constraints(u_min=[-0.5], u_max=[0.5], x_max=[1.0])
    fast, slow = ConstrainedQP(s, "udp", hard), _through_cvxpy(ConstrainedQP(s, "udp", hard))
    errors = []
    for qp in (fast, slow):
        with pytest.raises(InfeasibleError, match="infeasible") as info:
            qp.solve()
        errors.append(info.value)
    assert errors[0].status == errors[1].status == "infeasible"
    assert errors[0].certificate["verdict"] == errors[1].certificate["verdict"] == "verified"
    assert errors[0].certificate["margin"] > 0
    _agree(fast.solve(x0=[0.5]), slow.solve(x0=[0.5]))
    with pytest.raises(SolverError) as info:        # a chance row: the solver's "infeasible" is not proved
        ConstrainedQP(s, "udp", Constraints(u_min=[-0.5], u_max=[0.5], chance=[([1.0], 1.0, 0.1)])).solve()
    assert not isinstance(info.value, InfeasibleError)
    assert (info.value.status, info.value.certificate["verdict"]) == ("infeasible", "undecided")


def test_the_users_constraints_are_compiled_into_the_next_solve():
    s = _system(5)
    c = _constraints(s, "tcp", "binding")
    fast = ConstrainedQP(s, "tcp", c)
    first = fast.solve()
    bound = first.inputs[0, 0] + 0.25 * (c.u_max[0] - first.inputs[0, 0])        # moves the plan
    for qp in (fast, slow := _through_cvxpy(ConstrainedQP(s, "tcp", c))):
        qp.add_constraints([qp.U[0, 0] >= bound])
    mine, theirs = fast.solve(), slow.solve()
    assert mine.inputs[0, 0] >= bound - CLARABEL_DEFAULT["tol_feas"] * max(1.0, abs(bound))    # a raw answer
    assert abs(mine.inputs[0, 0] - first.inputs[0, 0]) > 1e-3
    assert mine.kkt_residual is None                              # the KKT check does not cover the user's rows
    np.testing.assert_allclose(mine.inputs, theirs.inputs,                # unpolished: two solves' answers
                               atol=CONSTRAINED_AGREEMENT_RTOL * max(1.0, np.abs(theirs.inputs).max()))


def test_a_compilation_that_cannot_be_mapped_goes_through_cvxpy_and_says_why(monkeypatch):
    s = _system(6)
    c = _constraints(s, "udp", "binding")
    reference = ConstrainedQP(s, "udp", c).solve()

    def refuse(self, problem, duals=False):
        raise ValueError("a constraint's multiplier is not a selection of Clarabel's point")
    monkeypatch.setattr(ClarabelProgram, "__init__", refuse)
    qp = ConstrainedQP(s, "udp", c)
    _agree(qp.solve(), reference)
    assert "refused" in qp.fast_path_refused
    assert "selection" in qp.fast_path_refused


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_a_re_solve_depends_on_its_own_data_only(protocol):
    """The determinism contract (docs/design.md): a controller re-solved along a sequence of (mu, x0) gives, at each
    point, the solver's own answer (``U.value``, before the polish) and the returned plan bit for bit as a fresh
    controller solving that point first; the kept solvers carry no equilibration of earlier data."""
    s = _system(7, n=4, m=2, horizon=12)
    c = _constraints(s, protocol, "binding")
    qp = ConstrainedQP(s, protocol, c)
    for mu, x0 in _points(s, np.random.default_rng(8), count=4):
        try:
            answer = qp.solve(mu, x0)
        except InfeasibleError:
            continue
        raw = np.array(qp.U.value)
        fresh = ConstrainedQP(s, protocol, c)
        again = fresh.solve(mu, x0)
        assert np.array_equal(raw, fresh.U.value)
        assert np.array_equal(answer.inputs, again.inputs)
        assert answer.cost == again.cost
    assert qp._program is not None
    assert all(key and dict(key).get("equilibrate_enable") is False for key in qp._program._kept.solvers)
