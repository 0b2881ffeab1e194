"""The brute-force reference allocator (allocation/brute_force.py): its batched bisection takes the sequential
bisection's midpoints and decisions; its batched speculation and read-back points take the decisions of the plain
search its docstring describes, written here point by point (the same (beta'mu, mu1, mu2) to the last bit); run
side by side (requests pooled), each case answers what it answers alone, and a case whose evaluation fails fails
alone."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.allocation.brute_force import bisect, brute_force_allocation, brute_force_allocations
from packetloss_cvx.lq.evaluator import CostEvaluator


def _sequential(feasible, a, b, tol):
    while b - a > tol:
        mid = 0.5 * (a + b)
        a, b = (a, mid) if feasible(mid) else (mid, b)
    return b


@pytest.mark.parametrize("seed", range(5))
def test_batched_bisection_takes_the_sequential_steps(seed):
    rng = np.random.default_rng(seed)
    for _ in range(200):
        edge = rng.uniform(-0.2, 1.2)
        a, b = rng.uniform(0.0, 0.5), rng.uniform(0.5, 1.0)
        tol = 10 ** rng.uniform(-12, -2)
        seen = []

        def batch(points, edge=edge, seen=seen):
            seen.append(len(points))
            return [p >= edge for p in points]

        got = bisect(batch, a, b, tol, depth=int(rng.integers(1, 6)))
        assert got == _sequential(lambda x, edge=edge: x >= edge, a, b, tol)


def _plain_search(system, protocol, alpha, beta, G, h, coarse, fine, tol):
    """The brute force as its docstring states it, one point and one bisection step at a time."""
    ev = CostEvaluator(system, protocol, "recursion")

    def ok(mu1, mu2):
        return ev.costs(np.array([[mu1, mu2]]))[0] <= alpha

    def scan(points, best):
        for mu1 in points:
            mu1 = float(mu1)
            cap = np.inf if best is None or beta[1] <= 0 else (best[0] - beta[0] * mu1) / beta[1]
            lo, hi = 0.0, 1.0
            skip = False
            for g, c in zip(G, h, strict=True):
                if g[1] > 0:
                    hi = min(hi, (c - g[0] * mu1) / g[1])
                elif g[1] < 0:
                    lo = max(lo, (c - g[0] * mu1) / g[1])
                elif g[0] * mu1 > c + 1e-12:
                    skip = True
            top = min(hi, cap)
            if skip or lo > top or not ok(mu1, top):
                continue
            if ok(mu1, lo):
                mu2 = lo
            else:
                a, b = lo, top
                while b - a > tol:
                    mid = 0.5 * (a + b)
                    a, b = (a, mid) if ok(mu1, mid) else (mid, b)
                mu2 = b
            if best is None or beta[0] * mu1 + beta[1] * mu2 < best[0]:
                best = (float(beta[0] * mu1 + beta[1] * mu2), mu1, float(mu2))
        return best

    best = scan(np.linspace(0, 1, coarse), None)
    if best is None:
        return None
    step = 1 / (coarse - 1)
    return scan(np.clip(np.linspace(best[1] - step, best[1] + step, fine), 0, 1), best)


@pytest.mark.parametrize(("protocol", "alpha", "beta", "rows"), [
    ("udp", 6.0, (1.0, 0.05), None),            # a cap above 1: J*(mu1, 1) asked again after each new best
    ("udp", 8.0, (1.0, 2.0), None),
    ("tcp", 5.0, (1.0, 1.0), ([[1.0, -1.0]], [0.1])),
])
def test_brute_force_takes_the_plain_searchs_decisions(two_actuator, protocol, alpha, beta, rows):
    G, h = (np.zeros((0, 2)), np.zeros(0)) if rows is None else (np.array(rows[0]), np.array(rows[1]))
    grid = {"coarse": 21, "fine": 11, "tol": 1e-8}
    got = brute_force_allocation(two_actuator, protocol, alpha, beta, G, h, **grid)
    assert got is not None
    assert got == _plain_search(two_actuator, protocol, alpha, np.array(beta), G, h, **grid)


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_searches_side_by_side_answer_what_each_answers_alone(two_actuator, protocol):
    cases = [(4.78, (1.0, 1.0)), (6.0, (0.05, 1.0)), (8.0, (1.0, 0.05)), (20.0, (1.0, 2.0)),
             (5.0, (1.0, 1.0), np.array([[1.0, -1.0]]), np.array([0.1])), (1.0, (1.0, 1.0))]   # the last: none
    grid = {"coarse": 21, "fine": 11, "tol": 1e-8}
    alone = [brute_force_allocation(two_actuator, protocol, *case, **grid) for case in cases]
    assert alone[-1] is None
    assert brute_force_allocations(two_actuator, protocol, cases, **grid) == alone


def test_a_failing_search_fails_alone():
    """x' = 3x over 330 steps: J* overflows at mu = (0, 0), which only the unconstrained search asks."""
    s = pl.System(A=3 * np.eye(2), B=np.eye(2), horizon=330, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
                  mu=[0.5, 0.5], x0=[1.0, 1.0])
    high = (50.0, (1.0, 1.0), -np.eye(2), np.array([-0.9, -0.9]))          # mu1, mu2 >= 0.9 only
    grid = {"coarse": 5, "fine": 3}
    with pytest.raises(pl.NumericalError, match="overflowed") as alone:
        brute_force_allocation(s, "tcp", 50.0, (1.0, 1.0), **grid)
    ok, failed = brute_force_allocations(s, "tcp", [high, (50.0, (1.0, 1.0))], **grid)
    assert ok == brute_force_allocation(s, "tcp", *high, **grid) == (1.9, 1.0, 0.9)
    assert isinstance(failed, pl.NumericalError)
    assert str(failed) == str(alone.value)


def test_a_search_failing_after_the_others_ended_fails_alone(monkeypatch):
    """The last search left running fails: the others' answers are kept and it gets its error (the whole
    call raised it when only one request was left, losing the answers of the cases already settled)."""
    t = pl.System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
                  mu=[0.5, 0.5], x0=[1.0, 1.0])
    costs = CostEvaluator.costs

    def failing(self, mus, x0=None):       # J* undefined where mu1 > 0.5 and mu2 < 0.3 (as an overflow)
        mus = np.asarray(mus)
        if np.any((mus[:, 1] < 0.3) & (mus[:, 0] > 0.5)):
            raise pl.NumericalError("no J* here")
        return costs(self, mus, x0)

    monkeypatch.setattr(CostEvaluator, "costs", failing)
    settled, late = (0.1, (1.0, 1.0)), (1.5, (1.0, 1.0))     # J* >= 1 > 0.1: settled in the first round
    grid = {"coarse": 11, "fine": 11}
    assert brute_force_allocation(t, "tcp", *settled, **grid) is None
    with pytest.raises(pl.NumericalError, match="no J"):
        brute_force_allocation(t, "tcp", *late, **grid)
    first, second = brute_force_allocations(t, "tcp", [settled, late], **grid)
    assert first is None
    assert isinstance(second, pl.NumericalError)
