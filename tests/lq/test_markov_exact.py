"""The exact expected cost under Gilbert–Elliott losses: against the dense second-moment form built
from path enumeration, against Monte Carlo (4 standard errors) on seeded random systems, its
minimiser in closed form against the cvxpy + Clarabel QP, and the memoryless reduction to Bernoulli."""

import importlib

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.lq.markov_cost import exact_closed_form, exact_cost
from packetloss_cvx.lq.prediction import prediction
from packetloss_cvx.model.chain import attach_channel
from packetloss_cvx.model.channel import GilbertElliott
from packetloss_cvx.model.files import system_from_dict
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.montecarlo.markov_channels import sample_markov_plan_costs
from packetloss_cvx.qp.markov import exact_qp
from packetloss_cvx.tolerances import SELF_CHECK_RTOL
from tests.model.test_markov_chain import moments_by_enumeration, random_channel


def bursty(seed, **kwargs):
    rng = np.random.default_rng(seed)
    s = random_system(rng, spectral_radius=rng.uniform(0.5, 1.1), **kwargs)
    return attach_channel(s, random_channel(rng, s.m, given=seed % 2 == 0))


def dense_reference(system, U):
    """C + 2U'Vbar Omega_gp x + U'(Omega_g o R + Vbar Psi)U with R from path enumeration."""
    pred = prediction(system)
    ch, N, m = system.channel, system.horizon, system.m
    R = np.outer(pred.Vbar, pred.Vbar)
    for i in range(m):
        Ri = moments_by_enumeration(ch.p[i], ch.r[i], ch.h_good[i], ch.h_bad[i], ch.initial_belief[i, 0], N)
        idx = np.arange(N) * m + i
        R[np.ix_(idx, idx)] = Ri
    u, x = U.ravel(), system.x0
    const = x @ (system.initial_weight + pred.Omega_p) @ x + pred.noise_term
    quad = u @ (pred.Omega_g * R) @ u + np.sum(pred.Vbar * pred.Psi * u * u)
    return const + 2 * u @ (pred.Vbar * (pred.Omega_gp @ x)) + quad


@pytest.mark.parametrize("seed", range(8))
def test_exact_cost_matches_the_dense_second_moment_form(seed):
    s = bursty(seed)
    U = np.random.default_rng(seed + 100).normal(size=(s.horizon, s.m))
    assert exact_cost(s, U) == pytest.approx(dense_reference(s, U), rel=1e-9)


@pytest.mark.parametrize("seed", range(5))
def test_exact_cost_agrees_with_monte_carlo(seed):
    s = bursty(1000 + seed)
    U = np.random.default_rng(seed).normal(size=(s.horizon, s.m))
    costs = sample_markov_plan_costs(s, U, 40_000, np.random.default_rng(seed + 50))
    se = costs.std(ddof=1) / np.sqrt(costs.size)
    assert abs(costs.mean() - exact_cost(s, U)) <= 4 * se


@pytest.mark.parametrize("seed", range(8))
def test_closed_form_minimiser_agrees_with_the_qp(seed):
    s = bursty(200 + seed)
    closed = exact_closed_form(s)
    qp = exact_qp(s, reference=closed)                      # raises CrossCheckError on disagreement
    assert qp.status == "optimal"
    assert qp.cost == pytest.approx(closed.cost, rel=1e-7)
    # the gradient of the dense reference vanishes at the minimiser (central differences of a quadratic: exact)
    u = closed.inputs.ravel()
    mu = s.mu_schedule.ravel()
    for j in np.flatnonzero(mu > 0):
        e = np.zeros_like(u)
        e[j] = 1e-3
        grad = (dense_reference(s, (u + e).reshape(closed.inputs.shape))
                - dense_reference(s, (u - e).reshape(closed.inputs.shape))) / 2e-3
        assert abs(grad) <= 1e-6 * max(1.0, closed.cost)
    assert closed.cost == pytest.approx(exact_cost(s, closed.inputs), rel=1e-9)


def test_qp_cross_check_binds():
    s = bursty(3)
    closed = exact_closed_form(s)
    wrong = pl.Solution(protocol="udp", cost=closed.cost * 1.01, inputs=closed.inputs, gain=None,
                        closed_loop_eigenvalues=None, method="planted")
    with pytest.raises(pl.CrossCheckError, match="disagree"):
        exact_qp(s, reference=wrong)


@pytest.mark.parametrize("state", [None, ["good", "bad"], ["bad", "good"]])
def test_memoryless_chain_reduces_exactly_to_bernoulli(state):
    s = pl.load_example("two_actuator")
    p, r = np.array([0.1, 0.5]), np.array([0.9, 0.5])
    g = attach_channel(s, GilbertElliott(p=p, r=r, state=state))
    first = r if state is None else np.array([1.0 if x == "good" else 0.0 for x in state])
    bern = s.with_mu(np.vstack([first, np.repeat(r[None], s.horizon - 1, axis=0)]))
    for protocol in ("udp", "tcp"):
        ref = pl.closed_form(bern, protocol, method="dense")
        got = exact_closed_form(g, protocol)
        assert got.cost == pytest.approx(ref.cost, rel=1e-12)
        delivered = bern.mu_schedule > 0
        np.testing.assert_allclose(got.inputs[delivered], ref.inputs[delivered], rtol=1e-10, atol=1e-12)
    U = np.random.default_rng(0).normal(size=(s.horizon, s.m))
    assert exact_cost(g, U) == pytest.approx(pl.expected_cost(bern, U, "udp"), rel=1e-13)


def test_plugin_udp_law_loses_only_under_correlation():
    s = pl.load_example("two_actuator")
    for lam, loses in ((0.0, False), (0.8, True), (-0.1, True)):
        total = 1.0 - lam                                   # p + r; the average rate stays mu = (0.9, 0.5)
        g = attach_channel(s, GilbertElliott(p=(1 - s.mu) * total, r=s.mu * total))
        np.testing.assert_allclose(g.mu_schedule, np.broadcast_to(s.mu, g.mu_schedule.shape), rtol=1e-14)
        plugin = pl.closed_form(g.with_mu(g.mu_schedule), "udp")
        exact = exact_closed_form(g)
        excess = exact_cost(g, plugin.inputs) - exact.cost
        assert excess >= -1e-9 * exact.cost
        assert (excess > 1e-6 * exact.cost) == loses


def test_tcp_exact_is_the_plugin_law():
    s = bursty(5)
    got, ref = exact_closed_form(s, "tcp"), pl.closed_form(s, "tcp")
    assert got.cost == ref.cost
    np.testing.assert_array_equal(got.inputs, ref.inputs)
    assert exact_cost(s, ref.inputs, "tcp") == pytest.approx(pl.expected_cost(s, ref.inputs, "tcp"), rel=1e-15)
    assert exact_qp(s, "tcp").cost == pytest.approx(ref.cost, rel=1e-7)


def test_the_udp_like_cost_of_a_chain_is_refused_not_the_plug_in_number():
    """closed_form(pendulum_bursty, "udp") returned 15706, the paper's formula on the chain's mu_t, while
    the expected cost of that plan under the chain is 51735: a number without a word. It is refused now,
    with the two ways out; the TCP-like cost (first moments only) stays exact."""
    from packetloss_cvx.errors import InputError
    from packetloss_cvx.lq.markov_cost import exact_closed_form, exact_cost

    s = pl.load_example("pendulum_bursty")
    for call in (lambda: pl.closed_form(s, "udp"), lambda: pl.solve_qp(s, "udp"),
                 lambda: pl.expected_cost(s, [[0.0]] * s.horizon, "udp")):
        with pytest.raises(InputError, match="exact_closed_form") as err:
            call()
        assert err.value.field == "channel"
    plug_in = pl.closed_form(s.with_mu(s.mu_schedule), "udp")
    assert exact_cost(s, plug_in.inputs, "udp") > 3 * plug_in.cost       # 51735 against 15706
    assert exact_closed_form(s, "udp").cost < exact_cost(s, plug_in.inputs, "udp")
    assert pl.closed_form(s, "tcp").cost == pytest.approx(exact_closed_form(s, "tcp").cost, rel=1e-10)


@pytest.mark.parametrize(("factor", "kept"), [(3.0, False), (0.3, True)])
def test_dense_closed_form_self_check_refuses_3_and_keeps_0_3_times_self_check_rtol(monkeypatch, factor, kept):
    """The dense route's J* off the exact forward cost of its own plan (exact_cost, method 'dense') by 3
    SELF_CHECK_RTOL (relative) raises, by 0.3 is returned."""
    exact_module = importlib.import_module("packetloss_cvx.lq.markov_cost")   # the name is also a function
    s = bursty(3)
    exact = exact_closed_form(s, method="dense").cost
    real = exact_module.exact_cost
    monkeypatch.setattr(exact_module, "exact_cost", lambda *a, **k: real(*a, **k) * (1 + factor * SELF_CHECK_RTOL))
    if kept:
        assert exact_closed_form(s, method="dense").cost == exact
    else:
        with pytest.raises(pl.NumericalError, match="the forward cost of its own plan"):
            exact_closed_form(s, method="dense")


def test_markov_exact_cost_of_a_plan_is_refused_where_its_mean_states_are_not_resolved():
    """The Gilbert-Elliott pendulum over 2000 steps under the plug-in law's plan: the TCP-like cost (the mean states
    alone) is refused as the Bernoulli one is. The UDP-like cost is returned: the lost inputs' variance, amplified
    by A^t, makes it about 1e106, beside which the mean states' rounding (1e78) is nothing. With a chain that never
    loses (p = 0, mu = 1) the UDP-like cost is the mean states' alone, and it is refused."""
    from packetloss_cvx.lq.markov_cost import exact_cost

    data = pl.load_example("pendulum_bursty").to_dict()
    data["cost"]["horizon"] = 2000
    bursty = system_from_dict(data)
    data["channel"]["p"] = [0.0]
    perfect = system_from_dict(data)
    U = pl.closed_form(bursty.with_mu(bursty.mu_schedule), "tcp").inputs
    with pytest.raises(pl.NumericalError, match="not resolved"):
        exact_cost(bursty, U, "tcp")
    assert exact_cost(bursty, U, "udp") > 1e100
    U = pl.closed_form(perfect.with_mu(perfect.mu_schedule), "tcp").inputs
    with pytest.raises(pl.NumericalError, match="udp-like expected cost of this plan is not resolved"):
        exact_cost(perfect, U, "udp")
