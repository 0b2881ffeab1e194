"""The (mean rate × burstiness) map of one channel (markov.burstiness_map, markov.channel_twin,
results.BurstinessMap, plots.plot_burstiness_map, ``sweep --burstiness --mean-rate``): against the Bernoulli
closed form at lambda = 0, the dense second-moment route on chains built here by hand, and the minimum of the
enumerated expected cost (every loss pattern) on a short horizon."""

import itertools
import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.errors import BudgetError, InputError
from packetloss_cvx.lq.markov_cost import exact_closed_form, exact_cost
from packetloss_cvx.model.chain import attach_channel
from packetloss_cvx.model.channel import GilbertElliott, MarkovChannel
from packetloss_cvx.model.system import System
from packetloss_cvx.model.twins import channel_twin
from packetloss_cvx.studies.burstiness import burstiness_map
from tests.references import enumerated_chain_cost


def gilbert(rate, lam):
    """The stationary Gilbert chain (T, d, pi0) of mean rate ``rate`` and lambda ``lam``, written out here."""
    p, r = (1 - rate) * (1 - lam), rate * (1 - lam)
    return np.array([[1 - p, p], [r, 1 - r]]), np.array([1.0, 0.0]), np.array([r, p]) / (p + r)


def small_system():
    return System(A=[[1.2, 0.3], [0.0, 0.8]], B=[[1.0, 0.0], [0.4, 1.0]], horizon=3, state_weight=[2.0, 1.0],
                  input_weight=[0.5, 1.0], mu=[0.7, 0.6], x0=[1.0, -0.5], name="small")


def enumerated_minimum(s, chains):
    """min over U of the enumerated expected cost: it is a quadratic c + g'U + U'HU in the N m inputs, recovered
    from its values at 0, e_i and e_i + e_j (exact for a quadratic), then minimised by a linear solve."""
    N, m = s.horizon, s.m
    size = N * m

    def f(u):
        return enumerated_chain_cost(s.A, s.B, s.state_weights, s.input_weights, s.initial_weight, s.x0, chains,
                                     np.asarray(u, float).reshape(N, m))

    c = f(np.zeros(size))
    unit = np.eye(size)
    single = np.array([f(unit[i]) for i in range(size)])
    minus = np.array([f(-unit[i]) for i in range(size)])
    H = np.diag((single + minus) / 2 - c)
    g = (single - minus) / 2
    for i, j in itertools.combinations(range(size), 2):
        H[i, j] = H[j, i] = (f(unit[i] + unit[j]) - single[i] - single[j] + c) / 2
    active = np.diag(H) > 0
    u = np.zeros(size)
    u[active] = np.linalg.solve(2 * H[np.ix_(active, active)], -g[active])
    return c + g @ u + u @ H @ u


def test_memoryless_column_is_the_bernoulli_optimum_at_the_mean_rate():
    s = pl.load_example("two_actuator")                 # mu = (0.9, 0.5): channel 2 mapped, channel 1 kept at 0.9
    rates = [0.0, 0.3, 0.75, 1.0]
    grid = burstiness_map(s, rates, [0.0, 0.6], channel=1, progress=False)
    assert grid.exact["udp"].shape == (4, 2)
    for a, rate in enumerate(rates):
        bernoulli = s.with_mu([0.9, rate])
        for protocol in ("tcp", "udp"):
            reference = pl.closed_form(bernoulli, protocol, method="recursion").cost    # the paper's J* (Theorem 1)
            assert grid.exact[protocol][a, 0] == pytest.approx(reference, rel=1e-10)
            assert grid.plugin[protocol][a, 0] == pytest.approx(reference, rel=1e-10)
    loss = grid.relative_loss("udp")
    assert np.all(np.abs(loss[:, 0]) < 1e-10)
    # a channel that always or never delivers has no burst: lambda changes nothing there
    np.testing.assert_allclose(grid.exact["udp"][[0, 3], 1], grid.exact["udp"][[0, 3], 0], rtol=1e-10)
    assert np.all(loss[1:3, 1] > 1e-3)                                # bursts in between: the plug-in law loses
    np.testing.assert_allclose(grid.relative_loss("tcp"), 0.0, atol=1e-10)   # first moments only: exact


def test_map_points_match_the_dense_route_on_hand_built_chains():
    s = pl.load_example("pendulum_bursty")               # N = 80, one channel
    rates, lams = [0.6, 0.9], [0.3, 0.8, 0.95]
    grid = burstiness_map(s, rates, lams, progress=False)
    for (a, rate), (b, lam) in itertools.product(enumerate(rates), enumerate(lams)):
        p, r = (1 - rate) * (1 - lam), rate * (1 - lam)
        twin = attach_channel(s, GilbertElliott(p=[p], r=[r]))
        dense = exact_closed_form(twin, "udp", method="dense").cost          # the stacked second-moment solve
        assert grid.exact["udp"][a, b] == pytest.approx(dense, rel=1e-10)
        plugin = pl.closed_form(twin.with_mu(np.full((80, 1), rate)), "udp").inputs
        assert grid.plugin["udp"][a, b] == pytest.approx(exact_cost(twin, plugin, method="dense"), rel=1e-10)
    # the file's own chain (p = 0.02, r = 0.18: rate 0.9, lambda 0.8): the documented 7.90 % loss
    assert grid.relative_loss("udp")[1, 1] == pytest.approx(0.0790, abs=5e-4)


def test_map_matches_the_enumerated_minimum_on_a_short_horizon():
    s = small_system()
    rates, lams = [0.35, 0.8], [0.5, -0.2]
    grid = burstiness_map(s, rates, lams, channel=0, progress=False)
    for (a, rate), (b, lam) in itertools.product(enumerate(rates), enumerate(lams)):
        chains = [gilbert(rate, lam), (np.ones((1, 1)), np.array([0.6]), np.ones(1))]   # channel 2: i.i.d. at 0.6
        assert grid.exact["udp"][a, b] == pytest.approx(enumerated_minimum(s, chains), rel=1e-10)
        plugin = pl.closed_form(s.with_mu([rate, 0.6]), "udp").inputs
        reference = enumerated_chain_cost(s.A, s.B, s.state_weights, s.input_weights, s.initial_weight, s.x0,
                                          chains, plugin)
        assert grid.plugin["udp"][a, b] == pytest.approx(reference, rel=1e-10)


def test_other_channels_keep_their_own_chain():
    s = small_system()
    three = MarkovChannel(transition=[[[0.5, 0.5], [0.2, 0.8]], [[0.6, 0.3, 0.1], [0.1, 0.6, 0.3], [0.2, 0.2, 0.6]]],
                          delivery=[[1.0, 0.0], [1.0, 0.5, 0.0]], belief=[[0.5, 0.5], [0.0, 0.0, 1.0]])
    chained = attach_channel(s, three)
    grid = burstiness_map(chained, [0.5], [0.7], channel=0, progress=False)
    T1, d1, pi1 = (np.asarray(a) for a in chained.channel.chain_matrices()[1])
    T0, d0, pi0 = gilbert(0.5, 0.7)
    by_hand = MarkovChannel(transition=[T0, T1], delivery=[d0, d1], belief=[pi0, pi1])
    dense = exact_closed_form(attach_channel(s, by_hand), "udp", method="dense").cost
    assert grid.exact["udp"][0, 0] == pytest.approx(dense, rel=1e-10)
    twin = channel_twin(chained, 0, 0.5, 0.7)
    assert twin.channel.sizes == (2, 3)
    np.testing.assert_array_equal(twin.mu_schedule[:, 1], chained.mu_schedule[:, 1])


def test_result_is_frozen_and_serialises():
    grid = burstiness_map(small_system(), [0.4, 0.9], [0.0, 0.5, 0.9], channel=1, progress=False)
    with pytest.raises(ValueError, match="read-only"):
        grid.exact["udp"][0, 0] = 0.0
    data = json.loads(grid.to_json())
    assert (data["channel"], data["rate"], len(data["udp"]["exact"][0])) == (1, [0.4, 0.9], 3)
    xr = pytest.importorskip("xarray")
    ds = grid.to_xarray()
    assert isinstance(ds, xr.Dataset)
    assert ds["exact_udp"].dims == ("rate", "correlation")
    np.testing.assert_array_equal(ds["loss_udp"].values, grid.relative_loss("udp"))


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"rates": [1.2]}, "rates"), ({"rates": [np.nan]}, "rates"), ({"rates": []}, "rates"),
    ({"correlations": [1.0]}, "correlations"), ({"correlations": [-0.9], "rates": [0.9]}, "correlations"),
    ({"channel": 2}, "channel"), ({"channel": -1}, "channel"), ({"channel": True}, "channel"),
])
def test_bad_grids_are_refused_naming_the_field(kwargs, field):
    with pytest.raises(InputError) as info:
        burstiness_map(small_system(), **{"progress": False, **kwargs})
    assert info.value.field == field


def test_grid_beyond_the_work_budget_is_refused_before_any_point(monkeypatch):
    monkeypatch.setenv("PACKETLOSS_CVX_BUDGET_SWEEP_WORK", "1e6")
    calls = []
    monkeypatch.setattr("packetloss_cvx.studies.burstiness._evaluate", lambda *a: calls.append(a))
    with pytest.raises(BudgetError, match="rates"):
        burstiness_map(pl.load_example("pendulum_bursty"), np.linspace(0.5, 1, 10), [0.0, 0.5], progress=False)
    assert calls == []


def test_plot_draws_the_cost_on_a_log_scale_and_the_loss_linearly_in_sorted_order():
    from packetloss_cvx.plots import plot_burstiness_map

    cost = np.array([[10.0, 100.0], [1.0, 20.0]])          # rates given as (0.9, 0.5): drawn as (0.5, 0.9)
    fig = plot_burstiness_map([0.9, 0.5], [0.0, 0.8], cost, [[0.0, 3.0], [0.0, 7.0]])
    left, right = fig.axes[0], fig.axes[1]
    drawn = left.collections[0].get_array().reshape(2, 2)
    np.testing.assert_array_equal(drawn, [[1.0, 20.0], [10.0, 100.0]])
    assert type(left.collections[0].norm).__name__ == "LogNorm"
    assert (right.collections[0].norm.vmin, right.collections[0].norm.vmax) == (0.0, 7.0)
    with pytest.raises(InputError, match="rates"):
        plot_burstiness_map([0.5, 0.5], [0.0, 0.8], cost, cost)


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_command_line_carries_the_points_and_writes_the_map(capsys, tmp_path):
    code, out, err = _run(capsys, "sweep", "two_actuator", "--burstiness", "0,0.9", "--mean-rate", "0.2,0.6,1",
                          "--channel", "2", "--json", "-q", "--out", str(tmp_path / "map"))
    assert code == 0, err
    data = json.loads(out)
    assert (data["kind"], data["channel"], data["shape"]) == ("burstiness-map", 2, [3, 2])
    s = pl.load_example("two_actuator")
    for a, rate in enumerate([0.2, 0.6, 1.0]):
        reference = pl.closed_form(s.with_mu([0.9, rate]), "udp", method="recursion").cost
        assert data["udp"]["exact"][a][0] == pytest.approx(reference, rel=1e-10)
    rows = np.loadtxt(tmp_path / "map" / "burstiness_map.csv", delimiter=",", skiprows=1)
    assert rows.shape == (6, 6)
    np.testing.assert_array_equal(rows[:, :2], [[0.2, 0], [0.2, 0.9], [0.6, 0], [0.6, 0.9], [1, 0], [1, 0.9]])
    np.testing.assert_allclose(rows[:, 5], np.ravel(data["udp"]["exact"]), rtol=1e-15)
    assert {p.name for p in (tmp_path / "map").iterdir()} >= {"burstiness_map.csv", "burstiness_map_tcp.png",
                                                               "burstiness_map_udp.png"}


@pytest.mark.parametrize(("argv", "field"), [
    (["--burstiness", "0,0.5", "--mean-rate", "1.5"], "--mean-rate"),
    (["--burstiness", "0,0.5", "--mean-rate", "abc"], "--mean-rate"),
    (["--burstiness", "0,1", "--mean-rate", "0.5"], "--burstiness"),
    (["--burstiness", "-0.9", "--mean-rate", "0.95"], "--burstiness"),
    (["--burstiness", "0,0.5", "--mean-rate", "0.5", "--channel", "3"], "--channel"),
    (["--burstiness", "0,0.5", "--mean-rate", "0.5", "--shared"], "--mean-rate"),
    (["--mu-grid", "3", "--mean-rate", "0.5"], "--mean-rate"),
    (["--burstiness", "0:0.9:1000", "--mean-rate", "0:1:2000"], "--mean-rate"),
])
def test_command_line_bad_input_exits_2_with_one_line(capsys, argv, field):
    code, out, err = _run(capsys, "sweep", "two_actuator", *argv, "-q")
    assert code == 2
    assert err.count("\n") == 1
    assert "Traceback" not in err
    assert f"error: {field}:" in err


@pytest.mark.parametrize(("factor", "exact_words"), [(3.0, False), (0.3, True)])
def test_a_map_loss_within_self_check_rtol_reads_as_the_exact_minimiser(capsys, monkeypatch, factor, exact_words):
    """As the sweep's summary (tests/studies/test_sweep_burstiness.py): the map calls the plug-in law the exact minimiser only
    where its largest loss is within SELF_CHECK_RTOL; a planted loss of 3 times the band is printed as a loss."""
    import packetloss_cvx.cli.sweep as sweep_command
    from packetloss_cvx.results import BurstinessMap
    from packetloss_cvx.tolerances import SELF_CHECK_RTOL

    exact = np.array([[2.0, 3.0]])
    planted = BurstinessMap(channel=0, rate=np.array([0.9]), correlation=np.array([0.0, 0.5]),
                            plugin={p: exact * (1 + factor * SELF_CHECK_RTOL) for p in ("tcp", "udp")},
                            exact={p: exact for p in ("tcp", "udp")})
    monkeypatch.setattr(sweep_command, "burstiness_map", lambda *a, **k: planted)
    code, out, err = _run(capsys, "sweep", "pendulum_bursty", "--burstiness", "0,0.5", "--mean-rate", "0.9", "-q")
    assert code == 0, err
    assert ("the plug-in law is the exact minimiser at every point" in out) is exact_words
    assert ("the plug-in law loses up to" in out) is not exact_words
