"""convex.py: Clarabel under one status policy, and a DPP problem compiled once (ClarabelProgram) whose
solves are cvxpy's own solve of the same problem, bit for bit."""

import cvxpy as cp
import numpy as np
import pytest

import packetloss_cvx.qp.convex as convex
from packetloss_cvx.allocation.tcp import TCPProgram
from packetloss_cvx.errors import SolverError
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp.convex import ClarabelProgram, first_answer, solve_problem
from packetloss_cvx.tolerances import (
    ALLOCATION_CLARABEL_ATTEMPTS,
    ALLOCATION_TCP_ATTEMPTS,
    CLARABEL_DEFAULT,
    CLARABEL_TIGHT,
    ROUNDING_ORDER_RTOL,
)


def _random_values(program: TCPProgram, system, rng, rows):
    """Parameter values of a TCP-like program: a random x0, scale, bounds, rows (with zero entries, which
    cvxpy drops from the data) and prices."""
    m = system.m
    lo = rng.uniform(0.0, 0.3, m) * (rng.uniform(size=m) < 0.5)
    hi = np.maximum(lo, rng.uniform(0.6, 1.0, m))
    G = rng.normal(size=(rows, m)) * (rng.uniform(size=(rows, m)) < 0.6)
    h = np.abs(G) @ hi + 0.1
    values = {program.x0: rng.normal(size=system.n), program.root: rng.uniform(0.05, 2.0), program.lo: lo,
              program.hi: hi}
    if program.kind == "allocate":
        values[program.beta] = rng.uniform(0.5, 1.5, m)
    if rows:
        values.update({program.rows[0]: G, program.rows[1]: h})
    return values


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize(("kind", "rows"), [("allocate", 0), ("allocate", 2), ("min_cost", 1)])
def test_compiled_solve_is_cvxpys_solve_bit_for_bit(seed, kind, rows):
    """The reference is cvxpy itself: the same problem, Parameters assigned, problem.solve cold under the
    same attempts. Same status, same mu to the last bit (the data, cones and settings are the same)."""
    rng = np.random.default_rng(seed)
    s = random_system(rng, n=int(rng.integers(1, 4)), m=int(rng.integers(1, 4)), horizon=int(rng.integers(2, 9)))
    program = TCPProgram(s, kind, rows)
    for _ in range(3):
        values = _random_values(program, s, rng, rows)
        status, point = program.compiled.solve(values, "compiled", ALLOCATION_CLARABEL_ATTEMPTS)
        for parameter, value in values.items():
            parameter.value = value
        expected = solve_problem(program.problem, "cvxpy", tuple({**a, "warm_start": False}
                                                                 for a in ALLOCATION_CLARABEL_ATTEMPTS))
        assert status == expected
        if status == "optimal":
            assert np.array_equal(point(program.mu), program.mu.value)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize(("kind", "rows"), [("allocate", 0), ("allocate", 2), ("min_cost", 1)])
def test_a_kept_solver_updated_with_new_data_is_a_new_solver_bit_for_bit(seed, kind, rows):
    """Attempts without equilibration (the TCP-like program's first) run on a solver kept and updated with each
    solve's data. Reference: cvxpy's own problem.solve, cold (a new solver each time), under the same attempts,
    for a sequence of values on one program: same status and the same mu to the last bit, whatever was solved
    before on the kept solver."""
    rng = np.random.default_rng(100 + seed)
    s = random_system(rng, n=int(rng.integers(1, 4)), m=int(rng.integers(2, 4)), horizon=int(rng.integers(2, 12)))
    program = TCPProgram(s, kind, rows)
    attempts = tuple({**a, "warm_start": False} for a in ALLOCATION_TCP_ATTEMPTS)
    for _ in range(5):
        values = _random_values(program, s, rng, rows)
        status, point = program.compiled.solve(values, "compiled", ALLOCATION_TCP_ATTEMPTS)
        for parameter, value in values.items():
            parameter.value = value
        assert status == solve_problem(program.problem, "cvxpy", attempts)
        if status == "optimal":
            assert np.array_equal(point(program.mu), program.mu.value)


def test_kept_solvers_are_per_thread():
    """Two threads solving one program at once (a shared System's program) get the answers a single thread gets,
    bit for bit: each thread updates its own kept solver."""
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(7)
    s = random_system(rng, n=3, m=3, horizon=10)
    program = TCPProgram(s, "allocate", 1)
    batches = [[_random_values(program, s, rng, 1) for _ in range(6)] for _ in range(2)]

    def run(batch):
        return [program.compiled.solve(v, "threads", ALLOCATION_TCP_ATTEMPTS) for v in batch]

    serial = [[(st, pt(program.mu).copy()) for st, pt in run(b)] for b in batches]
    with ThreadPoolExecutor(2) as pool:
        parallel = [[(st, pt(program.mu).copy()) for st, pt in out] for out in pool.map(run, batches)]
    for one, other in zip(serial, parallel, strict=True):
        for (st1, mu1), (st2, mu2) in zip(one, other, strict=True):
            assert st1 == st2
            assert np.array_equal(mu1, mu2, equal_nan=True)


@pytest.mark.parametrize("shape", [(8, 8), (24, 16), (64, 64)])
def test_a_quadratic_objective_is_cvxpys_solve_bit_for_bit(shape):
    """The shared condensed QP (a quadratic objective: P mapped once) through ClarabelProgram against cvxpy's
    problem.solve of the same problem, cold: same status and z to the last bit (the same data to one solver), the
    objective value (qp_shared.objective_value against cvxpy's evaluation) to rounding, on data padded as the
    audit pads them and scaled over nine decades."""
    from packetloss_cvx.qp.shared import CondensedQP

    rng = np.random.default_rng(sum(shape))
    compiled, reference = CondensedQP(*shape), CondensedQP(*shape)
    R, K = shape
    for _ in range(8):
        rows, k = int(rng.integers(1, R + 1)), int(rng.integers(1, K + 1))
        c = rng.normal(size=rows) * 10.0 ** rng.integers(-6, 3)
        G = rng.normal(size=(rows, k)) * (rng.uniform(size=(rows, k)) < 0.7)
        r = rng.uniform(0.0, 2.0, k)
        z, value, status = compiled.solve(c, G, r, "compiled")
        reference.c.value, reference.G.value = np.pad(c, (0, R - rows)), np.pad(G, ((0, R - rows), (0, K - k)))
        reference.r.value = np.pad(r, (0, K - k), constant_values=1.0)
        expected = solve_problem(reference.problem, "cvxpy", ({**CLARABEL_TIGHT, "warm_start": False},))
        assert status == expected == "optimal"
        assert np.array_equal(z, reference.z.value[:k])
        assert value == pytest.approx(reference.problem.value, rel=ROUNDING_ORDER_RTOL)


def test_both_paths_pin_clarabels_linear_solver(monkeypatch):
    """ClarabelProgram (the shared condensed QP, compiled) and cvxpy's problem.solve (solve_problem) both run Clarabel
    with its linear solver pinned (tolerances.CLARABEL_LINEAR_SOLVER, QDLDL), on a dense 64 x 64 program for which
    Clarabel's own default ("auto") picks faer's supernodal solver: the linear solver each built solver reports."""
    import clarabel

    from packetloss_cvx.qp.shared import CondensedQP

    used, made = [], clarabel.DefaultSolver

    def built(*args, **kwargs):
        solver = made(*args, **kwargs)
        used.append(solver.get_info().linsolver.name)
        return solver

    monkeypatch.setattr(clarabel, "DefaultSolver", built)
    rng = np.random.default_rng(3)
    c, G, r = rng.normal(size=64), rng.normal(size=(64, 64)), rng.uniform(0.0, 2.0, 64)

    def cvxpy_solve(settings):
        reference = CondensedQP(64, 64)
        reference.c.value, reference.G.value, reference.r.value = c, G, r
        assert solve_problem(reference.problem, "cvxpy", ({**settings, "warm_start": False},)) == "optimal"

    cvxpy_solve({**CLARABEL_TIGHT, "direct_solve_method": "auto"})
    assert used == ["faer"]                               # what the pin avoids, on this program
    used.clear()
    status = CondensedQP(64, 64).solve(c, G, r, "compiled")[2]
    assert status == "optimal"
    cvxpy_solve(CLARABEL_TIGHT)
    cvxpy_solve(CLARABEL_DEFAULT)
    assert used == ["qdldl"] * 3


def test_a_quadratic_objective_by_hand():
    """min ||x - a||^2 + 1 is 1 at x = a: the point and the value with the objective's constant."""
    x, a = cp.Variable(2), cp.Parameter(2)
    program = ClarabelProgram(cp.Problem(cp.Minimize(cp.sum_squares(x - a) + 1.0)))
    status, point = program.solve({a: [1.0, -2.0]}, "a QP")
    assert status == "optimal"
    assert np.allclose(point(x), [1.0, -2.0], rtol=0, atol=1e-8)
    assert abs(point.value - 1.0) < 1e-8


def test_compiled_data_is_cvxpys_data():
    """(q, A, b) equal those cvxpy hands Clarabel for the same values, structure included (explicit zeros)."""
    rng = np.random.default_rng(7)
    s = random_system(rng, n=3, m=3, horizon=5)
    program = TCPProgram(s, "allocate", 2)
    values = _random_values(program, s, rng, 2)
    values[program.rows[0]] = np.array([[1.0, 0.0, -2.0], [0.0, 0.0, 3.0]])
    _, q, A, b = program.compiled.data(values)
    for parameter, value in values.items():
        parameter.value = value
    data, _, _ = program.problem.get_problem_data(cp.CLARABEL)
    assert np.array_equal(q, data["c"])
    assert np.array_equal(b, data["b"])
    A, ref = A.tocsc(), data["A"].tocsc()
    assert np.array_equal(A.indptr, ref.indptr)
    assert np.array_equal(A.indices, ref.indices)
    assert np.array_equal(A.data, ref.data)


def test_compiled_solve_refuses_bad_values():
    x, a = cp.Variable(2), cp.Parameter(2)
    program = ClarabelProgram(cp.Problem(cp.Minimize(cp.sum(x)), [cp.norm(x - a) <= 1]))
    with pytest.raises(SolverError, match="not finite"):
        program.solve({a: [np.inf, 0.0]}, "an SOCP")
    with pytest.raises(SolverError, match="missing"):
        program.solve({}, "an SOCP")
    with pytest.raises(SolverError, match="reshape|size"):
        program.solve({a: [1.0, 2.0, 3.0]}, "an SOCP")
    with pytest.raises(ValueError, match="DPP"):
        ClarabelProgram(cp.Problem(cp.Minimize(cp.sum(x)), [cp.multiply(a, a) @ x >= 1]))


def test_compiled_solve_follows_the_status_policy(monkeypatch):
    """Proven infeasibility stops the attempts; the tight settings' failure falls through to the defaults."""
    x, a = cp.Variable(), cp.Parameter()
    program = ClarabelProgram(cp.Problem(cp.Minimize(x), [x >= a, x <= 0]))
    assert program.solve({a: 1.0}, "an LP")[0] == "infeasible"
    status, point = program.solve({a: -0.25}, "an LP")
    assert status == "optimal"
    assert np.isclose(point(x), -0.25, atol=1e-8)
    seen = []

    def attempt(settings):
        seen.append(settings)
        return "optimal_inaccurate" if settings is CLARABEL_TIGHT else "optimal"

    assert first_answer(attempt, (CLARABEL_TIGHT, CLARABEL_DEFAULT)) == "optimal"
    assert len(seen) == 2
    monkeypatch.setattr(convex.CLARABEL, "STATUS_MAP", {})      # every Clarabel status unknown
    assert program.solve({a: -0.25}, "an LP")[0] == "solver_error"


#: pyo3's panic type as Clarabel raises it: ``pyo3_runtime.PanicException``, a BaseException (no Python module
#: exports it; a real panic, "Eigval error" in the PSD cone, needs the search's state to reproduce)
PanicException = type("PanicException", (BaseException,), {"__module__": "pyo3_runtime"})


def _panics(*args, **kwargs):
    raise PanicException("Eigval error: Eigen(1)")


def test_a_clarabel_panic_in_problem_solve_is_a_solver_error(monkeypatch):
    x = cp.Variable()
    problem = cp.Problem(cp.Minimize(cp.square(x - 1)))
    monkeypatch.setattr(cp.Problem, "solve", _panics)
    with pytest.raises(SolverError, match=r"an SDP: Clarabel panicked \(Eigval error: Eigen\(1\)\)") as info:
        solve_problem(problem, "an SDP")
    assert info.value.status == "solver_error"


def test_a_clarabel_panic_in_the_compiled_program_is_a_solver_error(monkeypatch):
    x, a = cp.Variable(2), cp.Parameter(2)
    program = ClarabelProgram(cp.Problem(cp.Minimize(cp.sum(x)), [cp.norm(x - a) <= 1]))
    monkeypatch.setattr(convex.clarabel, "DefaultSolver", _panics)
    with pytest.raises(SolverError, match=r"an SOCP: Clarabel panicked"):
        program.solve({a: [1.0, 2.0]}, "an SOCP")


def test_an_interrupt_during_a_solve_is_not_a_solver_error(monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    x = cp.Variable()
    monkeypatch.setattr(cp.Problem, "solve", interrupted)
    with pytest.raises(KeyboardInterrupt):
        solve_problem(cp.Problem(cp.Minimize(cp.square(x))), "a QP")


def test_each_solve_runs_on_a_new_clarabel_solver(monkeypatch):
    """solve_problem never updates the solver of an earlier solve in place: an updated Clarabel solver carries the
    first data's equilibration, and one panicked where a new solver on the same data failed cleanly (the pendulum's
    stabilising LMI at --margin 1e-9). Two solves of one problem: two solvers built, and the second answer is the
    least (x - a)^2's, x = a (by hand)."""
    built = []
    convex_clarabel_solver = convex.clarabel.DefaultSolver

    def counting(*args, **kwargs):
        built.append(args)
        return convex_clarabel_solver(*args, **kwargs)
    monkeypatch.setattr(convex.clarabel, "DefaultSolver", counting)
    x, a = cp.Variable(), cp.Parameter()
    problem = cp.Problem(cp.Minimize(cp.square(x - a)))
    for value in (1.0, 3.0):
        a.value = value
        assert solve_problem(problem, "a scalar QP", attempts=(CLARABEL_TIGHT,)) == "optimal"
    assert len(built) == 2
    assert float(x.value) == pytest.approx(3.0, abs=1e-7)
