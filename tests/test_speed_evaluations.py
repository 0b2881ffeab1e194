"""What the audit's speed work on J* evaluations must not change.

* A point's cost from the batched recursion does not depend on the batch it is in (the brute
  force reads repeated points back instead of evaluating them again): checked bit for bit
  against the point evaluated alone.
* The brute-force allocator (batched speculation, read-back points) takes the decisions of the
  plain search its docstring describes, written here point by point: the same (beta'mu, mu1, mu2)
  to the last bit.
"""

import numpy as np
import pytest

from packetloss_cvx.allocation.brute_force import brute_force_allocation
from packetloss_cvx.evaluator import CostEvaluator
from packetloss_cvx.random_systems import random_system


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_a_points_cost_does_not_depend_on_its_batch(seed, protocol):
    rng = np.random.default_rng(seed)
    s = random_system(rng)
    ev = CostEvaluator(s, protocol, "recursion")
    for P in (2, 15, 63):
        mus = rng.uniform(0.0, 1.0, (P, s.m))
        mus[0] = 1.0
        batch = ev.costs(mus)
        alone = np.array([ev.costs(mu[None])[0] for mu in mus])
        assert np.array_equal(batch, alone)
        assert np.array_equal(ev.costs(mus[::-1]), batch[::-1])


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
