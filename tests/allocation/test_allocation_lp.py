"""allocation.boxes.small_lp, the tangent-cut LP of the TCP-like allocation: Clarabel's interior point with
a proved bound, against HiGHS (scipy.optimize.linprog) as the independent reference."""

import numpy as np
import pytest
from scipy.optimize import linprog

import packetloss_cvx.allocation.boxes as boxes
from packetloss_cvx.allocation.boxes import polished, small_lp
from packetloss_cvx.tolerances import ALLOCATION_LP_FEASIBILITY


def _cut_lp(rng, m):
    """An LP shaped like the cut LPs: tangents of a convex decreasing function at a point and +- small steps
    (nearly parallel rows), a few general rows, bounds inside [0, 1]."""
    p = rng.uniform(0.1, 0.9, m)
    points = [p] + [p + s * e for s in (1e-3, -1e-3, 1e-5, -1e-5) for e in np.eye(m)]
    S = np.array([-1.0 / (1.0 + q) ** 2 * rng.uniform(0.5, 1.5, m) for q in points])
    h_cuts = rng.uniform(0.05, 0.5) + S @ p - np.abs(S).sum(axis=1) * rng.uniform(0.0, 0.3)
    rows = rng.normal(size=(int(rng.integers(0, 3)), m))
    G = np.vstack([S / np.abs(S).max(axis=1, keepdims=True), rows])
    h = np.concatenate([h_cuts / np.abs(S).max(axis=1), np.abs(rows).sum(axis=1) * 0.6])
    l = rng.uniform(0.0, 0.2, m) * (rng.uniform(size=m) < 0.5)
    return rng.uniform(0.0, 1.5, m), G, h, l, np.ones(m)


@pytest.mark.parametrize("seed", range(40))
def test_small_lp_bound_is_proved_and_as_tight_as_highs(seed):
    rng = np.random.default_rng(seed)
    c, G, h, l, u = _cut_lp(rng, int(rng.integers(1, 6)))
    ref = linprog(c, A_ub=G, b_ub=h, bounds=list(zip(l, u, strict=True)), method="highs")
    point, bound = small_lp(c, G, h, l, u)
    if ref.status == 2:
        assert point is None and bound == np.inf
        return
    assert ref.status == 0
    scale = max(abs(ref.fun), 1.0)
    assert bound <= ref.fun + 1e-9 * scale                       # a lower bound (HiGHS's optimum to its tolerance)
    assert bound >= ref.fun - 5e-11 * scale                      # as tight as HiGHS (1.8e-10 unpolished)
    assert np.all((l <= point) & (point <= u))
    assert np.max(G @ point - h) <= ALLOCATION_LP_FEASIBILITY
    assert c @ point <= ref.fun + 1e-8 * scale


def test_polished_multipliers_reach_the_optimum_and_never_lower_the_bound():
    """min mu1 + 2 mu2 s.t. mu1 + mu2 >= 1, mu1 <= 0.75 over [0, 1]^2: optimum 1.25 at (0.75, 0.25),
    multipliers (2, 1) by hand. Rough multipliers prove less; polished ones prove 1.25; a wrong point's
    guess never makes the bound worse than the rough multipliers'."""
    c, G, h = np.array([1.0, 2.0]), np.array([[-1.0, -1.0], [1.0, 0.0]]), np.array([-1.0, 0.75])
    l, u = np.zeros(2), np.ones(2)
    rough = np.array([1.9, 0.8])
    assert boxes.dual_bound(c, G, h, l, u, rough) < 1.25 - 1e-3
    assert polished(c, G, h, l, u, np.array([0.75, 0.25]), rough) == pytest.approx(1.25, abs=1e-14)
    assert polished(c, G, h, l, u, np.array([0.3, 0.3]), rough) >= boxes.dual_bound(c, G, h, l, u, rough)


def test_small_lp_falls_back_to_highs_when_clarabel_does_not_solve(monkeypatch):
    calls = []
    real = boxes.lp

    def highs(*args):
        calls.append(args)
        return real(*args)

    class Stalled:
        def __init__(self, *args):
            pass

        def solve(self):
            return type("Solution", (), {"status": "InsufficientProgress", "x": [np.nan], "z": [np.nan]})()

    monkeypatch.setattr(boxes, "lp", highs)
    monkeypatch.setattr(boxes.clarabel, "DefaultSolver", Stalled)
    c, G, h, l, u = np.ones(2), np.array([[-1.0, -1.0]]), np.array([-1.0]), np.zeros(2), np.ones(2)
    point, bound = small_lp(c, G, h, l, u)
    assert len(calls) == 1 and bound == pytest.approx(1.0) and np.isclose(point.sum(), 1.0)


def _box_lp(rng):
    """A random LP of the searches' shape: a few channels, a few rows (some zeros), a sub-box of [0, 1]^m,
    sometimes infeasible."""
    m, r = int(rng.integers(1, 6)), int(rng.integers(1, 5))
    G = rng.normal(size=(r, m))
    G[rng.uniform(size=(r, m)) < 0.3] = 0.0
    l = rng.uniform(0.0, 0.3, m)
    return rng.normal(size=m), G, rng.normal(size=r) + 1.0, l, l + rng.uniform(0.0, 1.0, m)


@pytest.mark.parametrize("seed", range(6))
def test_lp_answers_bit_for_bit_as_linprog(seed):
    """allocation.boxes.lp calls scipy's HiGHS directly (highs_optimum): the same point, the same multipliers
    and the same verdict as scipy.optimize.linprog with the same options, to the last bit, on 50 random LPs."""
    rng = np.random.default_rng(seed)
    for _ in range(50):
        c, G, h, l, u = _box_lp(rng)
        ref = linprog(c, A_ub=G, b_ub=h, bounds=list(zip(l, u, strict=True)), method="highs", options=boxes._HIGHS)
        direct = boxes.highs_optimum(c, G, h, l, u)
        point, bound = boxes.lp(c, G, h, l, u)
        if ref.status == 2:
            assert direct == (None, None)
            assert point is None
            assert bound == np.inf
            continue
        assert ref.status == 0
        assert np.array_equal(direct[0], ref.x)
        assert np.array_equal(direct[1], ref.ineqlin.marginals)
        assert np.array_equal(point, np.clip(ref.x, l, u))
        assert bound == boxes.dual_bound(c, G, h, l, u, -ref.ineqlin.marginals)


def test_lp_leaves_what_highs_does_not_solve_to_linprog(monkeypatch):
    """Where the direct call has no answer (an older scipy, here simulated), lp runs linprog: same result."""
    c, G, h, l, u = np.ones(2), np.array([[-1.0, -1.0]]), np.array([-1.0]), np.zeros(2), np.ones(2)
    monkeypatch.setattr(boxes, "highs_optimum", lambda *args: None)
    point, bound = boxes.lp(c, G, h, l, u)
    assert point.sum() == pytest.approx(1.0)
    assert bound == 1.0
    assert boxes.lp(c, G, np.array([-3.0]), l, u) == (None, np.inf)


def test_lp_answers_by_linprog_when_scipys_private_highs_binding_changed(monkeypatch):
    """boxes calls scipy's private HiGHS binding: a scipy whose binding lost a name (AttributeError) or changed a
    signature (TypeError) gets linprog's answer, not an exception; the options builder likewise gives None."""
    c, G, h, l, u = np.ones(2), np.array([[-1.0, -1.0]]), np.array([-1.0]), np.zeros(2), np.ones(2)
    ref = linprog(c, A_ub=G, b_ub=h, bounds=list(zip(l, u, strict=True)), method="highs", options=boxes._HIGHS)

    class Renamed:              # the binding without HighsLp / HighsOptions
        pass

    class Resigned:             # the binding whose constructors take other arguments
        def HighsLp(self, *args):   # noqa: N802 - the binding's name
            raise TypeError("HighsLp() takes 1 positional argument")

    for binding in (Renamed(), Resigned()):
        monkeypatch.setattr(boxes, "highs_core", binding)
        assert boxes.highs_optimum(c, G, h, l, u) is None
        point, bound = boxes.lp(c, G, h, l, u)
        assert np.array_equal(point, np.clip(ref.x, l, u))
        assert bound == 1.0
    monkeypatch.setattr(boxes, "highs_core", Renamed())
    assert boxes._highs_options() is None


@pytest.mark.parametrize("bad", [np.inf, -np.inf, np.nan])
def test_lp_refuses_a_non_finite_right_hand_side_as_linprog_does(bad):
    """linprog refuses a right-hand side with inf or nan (ValueError); lp's direct HiGHS call must leave such data to
    it, not answer (HiGHS takes h = +inf as a free row, and the weak-duality bound is then nan)."""
    c, G, l, u = np.ones(2), np.array([[-1.0, -1.0], [1.0, 0.0]]), np.zeros(2), np.ones(2)
    h = np.array([-1.0, bad])
    with pytest.raises(ValueError, match="b_ub"):
        linprog(c, A_ub=G, b_ub=h, bounds=list(zip(l, u, strict=True)), method="highs", options=boxes._HIGHS)
    assert boxes.highs_optimum(c, G, h, l, u) is None
    with pytest.raises(ValueError, match="b_ub"):
        boxes.lp(c, G, h, l, u)


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_an_answer_outside_the_rows_by_3_lp_feasibilities_is_refused_and_by_0_3_kept(factor, kept):
    """Every answer is checked against the bounds and rows to ALLOCATION_LP_FEASIBILITY (HiGHS's own feasibility
    tolerance): a row mu1 + mu2 <= 1 or the bound mu <= 1 missed by 3 times it raises SolverError naming the
    excess; by 0.3 times the point is returned as it is."""
    from packetloss_cvx.allocation.boxes import check_in_polytope
    from packetloss_cvx.allocation.grammar import read_polytope
    from packetloss_cvx.errors import SolverError

    poly = read_polytope([([[1.0, 1.0]], [1.0])], 2, 0.0, 1.0)
    excess = factor * ALLOCATION_LP_FEASIBILITY
    for mu in (np.array([0.5, 0.5 + excess]), np.array([0.0, 1.0 + excess])):
        if kept:
            assert check_in_polytope(mu, poly, "a test") is mu
        else:
            with pytest.raises(SolverError, match="a test: mu violates the constraints by 3.00e-09"):
                check_in_polytope(mu, poly, "a test")


def test_a_clarabel_panic_in_the_small_lp_falls_back_to_highs(monkeypatch):
    """min mu1 + mu2 s.t. mu1 + mu2 >= 1 over [0, 1]^2 is 1 (by hand), decided by HiGHS when Clarabel panics."""
    panic = type("PanicException", (BaseException,), {"__module__": "pyo3_runtime"})

    def panics(*args, **kwargs):
        raise panic("Eigval error: Eigen(1)")
    monkeypatch.setattr(boxes.clarabel, "DefaultSolver", panics)
    c, G, h, lo, hi = np.ones(2), np.array([[-1.0, -1.0]]), np.array([-1.0]), np.zeros(2), np.ones(2)
    point, bound = boxes.small_lp(c, G, h, lo, hi)
    assert point.sum() == pytest.approx(1.0)
    assert bound == pytest.approx(1.0)
