"""The condensed QP shared by shape (qp_shared): its answers against the sparse form (dynamics as
constraints, compiled per system: an independent formulation) and the closed form, on seeded random
systems of many shapes; no state carried from one system to the next; the cache's bound."""

import threading

import cvxpy as cp
import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.model.files import load_example
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.qp import shared as qp_shared
from packetloss_cvx.qp.shared import CondensedQP, cached_shapes, clear_cache, condensed_problem, objective_value, padded
from packetloss_cvx.tolerances import CLARABEL_TIGHT, CROSS_CHECK_COST_RTOL, CROSS_CHECK_INPUT_ATOL, ROUNDING_ORDER_RTOL


def _systems(seed: int, count: int) -> list[pl.System]:
    """Random shapes (n, m <= 4, N <= 8), stable and unstable, schedules, edge channels, noise."""
    rng = np.random.default_rng(seed)
    return [random_system(rng) for _ in range(count)]


def _agree(got: pl.Solution, ref: pl.Solution, system: pl.System) -> None:
    """The cross-check's own tolerances (qp.compare), stated here against an independent reference."""
    mu = system.mu_schedule
    scale = max(float(np.abs(mu * ref.inputs).max(initial=0.0)), 1e-9 * float(np.abs(system.x0).max(initial=0.0)))
    assert float(np.abs(mu * (got.inputs - ref.inputs)).max(initial=0.0)) <= CROSS_CHECK_INPUT_ATOL * scale
    assert abs(got.cost - ref.cost) <= CROSS_CHECK_COST_RTOL * max(abs(ref.cost), 1e-300)


@pytest.mark.parametrize("seed", [3, 4])
def test_shared_problems_agree_with_the_sparse_form_and_the_closed_form(seed):
    clear_cache()
    for s in _systems(seed, 20) + ([load_example("two_actuator")] if seed == 3 else []):
        for protocol in ("tcp", "udp"):
            shared = pl.ExpectedCostQP(s, protocol, "condensed").solve(cross_check=False)
            sparse = pl.ExpectedCostQP(s, protocol, "sparse").solve(cross_check=False)
            _agree(shared, sparse, s)
            _agree(shared, pl.closed_form(s, protocol, method="recursion"), s)
            assert np.allclose(shared.gain, sparse.gain, rtol=1e-5, atol=1e-6 * max(1.0, np.abs(sparse.gain).max()))
    assert len(cached_shapes()) < 40                     # 40 systems x 2 protocols, far fewer compiles


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_zero_mu_channels_zero_state_and_no_state_weight(protocol):
    rng = np.random.default_rng(21)
    s = random_system(rng, n=3, m=3, horizon=5, non_stationary=True, spectral_radius=1.1)
    mu = s.mu_schedule.copy()
    mu[:, 1] = 0.0
    mu[2, 0] = 0.0
    for case in (s.with_mu(mu), s.with_x0(np.zeros(3)), s.with_mu(np.zeros(3))):
        got = pl.ExpectedCostQP(case, protocol, "condensed").solve(cross_check=False)
        _agree(got, pl.ExpectedCostQP(case, protocol, "sparse").solve(cross_check=False), case)
        _agree(got, pl.closed_form(case, protocol, method="recursion"), case)
    unweighted = pl.System(A=s.A, B=s.B, horizon=5, state_weight=np.zeros((3, 3)), input_weight=[1.0, 2.0, 0.5],
                           mu=[0.5, 0.2, 0.9], x0=s.x0, initial_weight=np.eye(3))
    got = pl.ExpectedCostQP(unweighted, protocol, "condensed").solve(cross_check=False)
    assert np.all(got.inputs == 0.0) or np.abs(got.inputs).max() < 1e-12      # nothing to steer: u* = 0
    assert got.cost == pytest.approx(float(s.x0 @ s.x0), rel=1e-12)           # x0' I x0, hand value


def test_two_systems_of_one_bucket_solved_alternately_keep_their_own_answers():
    """A larger system leaves data in every row and column of the bucket; the smaller one solved next
    must see none of it (every Parameter, padding included, is re-assigned) and get, bit for bit, the
    answer it gets alone in a fresh process cache (the solves are cold: no equilibration carried over)."""
    rng = np.random.default_rng(31)
    big = random_system(rng, n=4, m=4, horizon=4, non_stationary=False)        # R = 16, K = 16
    small = random_system(rng, n=3, m=3, horizon=3, non_stationary=True)       # R = 9, K = 9
    assert padded(16) == padded(9) == 16
    clear_cache()
    alone = {}
    for name, s in (("big", big), ("small", small)):
        clear_cache()
        alone[name] = pl.ExpectedCostQP(s, "udp", "condensed").solve(with_gain=False, cross_check=False)
    clear_cache()
    qps = {"big": pl.ExpectedCostQP(big, "udp", "condensed"), "small": pl.ExpectedCostQP(small, "udp", "condensed")}
    problem = condensed_problem(16, 16)
    for name in ("big", "small", "big", "small"):
        got = qps[name].solve(with_gain=False, cross_check=False)
        assert np.array_equal(got.inputs, alone[name].inputs)
        assert got.cost == alone[name].cost
        if name == "small":
            assert np.all(problem.c.value[9:] == 0.0)
            assert np.all(problem.G.value[9:, :] == 0.0)
            assert np.all(problem.G.value[:, 9:] == 0.0)
            assert np.all(problem.r.value[9:] == 1.0)
            assert np.all(problem.z.value[9:] == 0.0) or np.abs(problem.z.value[9:]).max() < 1e-12
    assert problem.solves == 4
    assert cached_shapes() == [(16, 16)]


def test_a_warm_re_solve_would_carry_the_previous_systems_scaling():
    """Why the solves are cold: cvxpy's default re-solve updates Clarabel's data in place with the
    equilibration of the first data, so an answer would depend on what was solved before it."""
    rng = np.random.default_rng(41)
    data = [(rng.normal(size=6), rng.normal(size=(6, 6)), rng.uniform(0.5, 2.0, 6)),
            (rng.normal(size=6) * 1e3, rng.normal(size=(6, 6)) * 1e4, rng.uniform(0.5, 2.0, 6) * 1e-3)]
    cold = CondensedQP(8, 8)
    cold.solve(*data[0], "first")
    z_cold = cold.solve(*data[1], "second")[0]
    assert np.array_equal(z_cold, CondensedQP(8, 8).solve(*data[1], "second alone")[0])
    warm = CondensedQP(8, 8)                       # cvxpy's default re-solve of the same problem: warm
    for c, G, r in data:                           # padded to the problem's 8 x 8 as CondensedQP.solve pads
        warm.c.value, warm.G.value = np.pad(c, (0, 2)), np.pad(G, ((0, 2), (0, 2)))
        warm.r.value = np.pad(r, (0, 2), constant_values=1.0)
        warm.problem.solve(solver=cp.CLARABEL, **CLARABEL_TIGHT)
    assert warm.problem.status == "optimal"
    assert not np.array_equal(warm.z.value[:6], z_cold)


def test_the_cache_is_bounded_and_large_shapes_are_private(monkeypatch):
    clear_cache()
    monkeypatch.setattr(qp_shared, "SHARED_CACHE_SIZE", 3)
    for rows in (8, 16, 24, 32, 16):
        condensed_problem(rows, 8)
    assert cached_shapes() == [(24, 8), (32, 8), (16, 8)]                      # (8, 8) dropped, 16 used last
    big = condensed_problem(qp_shared.SHARED_MAX_ENTRIES // 8 + 1, 9)
    assert not big.shared
    assert big.shape == (qp_shared.SHARED_MAX_ENTRIES // 8 + 1, 9)
    assert (padded(qp_shared.SHARED_MAX_ENTRIES // 8 + 1), 16) not in cached_shapes()
    clear_cache()


def test_an_object_keeps_its_private_problem_beyond_the_shared_sizes(monkeypatch):
    monkeypatch.setattr(qp_shared, "SHARED_MAX_ENTRIES", 10)
    s = random_system(np.random.default_rng(51), n=2, m=2, horizon=3, non_stationary=False)
    qp = pl.ExpectedCostQP(s, "udp", "condensed")
    got = qp.solve(cross_check=False)                                           # n + 1 = 3 solves
    (private,) = qp.backend._own.values()
    assert not private.shared
    assert private.solves == 3
    assert private.shape == (6, 6)
    _agree(got, pl.closed_form(s, "udp", method="recursion"), s)


def test_threads_sharing_a_bucket_get_their_own_answers():
    systems = [random_system(np.random.default_rng(60 + k), n=2, m=2, horizon=3) for k in range(6)]
    clear_cache()
    expected = [pl.ExpectedCostQP(s, "udp", "condensed").solve(with_gain=False, cross_check=False) for s in systems]
    got: dict[int, list] = {}

    def work(k: int) -> None:
        qp = pl.ExpectedCostQP(systems[k], "udp", "condensed")
        got[k] = [qp.solve(with_gain=False, cross_check=False) for _ in range(5)]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k, answers in got.items():
        assert all(np.array_equal(a.inputs, expected[k].inputs) and a.cost == expected[k].cost for a in answers)
    assert len(got) == 6


@pytest.mark.parametrize(("rows", "cols"), [(8, 8), (16, 8), (32, 24)])
def test_the_objective_value_is_cvxpys_evaluation(rows, cols):
    """objective_value against cvxpy's own numeric evaluation of the compiled expression (Parameters and the
    Variable assigned, problem.objective.value): the same value to rounding (ROUNDING_ORDER_RTOL), at scales
    1e-3..1e3, and a solve reports it."""
    rng = np.random.default_rng(rows * cols)
    qp = CondensedQP(rows, cols)
    for _ in range(50):
        c, z = rng.normal(size=rows) * 10 ** rng.uniform(-3, 3), rng.normal(size=cols) * 10 ** rng.uniform(-3, 3)
        G, r = rng.normal(size=(rows, cols)), np.abs(rng.normal(size=cols))
        qp.c.value, qp.G.value, qp.r.value, qp.z.value = c, G, r, z
        assert objective_value(c, G, r, z) == pytest.approx(float(qp.problem.objective.value), rel=ROUNDING_ORDER_RTOL)
    z, value, status = qp.solve(c, G, r, "a random QP")
    qp.z.value = z
    assert status == "optimal"
    assert value == pytest.approx(float(qp.problem.objective.value), rel=ROUNDING_ORDER_RTOL)


def test_data_larger_than_the_problem_are_refused():
    with pytest.raises(pl.InputError, match="do not fit"):
        CondensedQP(8, 8).solve(np.zeros(9), np.zeros((9, 2)), np.ones(2), "too many rows")


@pytest.mark.parametrize(("a", "N", "mu"), [(4.0, 25, 0.5), (4.0, 25, 0.9), (8.0, 16, 0.5)])
def test_an_unresolvable_minimum_is_refused_not_reported(a, N, mu):
    """x' = [[a, 1], [0, 0.5]] x + [1, 1]' u over N steps: L Phi x ~ 1e15 against a minimum ~ 50. The shared
    (Parameter) problem can end 'optimal' with J off the recursion's by 2e-5 to 8e-3 relative: it is refused with
    NumericalError (as the per-system problem is, and `solve` then prints 'QP cross-check skipped'), neither
    reported with cross_check=False nor blamed on a disagreement (CrossCheckError)."""
    s = pl.System(A=[[a, 1.0], [0.0, 0.5]], B=[[1.0], [1.0]], horizon=N, state_weight=[1.0, 1.0],
                  input_weight=[1.0], mu=[mu], x0=[1.0, 1.0])
    with pytest.raises(pl.NumericalError, match="cannot resolve|Clarabel ended"):
        pl.ExpectedCostQP(s, "tcp", "condensed").solve(with_gain=False, cross_check=False)


def test_the_resolution_guard_keeps_badly_scaled_but_resolvable_minima():
    """Input weights down to 1e-18 of the state weights (a minimum ~1e-9 of ||L Phi x||^2) are still solved."""
    s = pl.System(A=[[0.9, 0.2], [0.0, 0.7]], B=[[1.0], [0.3]], horizon=20, state_weight=[1.0, 1.0],
                  input_weight=[1e-18], mu=[0.6], x0=[1.0, -2.0])
    for protocol in ("tcp", "udp"):
        sol = pl.ExpectedCostQP(s, protocol, "condensed").solve(with_gain=False)     # cross-checked
        assert sol.cross_check.cost_rel_diff <= CROSS_CHECK_COST_RTOL
