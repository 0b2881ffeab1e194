"""plots.py draws the data it is given, returns a Figure, saves only when asked, leaves the
matplotlib backend alone and reports bad data with the project's typed errors."""

import importlib

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

import packetloss_cvx as pl
import packetloss_cvx.plots.figures as plots
from packetloss_cvx.plots import plot_allocation_contours, plot_pareto

CURVES = {
    "tcp": [{"alpha": 4.0, "communication_cost": 1.5}, {"alpha": 8.0, "communication_cost": 0.7}],
    "udp": [{"alpha": 4.0, "communication_cost": None}, {"alpha": 8.0, "communication_cost": 1.1}],
}
AXIS = [0.0, 0.5, 1.0]
COSTS = [[9.0, 6.0, 5.0], [6.0, 4.0, 3.0], [5.0, 3.0, 2.0]]
ALLOCATIONS = {(1.0, 1.0): [{"mu": [0.2, 0.9]}, {"mu": None}], (0.05, 1.0): [{"mu": [1.0, 0.1]}]}


def test_pareto_draws_the_given_points():
    fig = plot_pareto(CURVES, title="two-actuator")
    assert isinstance(fig, Figure)
    (ax,) = fig.axes
    tcp, udp = ax.lines
    assert tcp.get_label() == "TCP-like"
    assert udp.get_label() == "UDP-like"
    assert np.array_equal(tcp.get_xydata(), [[4.0, 1.5], [8.0, 0.7]])
    assert np.array_equal(udp.get_xydata(), [[8.0, 1.1]])           # the infeasible row is left out
    assert ax.get_title() == "two-actuator"


def test_pareto_saved_only_when_a_path_is_given(tmp_path):
    before = set(tmp_path.iterdir())
    plot_pareto(CURVES)
    assert set(tmp_path.iterdir()) == before
    path = tmp_path / "pareto.png"
    plot_pareto(CURVES, path=path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_contours_draw_the_given_allocations(tmp_path):
    path = tmp_path / "contours.svg"
    fig = plot_allocation_contours(AXIS, COSTS, ALLOCATIONS, levels=[4.0, 6.0], path=path)
    ax, bar = fig.axes                                   # the map and its colour bar
    drawn = {line.get_label(): line.get_xydata().tolist() for line in ax.lines}
    assert drawn == {"beta=(1.0, 1.0)": [[0.2, 0.9]], "beta=(0.05, 1.0)": [[1.0, 0.1]]}
    assert path.read_text().lstrip().startswith("<?xml")


def test_figures_leave_the_backend_and_pyplot_alone(monkeypatch):
    """Importing plots and drawing neither calls matplotlib.use nor opens a pyplot figure."""
    def refuse(*args, **kwargs):
        raise AssertionError("matplotlib.use was called")

    monkeypatch.setattr(matplotlib, "use", refuse)
    backend, figures = matplotlib.get_backend(), plt.get_fignums()
    importlib.reload(plots)
    plots.plot_pareto(CURVES)
    plots.plot_allocation_contours(AXIS, COSTS, ALLOCATIONS, levels=[4.0])
    assert matplotlib.get_backend() == backend
    assert plt.get_fignums() == figures


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: plot_pareto({}), "curves"),
        (lambda: plot_pareto({"tcp": [{"alpha": 1.0}]}), r"curves\['tcp'\]\[0\]"),
        (lambda: plot_pareto({"tcp": [{"alpha": "x", "communication_cost": 1.0}]}), r"curves\['tcp'\]"),
        (lambda: plot_pareto({"tcp": [{"alpha": np.nan, "communication_cost": 1.0}]}), r"curves\['tcp'\]"),
        (lambda: plot_allocation_contours([0.0, 1.0], COSTS, {}, [1.0]), "costs"),
        (lambda: plot_allocation_contours([1.0, 0.5, 0.0], COSTS, {}, [1.0]), "axis"),
        (lambda: plot_allocation_contours(AXIS, np.zeros((3, 3)), {}, [1.0]), "costs"),
        (lambda: plot_allocation_contours(AXIS, COSTS, {"b": [{"mu": [0.1, 0.2, 0.3]}]}, [1.0]), "allocations"),
        (lambda: plot_allocation_contours(AXIS, COSTS, {}, []), "levels"),
        (lambda: plot_pareto(CURVES, path="/nonexistent-dir/x.png"), "path"),
        (lambda: plot_pareto(CURVES, path="figure.unknownformat"), "path"),
    ],
)
def test_bad_data_is_a_typed_error(call, field):
    with pytest.raises(pl.InputError, match=f"^{field}"):
        call()
