"""Notebook objects: short reprs with the headline numbers, escaped HTML tables, to_json everywhere."""

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.results import Allocation, ClaimResult, CrossCheck, Maximiser, MinCost, Solution, Sweep


def big_system(n=40, m=5, name="a <b>big</b> plant"):
    rng = np.random.default_rng(7)
    return pl.System(A=rng.normal(size=(n, n)) / n, B=rng.normal(size=(n, m)), horizon=30, state_weight=np.ones(n),
                     input_weight=np.ones(m), mu=np.full(m, 0.7), x0=np.ones(n), name=name)


def test_system_repr_is_one_short_line_without_arrays():
    s = big_system()
    text = repr(s)
    assert text == "System('a <b>big</b> plant', n=40, m=5, horizon=30, mu=[0.7, 0.7, 0.7, 0.7, 0.7])"
    assert "\n" not in text
    long = repr(big_system(m=9))                      # a long channel vector is summarised by its shape
    assert long.endswith("mu=array of shape (9,))")
    assert "0.7" not in long


def test_non_stationary_system_says_so():
    s = pl.load_example("two_actuator")
    sched = np.tile([0.9, 0.5], (10, 1))
    sched[3] = [0.2, 0.2]
    assert "non-stationary, 10 steps" in repr(s.with_mu(sched))


def test_html_escapes_and_summarises():
    page = big_system()._repr_html_()
    assert "a &lt;b&gt;big&lt;/b&gt; plant" in page
    assert "<b>big</b>" not in page
    assert "array of shape (40, 40)" in page          # A is too large to show
    small = pl.load_example("two_actuator")._repr_html_()
    assert "[[1.03, 0.005], [0.35, 1.01]]" in small   # the example's A, as written in its TOML file


def test_solution_repr_and_html():
    s = pl.load_example("two_actuator")
    sol = pl.closed_form(s, "tcp", method="recursion")
    radius = sol.stability.radius
    assert repr(sol) == (f"Solution(protocol='tcp', cost={sol.cost:.10g}, basis='paper', method='recursion', N=10, "
                         f"m=2, loop='mean-square stable, radius {radius:.6g}')")
    page = sol._repr_html_()
    radius = max(abs(np.linalg.eigvals(s.A - s.B @ sol.gain)))    # B = I: A - B K from the gain itself
    assert f"{radius:.6g}" in page
    assert "shape (10, 2)" in page


def allocation():
    return Allocation(mu=np.array([0.25, 1.0]), communication_cost=0.3, cost=7.5, lower_bound=0.29, gap=0.01,
                      status="optimal", method="m", protocol="udp", alpha=8.0, beta=np.array([1.0, 0.05]), boxes=3)


def test_allocation_and_claim_reprs_are_headlines():
    assert repr(allocation()) == ("Allocation(protocol='udp', status='optimal', mu=[0.25, 1], communication_cost=0.3, "
                                  "cost=7.5, basis='paper', attainable_cost=None, stabilisable=None, alpha=8, "
                                  "gap=1.0e-02)")
    result = ClaimResult("theorem-2", "J_udp >= J_tcp", "holds", 5, 0, 0.5, None, "note <x>", outcomes="+++++")
    assert repr(result) == "ClaimResult('theorem-2', 'holds', checked=5, violations=0, errors=0)"
    page = result._repr_html_()
    assert "+++++" in page
    assert "note &lt;x&gt;" in page


@pytest.mark.parametrize("make", [
    lambda: pl.load_example("pendulum"),
    lambda: pl.closed_form(pl.load_example("two_actuator"), "udp"),
    allocation,
    lambda: ClaimResult("lemma-1", "s", "fails", 3, 1, -0.5, {"a": 1}, "n", errors=0, outcomes="+-+"),
    lambda: CrossCheck("dense", 1e-9, 1e-10),
    lambda: Maximiser(np.array([0.3]), 1.5, "grid"),
    lambda: MinCost("tcp", 2.0, 1.9, 0.05, "optimal", np.array([1.0, 1.0]), "socp"),
    lambda: Sweep((np.array([0.0, 1.0]),), {"tcp": np.array([3.0, 2.0])}, None, None),
])
def test_to_json_is_to_dict_as_json(make):
    obj = make()
    assert json.loads(obj.to_json()) == obj.to_dict()
    assert json.loads(obj.to_json(indent=2)) == obj.to_dict()


def test_batch_solution_repr_is_a_summary():
    from packetloss_cvx.results import BatchSolution

    batch = BatchSolution("tcp", np.array([3.0, 2.5, 7.25]), np.zeros((3, 10, 2)), np.zeros((3, 2, 2)), "dense")
    assert repr(batch) == "BatchSolution(protocol='tcp', points=3, method='dense', paper costs in [2.5, 7.25])"
    assert json.loads(batch.to_json()) == batch.to_dict()


def test_to_json_refuses_non_finite_numbers():
    sol = Solution("tcp", float("inf"), np.zeros((1, 1)), None, None, "dense")
    with pytest.raises(ValueError, match="not JSON compliant"):
        sol.to_json()


def test_every_result_type_has_a_one_line_repr_and_json():
    """Issue 13: every result type prints its headline numbers in one line (arrays by shape when
    large) and has to_json; checked on each type's own fields, built from a real computation."""
    import json

    import packetloss_cvx as pl
    import packetloss_cvx.results as results
    from packetloss_cvx.closedloop.moments import closed_loop
    from packetloss_cvx.closedloop.riccati import dp_riccati

    for name in results.__all__:
        cls = getattr(results, name)
        if isinstance(cls, type):
            assert hasattr(cls, "to_json"), name
            assert cls.__repr__ is not object.__repr__, name
    s = pl.load_example("pendulum")
    for obj in (closed_loop(s, pl.closed_form(s, "tcp").gain), dp_riccati(s)):
        text = repr(obj)
        assert "\n" not in text
        assert len(text) < 400
        assert json.loads(obj.to_json())


def test_a_bursty_system_says_so_in_its_repr():
    """repr(load_example('pendulum_bursty')) was System('pendulum-bursty', ..., mu=[0.9]): a Bernoulli look-alike."""
    system = pl.load_example("pendulum_bursty")
    assert "GilbertElliott" in repr(system)
    assert "GilbertElliott" in system._repr_html_()
    assert "GilbertElliott" not in repr(system.with_mu([0.9]))   # with_mu drops the chain



def test_a_gilbert_elliott_repr_shows_what_was_given():
    from packetloss_cvx.model.channel import GilbertElliott
    assert repr(GilbertElliott(p=[0.1], r=[0.4])) == "GilbertElliott(m=1, p=[0.1], r=[0.4])"
    text = repr(GilbertElliott(p=[0.1], r=[0.4], state=["bad"]))
    assert text == "GilbertElliott(m=1, p=[0.1], r=[0.4], state=['bad'])"
    text = repr(GilbertElliott(p=[0.1], r=[0.4], h_good=0.9, h_bad=0.2, belief=[0.3]))
    assert text == "GilbertElliott(m=1, p=[0.1], r=[0.4], h_good=[0.9], h_bad=[0.2], belief=[0.3])"
