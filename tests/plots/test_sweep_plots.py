"""The sweep and reproduce figures draw given data: labelled axes, a colourbar on contours, the marker,
the allocation lines, and errors that name the field."""

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.plots import plot_cost_lines, plot_log_contour


def test_cost_lines_draw_the_values_on_a_log_axis_and_the_marker(tmp_path):
    x = [0.1, 0.5, 1.0]
    fig = plot_cost_lines(x, {"tcp": [np.e, np.e**2, 0.0], "diff": [1.0, 1.0, 1.0]}, xlabel="nu", marker=0.5,
                          marker_label="max", path=tmp_path / "f.png")
    ax = fig.axes[0]
    tcp = ax.lines[0].get_ydata()
    assert tcp[:2].tolist() == [np.e, np.e**2]
    assert ax.get_yscale() == "log"
    assert np.isnan(tcp[2])                       # 0 is not on a log axis: left out (the legend says so)
    assert ax.lines[1].get_linestyle() == "--"
    assert ax.lines[2].get_xdata()[0] == 0.5
    assert ax.get_xlabel() == "nu"
    assert (tmp_path / "f.png").stat().st_size > 0


def test_log_contour_has_a_colourbar_marker_and_allocation_lines():
    axis = np.linspace(0, 1, 4)
    values = np.exp(np.add.outer(axis, 2 * axis))          # values[j, i] = exp(axis[j] + 2 axis[i])
    fig = plot_log_contour(axis, axis, values, marker=[0.2, 0.3], levels=[3.0, 1e9],
                           allocations={"beta = (1, 1)": [[0.1, 0.9], None, [0.5, 0.5]]}, colorbar_label="log J")
    ax, bar = fig.axes
    assert bar.get_ylabel() == "log J"
    assert ax.get_xlabel() == r"$\mu_1$"
    assert ax.get_ylabel() == r"$\mu_2$"
    line, cross = ax.lines
    assert line.get_xydata().tolist() == [[0.1, 0.9], [0.5, 0.5]]
    assert cross.get_xydata().tolist() == [[0.2, 0.3]]


@pytest.mark.parametrize(("call", "field"), [
    (lambda: plot_log_contour([0, 1], [0, 1], np.ones((2, 3))), "values"),
    (lambda: plot_log_contour([0, 1], [0, 1], -np.ones((2, 2))), "values"),
    (lambda: plot_log_contour([1, 0], [0, 1], np.ones((2, 2))), "axis_x"),
    (lambda: plot_log_contour([0, 1], [0, 1], np.ones((2, 2)), allocations={"b": [[0.1, 0.2, 0.3]]}),
     "allocations['b']"),
    (lambda: plot_cost_lines([0, 1], {"tcp": [1.0]}, xlabel="x"), "curves['tcp']"),
    (lambda: plot_cost_lines([0, 1], {}, xlabel="x"), "curves"),
])
def test_bad_data_names_the_field(call, field):
    with pytest.raises(pl.InputError) as info:
        call()
    assert info.value.field == field
