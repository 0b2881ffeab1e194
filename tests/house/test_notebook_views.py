"""Notebook views of the results: one-line reprs, an HTML table for every result type with the numbers a user
looks at first, and a design sweep's arrays on its axes (DesignSweep.grid)."""

import dataclasses
import html
import re

import numpy as np
import pytest

import packetloss_cvx as pl
import packetloss_cvx.results as results
from packetloss_cvx import InputError
from packetloss_cvx.closedloop.law_stability import with_stability
from packetloss_cvx.closedloop.moments import closed_loop
from packetloss_cvx.closedloop.riccati import dp_riccati
from packetloss_cvx.montecarlo.simulate import simulate
from packetloss_cvx.studies import sweep


def second_moment_radius(A, B, K, mu):
    """Spectral radius of S -> Abar S Abar' + sum_i mu_i (1 - mu_i) F_i S F_i' (F_i = b_i k_i), from its Kronecker
    matrix: the textbook form, independent of simulation.stability's operator and ARPACK paths."""
    Abar = A - B @ np.diag(mu) @ K
    L = np.kron(Abar, Abar)
    for i, p in enumerate(mu):
        F = np.outer(B[:, i], K[i])
        L = L + p * (1 - p) * np.kron(F, F)
    return max(abs(np.linalg.eigvals(L)))


def cells(page):
    """The text of every table cell, unescaped."""
    return [html.unescape(c) for c in re.findall(r"<t[dh][^>]*>(.*?)</t[dh]>", page)]


@pytest.fixture(scope="module")
def grid_sweep():
    return sweep(pl.load_example("two_actuator"), mu_grid=5, stability=True)


def test_design_sweep_repr_is_one_short_line(grid_sweep):
    text = repr(grid_sweep)
    assert "\n" not in text and len(text) < 300
    assert text.startswith("DesignSweep('two-actuator', kind='mu-grid', shape={'mu2': 5, 'mu1': 5}, ")
    assert f"J*_tcp (paper) in [{grid_sweep.costs['tcp'].min():.6g}, {grid_sweep.costs['tcp'].max():.6g}]" in text
    big = sweep(pl.load_example("two_actuator"), mu_grid=41)
    assert len(repr(big)) < 300                     # 1681 points: still the ranges, never the arrays


def test_grid_puts_each_point_on_its_axes(grid_sweep):
    s = pl.load_example("two_actuator")
    mu2, mu1 = grid_sweep.axes
    assert grid_sweep.grid("cost_udp").shape == (5, 5) and grid_sweep.grid("mu").shape == (5, 5, 2)
    assert grid_sweep.grid("x0").shape == (5, 5, 2)
    for j, i in [(0, 0), (1, 3), (4, 2), (3, 4)]:
        # an independent solve at (mu1, mu2) = (axis mu1[i], axis mu2[j]): rows follow mu2
        for protocol in ("tcp", "udp"):
            expected = pl.closed_form(s.with_mu([mu1[i], mu2[j]]), protocol, method="recursion").cost
            assert grid_sweep.grid(f"cost_{protocol}")[j, i] == pytest.approx(expected, rel=1e-12)
        assert grid_sweep.grid("mu")[j, i].tolist() == [mu1[i], mu2[j]]
        K = pl.closed_form(s.with_mu([mu1[i], mu2[j]]), "tcp").gain
        assert grid_sweep.grid("radius_tcp")[j, i] == pytest.approx(second_moment_radius(s.A, s.B, K,
                                                                                         [mu1[i], mu2[j]]), rel=1e-9)
    assert not grid_sweep.grid("cost_tcp").flags.writeable
    assert grid_sweep.costs["tcp"].shape == (25,)   # the flat fields stay as they were


def test_grid_on_a_horizon_sweep_and_unknown_names():
    s = pl.load_example("two_actuator")
    result = sweep(s, horizons=[2, 5, 9])
    assert result.grid("horizon").tolist() == [2, 5, 9]
    assert result.grid("cost_tcp")[1] == pytest.approx(pl.closed_form(
        pl.System(A=s.A, B=s.B, horizon=5, state_weight=s.state_weights[0], input_weight=s.input_weights[0],
                  mu=s.mu, x0=s.x0), "tcp").cost, rel=1e-12)
    with pytest.raises(InputError, match="cost_tcp") as err:
        result.grid("cost")
    assert err.value.field == "name"


def test_design_sweep_view_shows_ranges_maxima_and_stable_points(grid_sweep):
    page = cells(grid_sweep._repr_html_())
    diff = grid_sweep.grid("cost_diff")
    j, i = np.unravel_index(np.argmax(diff), diff.shape)
    mu2, mu1 = grid_sweep.axes
    row = page[page.index("J_Delta = J*_udp - J*_tcp, paper") + 1]
    assert f"max at ({j}, {i}): mu2 = {mu2[j]:.4g}, mu1 = {mu1[i]:.4g}" in row
    stable = sum(second_moment_radius(*(lambda s, K: (s.A, s.B, K, p))(pl.load_example("two_actuator"),
                 pl.closed_form(pl.load_example("two_actuator").with_mu(p), "udp").gain)) < 1 for p in grid_sweep.mu)
    assert f"stable (< 1) at {stable} of 25" in page[page.index("mean-square radius, udp") + 1]


def test_closed_loop_view_is_the_mean_square_radius():
    for name, stable in (("two_actuator", "yes"), ("pendulum", "no")):     # the pendulum's TCP-like law is not
        s = pl.load_example(name)
        K = pl.closed_form(s, "tcp").gain
        page = cells(closed_loop(s, K, "tcp")._repr_html_())
        radius = second_moment_radius(s.A, s.B, K, s.mu)
        assert page[page.index("mean-square spectral radius") + 1] == f"{radius:.6g}"
        assert page[page.index("mean-square stable") + 1] == stable
        assert (radius < 1) == (stable == "yes")
    assert "inf (" in page[page.index("average stage cost") + 1]


def test_simulation_view_has_a_row_per_law():
    s = pl.load_example("two_actuator")
    sim = simulate(s, 500, steps=10, seed=1, closed_loop=True)
    page = cells(sim._repr_html_())
    assert "500 runs, 10 steps, seed 1" in sim._repr_html_()
    for law in ("tcp", "udp"):
        o, c = sim.open_loop[law], sim.closed_loop[law]
        row = page[page.index(law):page.index(law) + 8]
        assert row[1] == f"{pl.closed_form(s, law).cost:.6g}"             # the formula, solved again
        assert row[2] == f"{o.mean:.6g} ± {o.stderr:.2g}" and row[4] == f"{o.z:.2f}"
        assert row[5] == f"{c.mean_stage_cost:.6g} ± {c.stderr:.2g}"
    dp = page[page.index("dp"):page.index("dp") + 8]
    assert dp[1:5] == ["-"] * 4                                            # no open loop for the DP law


def test_solution_view_says_which_radius_it_shows():
    s = pl.load_example("pendulum")
    sol = pl.closed_form(s, "tcp", stability=False)
    page = cells(sol._repr_html_())
    radius = max(abs(np.linalg.eigvals(s.A - s.B @ sol.gain)))
    shown = page[page.index("radius of A - B K (all delivered)") + 1]
    assert shown == f"{radius:.6g}" + (": UNSTABLE even with every packet delivered" if radius >= 1 else "")
    # without the verdict the view says so and names the call that attaches it
    assert "with_stability(system, solution)" in page[page.index("mean-square stability") + 1]
    # not the mean-square radius over the channel, which is another number
    assert abs(radius - second_moment_radius(s.A, s.B, sol.gain, s.mu)) > 1e-3


def test_solution_view_shows_mean_square_stability_over_the_channel():
    s = pl.load_example("pendulum")
    plain = pl.closed_form(s, "tcp", stability=False)
    sol = with_stability(s, plain)
    expected = second_moment_radius(s.A, s.B, plain.gain, s.mu)       # the Kronecker matrix, independently
    assert sol.stability.radius == pytest.approx(expected, rel=1e-9)
    assert sol.stability.stable == (expected < 1)
    page = cells(sol._repr_html_())
    shown = page[page.index("mean-square stability") + 1]
    assert f"{expected:.6g}" in shown and ("NOT mean-square stable" in shown) == (expected >= 1)
    d = sol.to_dict()
    assert d["mean_square_spectral_radius"] == pytest.approx(expected, rel=1e-9) and d["stable"] == (expected < 1)
    assert np.array_equal(sol.inputs, plain.inputs) and sol.cost == plain.cost   # the plan is untouched
    assert "mean_square_spectral_radius" not in plain.to_dict()                   # nothing added unasked


def test_solution_view_says_not_stable_for_a_law_that_diverges():
    # x' = 2x - v K x, P(v = 1) = 0.5: E[x'^2] = (0.5 (2 - K)^2 + 0.5 * 4) x^2 >= 2 x^2 for every K
    s = pl.System(A=[[2.0]], B=[[1.0]], horizon=3, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    sol = with_stability(s, pl.closed_form(s, "tcp"))
    K = sol.gain[0, 0]
    assert sol.stability.radius == pytest.approx(0.5 * (2 - K) ** 2 + 2.0, rel=1e-12)
    assert not sol.stability.stable
    page = cells(sol._repr_html_())
    assert "NOT mean-square stable" in page[page.index("mean-square stability") + 1]


def test_solution_stability_behind_a_chain_is_the_markov_jump_radius():
    # a chain whose two states deliver alike is i.i.d. Bernoulli: the MJLS radius equals the Kronecker one
    from packetloss_cvx.model.channel import GilbertElliott
    s = pl.load_example("two_actuator")
    chain = GilbertElliott(p=[0.2, 0.3], r=[0.4, 0.1], h_good=[0.7, 0.6], h_bad=[0.7, 0.6])
    bursty = s.with_channel(chain)
    plain = pl.closed_form(bursty.with_mu(bursty.mu_schedule), "udp")
    st = with_stability(bursty, plain).stability
    assert "Markov chain" in st.over
    assert st.radius == pytest.approx(second_moment_radius(s.A, s.B, plain.gain, np.array([0.7, 0.6])), rel=1e-8)


def test_solution_stability_needs_a_gain():
    s = pl.load_example("pendulum")
    sol = pl.closed_form(s, "tcp")
    with pytest.raises(InputError, match="no gain"):
        with_stability(s, dataclasses.replace(sol, gain=None))


def test_every_result_type_has_a_notebook_view():
    s = pl.load_example("pendulum")
    made = {"ClosedLoop": closed_loop(s, pl.closed_form(s, "tcp").gain), "Riccati": dp_riccati(s)}
    for name in results.__all__:
        cls = getattr(results, name)
        if isinstance(cls, type):
            assert callable(getattr(cls, "_repr_html_", None)), name
    for name, obj in made.items():
        page = obj._repr_html_()
        assert page.startswith("<table>") and name in page
    page = cells(dp_riccati(s)._repr_html_())
    assert page[page.index("spectral_radius") + 1] == f"{dp_riccati(s).spectral_radius:.6g}"
