"""Figures a reviewer accepts, checked on what was drawn (artists' data and extents, never pixels): a log
colour scale ticked in the values, J_Delta = 0 filled, contour labels that do not collide, allocation paths
that stand out on the colour map, markers drawn whole off the frame, legends beside the plot."""

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LogNorm, to_rgb
from matplotlib.patheffects import withStroke

from packetloss_cvx.plots import plot_closed_loop, plot_cost_lines, plot_log_contour, plot_pareto
from packetloss_cvx.plots.style import log_ticks, tick_text

AXIS = np.linspace(0.0, 1.0, 61)
MU1, MU2 = np.meshgrid(AXIS, AXIS)                       # [j, i] = (AXIS[i], AXIS[j]): rows follow mu2
#: a cost like the two-actuator system's: large at (0, 0), about 2 at (1, 1), its contours crowded near (1, 1)
COST = 2.0 + 140.0 * (1 - MU1) ** 2 * (1 - MU2) ** 2 + 8.0 * (1 - MU1 * MU2)
#: a J_Delta-like difference: exactly 0 where mu1 or mu2 is 0 or 1
DIFF = 300.0 * MU1 * (1 - MU1) * MU2 * (1 - MU2)
ALPHAS = (2.5, 3.5, 4.78, 6.0, 8.0, 12.0, 20.0, 35.0, 50.0, 70.0, 100.0)
PATHS = {"beta = (1, 1)": [(0.05, 0.05), (0.2, 0.2), (0.5, 0.5), (0.8, 0.8)],
         "beta = (0.05, 1)": [(0.1, 0.0), (0.6, 0.0), (1.0, 0.0), (1.0, 0.5), (1.0, 0.9)],
         "beta = (1, 0.05)": [(0.0, 0.1), (0.0, 0.6), (0.0, 1.0), (0.5, 1.0)]}


def rendered(fig):
    FigureCanvasAgg(fig).draw()
    return fig.canvas.get_renderer()


def filled_area(contour_set):
    """The area the filled contours cover, by the shoelace formula over their polygons (holes count negative)."""
    total = 0.0
    for path in contour_set.get_paths():
        for poly in path.to_polygons():
            x, y = poly[:, 0], poly[:, 1]
            total += 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    return total


def test_colour_scale_is_logarithmic_and_ticked_in_the_values():
    fig = plot_log_contour(AXIS, AXIS, COST, colorbar_label="J* (log scale)")
    ax, bar = fig.axes
    norm = ax.collections[0].norm
    assert isinstance(norm, LogNorm)
    assert (norm.vmin, norm.vmax) == (COST.min(), COST.max())    # all of a cost map: no clamped colours
    ticks = bar.get_yticks()
    labels = [t.get_text() for t in bar.get_yticklabels()]
    inside = ticks[(ticks >= COST.min()) & (ticks <= COST.max())]
    assert COST.min() == 2.0 and COST.max() == 150.0
    assert inside.tolist() == [2.0, 5.0, 10.0, 20.0, 50.0, 100.0]    # 1-2-5 in each decade
    assert [lab for t, lab in zip(ticks, labels, strict=True) if t in inside] == ["2", "5", "10", "20", "50", "100"]
    assert bar.get_ylabel() == "J* (log scale)"


@pytest.mark.parametrize(("lo", "hi", "expected"), [
    (2.5, 84.0, [5, 10, 20, 50]), (1.0, 9.0, [1, 2, 5]), (2.0, 3.5, [2, 3]), (0.02, 0.05, [0.02, 0.03, 0.04, 0.05]),
    (1e-2, 1e9, [1e-2, 1, 1e2, 1e4, 1e6, 1e8]),
])
def test_log_ticks_are_round_numbers_in_range(lo, hi, expected):
    ticks = log_ticks(lo, hi)
    assert np.allclose(ticks, expected, rtol=1e-12)
    assert 2 <= ticks.size <= 9
    mantissas = ticks / 10.0 ** np.floor(np.log10(ticks) + 1e-12)
    assert np.allclose(mantissas, np.round(mantissas))           # m x 10^k, m an integer


def test_tick_text_reads_at_a_glance():
    assert [tick_text(v) for v in (5.0, 20.0, 0.05, 4.78, 1e6, 2e-5)] == ["5", "20", "0.05", "4.78", "$10^{6}$",
                                                                          "$2\\times10^{-5}$"]


def test_zero_difference_is_filled_in_the_lowest_colour():
    """J_Delta = 0 on the edges was NaN before its log: blank notches. Now every cell is filled."""
    fig = plot_log_contour(AXIS, AXIS, DIFF, colorbar_label="J_Delta (log scale)")
    ax = fig.axes[0]
    filled = ax.collections[0]
    assert filled_area(filled) == pytest.approx(1.0, rel=1e-9)   # the whole unit square
    assert filled.extend == "min"                                 # values below the scale: the bar's arrow
    legend = fig.legends[0]
    assert any("0 included" in t.get_text() for t in legend.get_texts())


def mult_figure():
    return plot_log_contour(AXIS, AXIS, COST, levels=ALPHAS, allocations=PATHS, marker=(0.0, 1.0))


def test_contour_labels_do_not_collide_or_cover_the_paths():
    fig = mult_figure()
    renderer = rendered(fig)
    ax = fig.axes[0]
    labels = [t for t in ax.texts if t.get_text()]
    assert len(labels) >= 5                                       # most levels carry a label ...
    assert len({t.get_text() for t in labels}) == len(labels)    # ... each at most once
    assert {t.get_text() for t in labels} <= {tick_text(a) for a in ALPHAS}
    boxes = [t.get_window_extent(renderer) for t in labels]
    frame = ax.get_window_extent(renderer)
    for k, a in enumerate(boxes):
        assert frame.x0 <= a.x0 and a.x1 <= frame.x1 and frame.y0 <= a.y0 and a.y1 <= frame.y1
        for b in boxes[k + 1:]:
            assert not a.overlaps(b), (labels[k].get_text(), a, b)
    # no label sits on an allocation path: points sampled along every segment stay outside every label
    for points in PATHS.values():
        pts = np.asarray(points)
        along = np.vstack([a + t * (b - a) for a, b in zip(pts[:-1], pts[1:], strict=True)
                           for t in np.linspace(0, 1, 50)])
        shown = ax.transData.transform(along)
        for box in boxes:
            inside = (shown[:, 0] > box.x0) & (shown[:, 0] < box.x1) & (shown[:, 1] > box.y0) & (shown[:, 1] < box.y1)
            assert not np.any(inside), "a contour label covers an allocation path"
    # every level is named in the legend, labelled on the plot or not
    legend = " ".join(t.get_text() for t in fig.legends[0].get_texts())
    assert all(tick_text(a) in legend for a in ALPHAS if COST.min() < a < COST.max())


def test_allocation_paths_stand_out_on_the_colour_map():
    fig = mult_figure()
    ax = fig.axes[0]
    cmap = ax.collections[0].cmap
    shades = np.array([cmap(t)[:3] for t in np.linspace(0, 1, 256)])
    paths = [line for line in ax.lines if line.get_label() in PATHS]
    assert [line.get_xydata().tolist() for line in paths] == [np.asarray(p).tolist() for p in PATHS.values()]
    colours = [np.array(to_rgb(line.get_color())) for line in paths]
    for line, colour in zip(paths, colours, strict=True):
        assert np.min(np.linalg.norm(shades - colour, axis=1)) > 0.3     # no colour of the map is near it
        assert any(isinstance(e, withStroke) for e in line.get_path_effects())   # outlined in black
        assert line.get_linewidth() >= 1.5
        assert not line.get_clip_on()                             # points on mu = 0 or 1 are drawn whole
    assert len({tuple(c) for c in colours}) == len(colours)
    assert len({str(line.get_linestyle()) + str(line.get_marker()) for line in paths}) == len(paths)


def test_markers_on_the_edge_are_drawn_whole_inside_the_frame():
    """A point on mu = 0 or 1 (fig:cost-diff-mixed's maximiser sits on mu2 = 0) is drawn whole and off the frame:
    the axes reach a margin beyond the grid (a marker across the frame half hides it)."""
    fig = plot_log_contour(AXIS, AXIS, DIFF, marker=(0.04, 0.0))
    renderer = rendered(fig)
    ax = fig.axes[0]
    (cross,) = [line for line in ax.lines if line.get_label() == "maximiser"]
    assert cross.get_xydata().tolist() == [[0.04, 0.0]]
    box, frame = cross.get_window_extent(renderer), ax.get_window_extent(renderer)
    assert frame.y0 < box.y0 < box.y1 < frame.y1
    assert frame.x0 < box.x0 < box.x1 < frame.x1


@pytest.mark.parametrize("make", [
    mult_figure,
    lambda: plot_cost_lines(AXIS[1:], {"tcp": COST[5, 1:], "diff": DIFF[5, 1:]}, xlabel="nu", marker=0.5,
                            marker_label="max"),
    lambda: plot_pareto({"tcp": [{"alpha": 2.0, "communication_cost": 1.0},
                                 {"alpha": 4.0, "communication_cost": 0.5}]}),
    lambda: plot_closed_loop({"tcp": {"state_norm_mean": [1.0, 0.5], "state_norm_std": [0.0, 0.1],
                                      "stage_cost_mean": [1.0]}}),
])
def test_legends_sit_beside_the_plot_at_a_readable_size(make):
    fig = make()
    renderer = rendered(fig)
    (legend,) = fig.legends
    ax = fig.axes[0]
    right = max(a.get_window_extent(renderer).x1 for a in fig.axes)
    assert legend.get_window_extent(renderer).x0 >= right        # right of every panel (and colour bar)
    assert all(t.get_fontsize() >= 8 for t in legend.get_texts())
    assert all(a.get_legend() is None for a in fig.axes)         # none inside the axes


def test_cost_lines_on_a_log_axis_say_what_they_leave_out():
    fig = plot_cost_lines([0.1, 0.5, 1.0], {"tcp": [3.0, 20.0, 7.0], "diff": [1.0, 2.0, 0.0]}, xlabel="nu")
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    assert ax.lines[0].get_ydata().tolist() == [3.0, 20.0, 7.0]   # the values themselves, not their logs
    diff = ax.lines[1]
    assert np.isnan(diff.get_ydata()[2])
    assert "1 point <= 0: off the log axis" in diff.get_label()
    assert ax.get_ylabel() == "expected cost (log scale)"
    # round ticks in the values, one label style, no minor labels such as 3x10^1
    assert ax.get_yticks().tolist() == [1.0, 2.0, 5.0, 10.0, 20.0]
    assert [t.get_text() for t in ax.get_yticklabels()] == ["1", "2", "5", "10", "20"]
    assert not [t for t in ax.yaxis.get_minorticklabels() if t.get_text()]
