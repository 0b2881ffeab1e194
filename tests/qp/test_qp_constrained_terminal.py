"""The terminal set of the constrained QP (``terminal_min``/``terminal_max``, ``terminal_F``/``terminal_g`` on
E[x_N]: model/constraints.py, qp/constrained.py, the ``[constraints]`` table and ``solve --json``).

References, none taken from the code under test: J(U) = u'Hu + 2 f'u + c identified from `expected_cost` (exact for
a quadratic up to rounding) and E[x_N] written from matrix powers; with one terminal row that the free plan crosses,
the convex optimum has that row active, so it solves the equality-constrained KKT system
[2H c; c' 0] [u; lambda] = [-2f; d] by linear algebra; soft with a weight rho below that lambda, the optimum
minimises J + rho c'u unconstrained, u = -H^{-1}(f + rho c / 2)."""

import itertools
import json

import numpy as np
import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.errors import DimensionError, InputError
from packetloss_cvx.lq.costs import closed_form, expected_cost
from packetloss_cvx.model.constraints import Constraints, check_constraints
from packetloss_cvx.model.files import load_constraints, save_system
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.model.system import System
from packetloss_cvx.qp.constrained import ConstrainedQP, solve_constrained
from packetloss_cvx.tolerances import CONSTRAINED_AGREEMENT_RTOL, CONSTRAINED_KKT_RTOL


def _system(seed, n=3, m=2, horizon=4):
    return random_system(np.random.default_rng(seed), n=n, m=m, horizon=horizon, spectral_radius=0.9,
                         non_stationary=False, noise=True, time_varying=False, edge_mu=False)


def _quadratic(system, protocol):
    """(H, f): J(u) = u'Hu + 2 f'u + J(0), from J at 0, +-e_i and e_i + e_j."""
    k = system.horizon * system.m

    def J(u):
        return expected_cost(system, np.asarray(u).reshape(system.horizon, system.m), protocol)
    c = J(np.zeros(k))
    eye = np.eye(k)
    plus, minus = np.array([J(e) for e in eye]), np.array([J(-e) for e in eye])
    H = np.diag((plus + minus) / 2 - c)
    for i, j in itertools.combinations(range(k), 2):
        H[i, j] = H[j, i] = (J(eye[i] + eye[j]) - plus[i] - plus[j] + c) / 2
    return H, (plus - minus) / 4


def _terminal_mean(system):
    """E[x_N] = A^N x0 + M u (u step-major), M from matrix powers."""
    N, A = system.horizon, system.A
    M = np.hstack([np.linalg.matrix_power(A, N - 1 - j) @ system.B * system.mu_schedule[j] for j in range(N)])
    return np.linalg.matrix_power(A, N) @ system.x0, M


def _crossing_row(system, protocol, seed):
    """A direction f and a level g halfway between f'E[x_N] under U = 0 and under the free plan (which crosses)."""
    free = closed_form(system, protocol).inputs.ravel()
    x_free, M = _terminal_mean(system)
    for f in np.random.default_rng(seed).normal(size=(40, system.n)):
        low, high = f @ x_free, f @ (x_free + M @ free)
        if high > low + 1e-3 * (abs(low) + abs(high)):
            return f, (low + high) / 2
    raise AssertionError("no crossing direction")  # pragma: no cover


def _active_row_optimum(system, protocol, f, g):
    """min J s.t. f'E[x_N] = g, by the KKT system: (u, lambda)."""
    H, lin = _quadratic(system, protocol)
    x_free, M = _terminal_mean(system)
    c, d = M.T @ f, g - f @ x_free
    k = H.shape[0]
    K = np.block([[2 * H, c[:, None]], [c[None], np.zeros((1, 1))]])
    sol = np.linalg.solve(K, np.concatenate([-2 * lin, [d]]))
    return sol[:k], sol[k]


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
@pytest.mark.parametrize(("seed", "formulation"), [(0, "condensed"), (1, "sparse"), (2, "condensed")])
def test_a_terminal_polyhedron_row_is_the_equality_constrained_optimum(protocol, seed, formulation):
    s = _system(seed)
    f, g = _crossing_row(s, protocol, seed)
    sol = solve_constrained(s, protocol, Constraints(terminal_F=[f], terminal_g=[g]), formulation)
    u, lam = _active_row_optimum(s, protocol, f, g)
    assert lam > 0                                   # the row pushes back: the optimum lies on it
    assert sol.binding == (f"terminal_F[0] at k={s.horizon}",)
    assert sol.kkt_residual <= CONSTRAINED_KKT_RTOL
    scale = max(1.0, float(np.abs(u).max()))
    assert np.abs(sol.inputs.ravel() - u).max() <= CONSTRAINED_AGREEMENT_RTOL * scale
    assert sol.states[-1] @ f == pytest.approx(g, abs=CONSTRAINED_AGREEMENT_RTOL * max(1.0, abs(g)))
    # only the last predicted state is held: the same row on every E[x_k] (F, g) gives another plan or the same
    every = solve_constrained(s, protocol, Constraints(F=[f], g=[g]), formulation)
    assert all(label.startswith("F[0]") for label in every.binding)
    assert every.cost >= sol.cost * (1 - CONSTRAINED_AGREEMENT_RTOL)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_a_terminal_box_entry_and_its_soft_form(protocol):
    s = _system(5)
    x_free, M = _terminal_mean(s)
    free = closed_form(s, protocol).inputs.ravel()
    end = x_free + M @ free
    j = int(np.argmax(np.abs(end - x_free)))          # the entry the plan moves most
    sign = np.sign(end[j] - x_free[j])
    level = (x_free[j] + end[j]) / 2
    e = sign * np.eye(s.n)[j]
    box = np.full(s.n, np.inf)
    box[j] = sign * level
    name = "terminal_max" if sign > 0 else "terminal_min"
    kwargs = {name: box if sign > 0 else -box}
    sol = solve_constrained(s, protocol, Constraints(**kwargs))
    u, lam = _active_row_optimum(s, protocol, e, sign * level)
    assert sol.binding == (f"{name}[{j}] at k={s.horizon}",)
    assert sol.kkt_residual <= CONSTRAINED_KKT_RTOL
    assert np.abs(sol.inputs.ravel() - u).max() <= CONSTRAINED_AGREEMENT_RTOL * max(1.0, float(np.abs(u).max()))
    # soft with the weight half the hard multiplier: the penalty's slope rho is too small to hold the row, so the
    # optimum minimises J + rho e'E[x_N] without it, and reports the violation
    rho = lam / 2
    soft = solve_constrained(s, protocol, Constraints(**kwargs, soft=True, soft_weight=rho))
    H, lin = _quadratic(s, protocol)
    ref = -np.linalg.solve(H, lin + rho * (M.T @ e) / 2)
    assert e @ (x_free + M @ ref) > sign * level                        # the reference violates the row
    assert np.abs(soft.inputs.ravel() - ref).max() <= CONSTRAINED_AGREEMENT_RTOL * max(1.0, float(np.abs(ref).max()))
    (label, by), = soft.violations
    assert label == f"{name}[{j}] at k={s.horizon}"
    assert by == pytest.approx(e @ (x_free + M @ ref) - sign * level, rel=CONSTRAINED_AGREEMENT_RTOL)
    assert soft.kkt_residual <= CONSTRAINED_KKT_RTOL


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"terminal_min": [1.0, 0.0], "terminal_max": [0.0, 0.0]}, "terminal_min"),
    ({"terminal_min": [np.inf]}, "terminal_min"),
    ({"terminal_max": [-np.inf]}, "terminal_max"),
    ({"terminal_F": [[1.0]]}, "terminal_g"),
    ({"terminal_g": [1.0]}, "terminal_F"),
    ({"terminal_F": [[1.0, np.nan]], "terminal_g": [1.0]}, "terminal_F"),
    ({"terminal_F": [[1.0, 0.0]], "terminal_g": [1.0, 2.0]}, "terminal_g"),
    ({"terminal_F": [[1.0, 0.0]], "terminal_g": [np.nan]}, "terminal_g"),
])
def test_bad_terminal_sets_name_their_field(kwargs, field):
    with pytest.raises(InputError) as info:
        Constraints(**kwargs)
    assert info.value.field == field


def test_terminal_shapes_are_checked_against_the_system():
    with pytest.raises(DimensionError, match="terminal_max: expected 2 numbers"):
        check_constraints(Constraints(terminal_max=[1.0, 2.0, 3.0]), 2, 1)
    with pytest.raises(DimensionError, match="terminal_F"):
        check_constraints(Constraints(terminal_F=[[1.0, 2.0, 3.0]], terminal_g=[1.0]), 2, 1)


def test_the_terminal_set_round_trips_through_the_file_and_reaches_solve_json(tmp_path, capsys):
    # x' = x + v u from 1, mu = 1/2, N = 2, Q = R = 1, E[x_2] <= 0.5 (the free TCP-like plan ends higher)
    s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    c = Constraints(terminal_max=[0.2], terminal_min=[-np.inf], terminal_F=[[-1.0]], terminal_g=[5.0])
    path = save_system(s, tmp_path / "terminal.toml", constraints=c)
    assert load_constraints(path) == c
    assert main(["solve", str(path), "--json", "--no-stability"]) == 0
    out = json.loads(capsys.readouterr().out)
    for protocol in ("tcp", "udp"):
        entry = out[protocol]["constrained"]
        u, _ = _active_row_optimum(s, protocol, np.array([1.0]), 0.2)
        assert entry["binding"] == ["terminal_max[0] at k=2"]
        assert entry["terminal_state"] == pytest.approx([0.2], abs=1e-9)
        assert np.allclose(np.ravel(entry["inputs"]), u, atol=1e-9)
        assert 1.0 + 0.5 * sum(u) == pytest.approx(0.2, abs=1e-12)       # E[x_2] of the reference, by hand


@pytest.mark.parametrize(("table", "field"), [
    ("terminal_min = [1.0]\nterminal_max = [0.0]", "constraints.terminal_min"),
    ("terminal_max = [1.0, 2.0]", "constraints.terminal_max"),                    # n = 1
    ("terminal_F = [[1.0]]", "constraints.terminal_g"),
    ("terminal_F = [[1.0, 1.0]]\nterminal_g = [1.0]", "constraints.terminal_F"),  # n = 1
    ("terminal_set = [1.0]", "constraints.terminal_set"),                         # unknown key
])
def test_bad_terminal_sets_in_a_file_exit_2_with_one_line(tmp_path, capsys, table, field):
    s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    path = save_system(s, tmp_path / "bad.toml")
    path.write_text(path.read_text() + f"\n[constraints]\n{table}\n")
    assert main(["solve", str(path), "--json"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert f"error: {field}" in err[0]


def test_the_compiled_terminal_row_is_the_one_written_from_matrix_powers():
    """The cvxpy problem a user solves holds the row itself (the polish evaluates rows on its own moments)."""
    s = _system(7)
    f, g = _crossing_row(s, "udp", 7)
    qp = ConstrainedQP(s, "udp", Constraints(terminal_F=[f], terminal_g=[g]), "condensed")
    qp.solve()
    U = np.random.default_rng(3).normal(size=(s.horizon, s.m))
    qp.U.value = U
    x_free, M = _terminal_mean(s)
    (con,) = qp.problem.constraints
    assert float(np.ravel(con.expr.value)[0]) == pytest.approx(f @ (x_free + M @ U.ravel()) - g, abs=1e-12)
