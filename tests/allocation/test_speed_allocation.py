"""What the speed work must not change: the batched bisection of the brute-force reference takes the
sequential bisection's midpoints and decisions, and the allocation through the cached evaluator
returns what the per-call closed form gives."""

from types import SimpleNamespace

import numpy as np
import pytest

import packetloss_cvx as pl
import packetloss_cvx.allocation.tcp as tcp_module
import packetloss_cvx.allocation.udp as udp_module
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


class _PerCall:
    """J*(mu) by closed_form on every call, as the allocation did before the cached evaluator."""

    def __init__(self, system, protocol):
        self.system, self.protocol = system, protocol

    def cost(self, mu, x0=None, checked=True):      # closed_form checks every value anyway
        return pl.closed_form(self.system.with_mu(np.clip(mu, 0.0, 1.0)), self.protocol).cost

    def solve(self, mus):
        sols = [pl.closed_form(self.system.with_mu(mu), self.protocol) for mu in mus]
        return SimpleNamespace(costs=np.array([s.cost for s in sols]), inputs=np.array([s.inputs for s in sols]))

    def line(self, mu, i, checked=True):
        def at(value, base=np.array(mu, dtype=float)):  # noqa: B008
            point = base.copy()
            point[i] = value
            return self.cost(point)
        return at


@pytest.mark.parametrize("protocol", ["tcp", "udp"])
def test_allocation_through_the_evaluator_equals_the_per_call_closed_form(two_actuator, protocol, monkeypatch):
    cached = pl.allocate(two_actuator, protocol, 6.0, [1.0, 0.5])

    def per_call(system, p):
        ev = _PerCall(system, p)
        return ev.cost, ev

    monkeypatch.setattr(udp_module, "cost_function", per_call)
    monkeypatch.setattr(tcp_module, "cost_function", per_call)
    reference = pl.allocate(two_actuator, protocol, 6.0, [1.0, 0.5])
    assert np.allclose(cached.mu, reference.mu, rtol=0, atol=1e-9)
    assert abs(cached.lower_bound - reference.lower_bound) <= 1e-9 * reference.lower_bound
    assert (cached.status, cached.boxes) == (reference.status, reference.boxes)
