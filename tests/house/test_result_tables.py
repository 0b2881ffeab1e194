"""Results that tabulate and draw themselves: ``to_pandas()`` on every result type (tidy: one row per point, each
number once), ``.plot()`` where a figure makes sense, the plot functions taking the package's own results, and
the design sweep's Dataset over its dimensions only, with attrs and units.

References: hand values of two decoupled copies of x' = x + v u (N = 1: J*_tcp = sum x0_i^2 / (1 + mu_i),
J*_udp = sum x0_i^2 (1 - mu_i / 2)), pandas' own CSV reader and DataFrame constructor, xarray's to_dataframe."""

import inspect
import sys
from unittest import mock

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx import results
from packetloss_cvx.model.system import System
from packetloss_cvx.montecarlo import simulate
from packetloss_cvx.studies import save_sweep, shared_channel_sweep, sweep, two_channel_sweep
from packetloss_cvx.studies.region_map import region_map

pd = pytest.importorskip("pandas")


@pytest.fixture(scope="module")
def decoupled():
    """Two decoupled copies of x' = x + v u, N = 1, x0 = (1, 2)."""
    return System(A=np.eye(2), B=np.eye(2), horizon=1, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0],
                  mu=[0.5, 0.5], x0=[1.0, 2.0])


def _hand(mu1, mu2):
    return {"tcp": 1 / (1 + mu1) + 4 / (1 + mu2), "udp": (1 - mu1 / 2) + 4 * (1 - mu2 / 2)}


def test_every_result_type_has_to_pandas():
    types = [getattr(results, name) for name in results.__all__ if inspect.isclass(getattr(results, name))]
    assert len(types) >= 25
    assert [t.__name__ for t in types if not callable(getattr(t, "to_pandas", None))] == []


def test_a_two_channel_sweep_is_one_row_per_grid_point_with_the_hand_costs(decoupled):
    frame = two_channel_sweep(decoupled, [0.0, 0.5, 1.0]).to_pandas()
    assert list(frame.columns) == ["mu2", "mu1", "cost_tcp", "cost_udp", "cost_diff"]
    assert len(frame) == 9
    for row in frame.itertuples():
        hand = _hand(row.mu1, row.mu2)
        assert row.cost_tcp == pytest.approx(hand["tcp"], rel=1e-12)
        assert row.cost_udp == pytest.approx(hand["udp"], rel=1e-12)
        assert row.cost_diff == pytest.approx(hand["udp"] - hand["tcp"], abs=1e-12)


def test_a_shared_channel_sweep_is_one_row_per_nu(decoupled):
    frame = shared_channel_sweep(decoupled, [0.0, 0.5]).to_pandas()
    assert frame["nu"].tolist() == [0.0, 0.5]
    assert frame["cost_tcp"].tolist() == pytest.approx([_hand(nu, nu)["tcp"] for nu in (0.0, 0.5)], rel=1e-12)


def test_a_design_sweep_table_is_its_csv_file(tmp_path, decoupled):
    result = sweep(decoupled, mu_grid=[0.0, 0.5, 1.0], progress=False)
    save_sweep(result, tmp_path / "out")
    expected = pd.read_csv(tmp_path / "out" / "sweep.csv")
    frame = result.to_pandas()
    assert list(frame.columns) == list(expected.columns)
    pd.testing.assert_frame_equal(frame, expected, check_dtype=False, rtol=1e-15)
    for row in frame.itertuples():
        assert row.cost_tcp == pytest.approx(_hand(row.mu1, row.mu2)["tcp"], rel=1e-12)
    assert frame.attrs["dims"] == ["mu2", "mu1"]


def test_a_design_sweep_dataset_has_one_row_per_point(decoupled):
    pytest.importorskip("xarray")
    result = sweep(decoupled, mu_grid=[0.0, 0.5, 1.0], progress=False)
    dataset = result.to_xarray()
    assert {name: dataset[name].dims for name in dataset.data_vars} == {
        name: ("mu2", "mu1") for name in ("x0_1", "x0_2", "horizon", "cost_tcp", "cost_udp", "cost_diff")}
    table = dataset.to_dataframe()
    assert len(table) == 9               # it repeated each cost 4 times (m x n)
    assert table.index.is_unique
    expected = result.to_pandas().set_index(["mu2", "mu1"])
    pd.testing.assert_frame_equal(table[expected.columns], expected, check_dtype=False)


def test_every_dataset_variable_carries_a_long_name_and_units(decoupled):
    pytest.importorskip("xarray")
    for dataset in (sweep(decoupled, mu_grid=3, progress=False).to_xarray(),
                    sweep(decoupled, horizons=[1, 2], progress=False).to_xarray(),
                    region_map(pl.load_example("two_actuator"), laws=("dp",), grid=3).to_xarray()):
        for name, variable in {**dataset.data_vars, **dataset.coords}.items():
            if name == "law":
                continue
            assert variable.attrs.get("long_name"), name
            assert "units" in variable.attrs, name
    assert dataset["stable"].attrs["units"] == "1"


def test_a_solution_is_one_row_per_step(decoupled):
    solution = pl.closed_form(pl.load_example("two_actuator"), "udp")
    frame = solution.to_pandas()
    expected = pd.DataFrame(np.asarray(solution.inputs), columns=["u1", "u2"])
    pd.testing.assert_frame_equal(frame[["u1", "u2"]], expected)
    assert frame["t"].tolist() == list(range(len(expected)))
    assert frame.attrs["cost"] == solution.cost
    assert "cost" not in frame.columns


def test_a_one_point_result_is_one_row_with_its_vectors_numbered():
    point = results.MinCost(protocol="tcp", cost=2.0, lower_bound=1.5, gap=0.25, status="optimal",
                            mu=np.array([0.25, 0.75]), method="hand")
    frame = point.to_pandas()
    assert frame.to_dict("records") == [{"protocol": "tcp", "cost": 2.0, "lower_bound": 1.5, "gap": 0.25,
                                         "status": "optimal", "mu1": 0.25, "mu2": 0.75, "method": "hand",
                                         "basis": "paper"}]


def test_to_pandas_without_pandas_says_how_to_install_it(decoupled):
    result = shared_channel_sweep(decoupled, [0.5])
    with mock.patch.dict(sys.modules, {"pandas": None}), \
            pytest.raises(pl.InputError, match=r"packetloss-cvx\[xarray\]"):
        result.to_pandas()


@pytest.fixture(scope="module")
def simulation():
    return simulate(pl.load_example("two_actuator"), 64, steps=6, seed=3, closed_loop=True)


def test_a_simulation_is_one_row_per_law_and_step(simulation):
    frame = simulation.to_pandas()
    assert len(frame) == sum(run.state_norm_mean.size for run in simulation.closed_loop.values())
    for law, run in simulation.closed_loop.items():
        rows = frame[frame["law"] == law]
        assert rows["state_norm_mean"].tolist() == run.state_norm_mean.tolist()
        assert rows["stage_cost_mean"].tolist()[:-1] == run.stage_cost_mean.tolist()
        assert np.isnan(rows["stage_cost_mean"].iloc[-1])                     # no stage cost at t = T


def test_plot_closed_loop_takes_a_simulation_and_its_runs(simulation):
    from packetloss_cvx.plots import plot_closed_loop

    for figure in (plot_closed_loop(simulation.closed_loop), plot_closed_loop(simulation), simulation.plot()):
        left = figure.axes[0]
        assert [line.get_ydata().tolist() for line in left.lines] == [
            run.state_norm_mean.tolist() for run in simulation.closed_loop.values()]
    one = simulation.closed_loop["tcp"].plot()
    assert one.axes[0].lines[0].get_ydata().tolist() == simulation.closed_loop["tcp"].state_norm_mean.tolist()


@pytest.fixture(scope="module")
def region():
    return region_map(pl.load_example("two_actuator"), laws=("dp", "tcp"), grid=4)


def test_plot_region_takes_a_region_map_alone(region):
    from packetloss_cvx.plots import plot_region

    manual = plot_region(region.axis, region.radius[region.laws.index("dp")],
                         dict(zip(region.laws, region.stable, strict=True)))
    for figure in (plot_region(region), region.plot()):
        mine, theirs = figure.axes[0].collections[0], manual.axes[0].collections[0]
        np.testing.assert_array_equal(mine.get_array(), theirs.get_array())
        assert (figure.axes[0].get_xlabel(), figure.axes[0].get_ylabel()) == (r"$\mu_1$", r"$\mu_2$")
    without = region_map(pl.load_example("two_actuator"), laws=("tcp",), grid=3)
    with pytest.raises(pl.InputError, match="dp") as info:
        plot_region(without)
    assert info.value.field == "region"


def test_a_region_map_table_is_its_dataset(region):
    pytest.importorskip("xarray")
    frame = region.to_pandas()
    assert len(frame) == len(region.laws) * region.axis.size ** 2
    expected = region.to_xarray().to_dataframe()[["stable", "radius"]]
    pd.testing.assert_frame_equal(frame.set_index(["law", "mu2", "mu1"]), expected, check_dtype=False)
    assert frame.attrs["critical"]["dp"]["t"] == region.critical[0].t


def test_a_sweep_draws_its_costs(decoupled):
    one = shared_channel_sweep(decoupled, [0.25, 0.5, 0.75])
    figure = one.plot()
    assert [line.get_ydata().tolist() for line in figure.axes[0].lines][:2] == [
        one.costs["tcp"].tolist(), one.costs["udp"].tolist()]
    two = sweep(decoupled, mu_grid=[0.25, 0.5, 0.75], progress=False)
    figure = two.plot("cost_tcp")
    assert figure.axes[0].get_xlabel() == r"$\mu_1$"
    with pytest.raises(pl.InputError, match="cost_tcp") as info:
        two.plot("cost")
    assert info.value.field == "quantity"


def test_a_burstiness_map_tabulates_and_draws_itself():
    from packetloss_cvx.plots import plot_burstiness_map
    from packetloss_cvx.studies.burstiness import burstiness_map

    grid = burstiness_map(pl.load_example("two_actuator"), [0.5, 0.8], [0.0, 0.6], channel=1, progress=False)
    frame = grid.to_pandas()
    assert len(frame) == 4
    row = frame[(frame["rate"] == 0.8) & (frame["correlation"] == 0.6)].iloc[0]
    assert row["exact_udp"] == grid.exact["udp"][1, 1]
    assert row["loss_tcp"] == grid.relative_loss("tcp")[1, 1]
    assert frame.attrs["channel"] == 2                                      # 1-based, as the xarray attrs
    pytest.importorskip("xarray")
    dataset = grid.to_xarray()
    for name, variable in {**dataset.data_vars, **dataset.coords}.items():
        assert variable.attrs.get("long_name"), name
        assert "units" in variable.attrs, name
    expected = dataset.to_dataframe()
    pd.testing.assert_frame_equal(frame.set_index(["rate", "correlation"])[expected.columns], expected)
    manual = plot_burstiness_map(grid.rate, grid.correlation, grid.exact["tcp"], 100 * grid.relative_loss("tcp"))
    for figure in (plot_burstiness_map(grid, protocol="tcp"), grid.plot("tcp")):
        for mine, theirs in zip(figure.axes[:2], manual.axes[:2], strict=True):
            np.testing.assert_array_equal(mine.collections[0].get_array(), theirs.collections[0].get_array())


def test_plot_pareto_takes_allocations():
    from packetloss_cvx.plots import plot_pareto

    rows = [results.Allocation(mu=np.array([0.5, 0.5]), communication_cost=1.0 + k, cost=2.0, lower_bound=1.0,
                               gap=0.0, status="optimal", method="hand", protocol="tcp", alpha=3.0 - k,
                               beta=np.ones(2)) for k in range(2)]
    line, = plot_pareto({"tcp": rows}).axes[0].lines
    assert (line.get_xdata().tolist(), line.get_ydata().tolist()) == ([3.0, 2.0], [1.0, 2.0])


def test_plot_ack_break_even_takes_protocol_choices():
    from packetloss_cvx.plots import plot_ack_break_even

    def choice(alpha, price):
        return results.ProtocolChoice(alpha=alpha, currency="beta'mu", ack_price=0.0, tcp=None, udp=None,
                                      tcp_total=1.0, udp_total=2.0, choice="tcp", certified=True, break_even=price)

    choices = [choice(2.0, 0.5), choice(4.0, 0.25), choice(6.0, float("inf"))]      # inf: no UDP-like design
    line = plot_ack_break_even(choices).axes[0].lines[0]
    assert (line.get_xdata().tolist(), line.get_ydata().tolist()) == ([2.0, 4.0], [0.5, 0.25])
