"""The brute-force reference allocator (allocation/brute_force.py): its batched bisection takes the sequential
bisection's midpoints and decisions; its batched speculation and read-back points take the decisions of the plain
search its docstring describes, written here point by point (the same (beta'mu, mu1, mu2) to the last bit); run
side by side (requests pooled), each case answers what it answers alone, and a case whose evaluation fails fails
alone."""

import numpy as np
import pytest

from packetloss_cvx.allocation.brute_force import bisect


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
