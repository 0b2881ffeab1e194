"""What a reviewer checks on the figures, read from what was drawn (artists, extents, limits, legends): no empty
band beside a square map, every contour level named once, each marker's level said, paths broken where told,
the region map's boundary interpolated and its colours fitting the data, legends listing only what is drawn,
power with its unit, closed-loop axes that a diverging law does not flatten, the stability lines."""

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.contour import ContourSet
from matplotlib.lines import Line2D
from matplotlib.text import Annotation

from packetloss_cvx.errors import InputError
from packetloss_cvx.plots import (
    plot_closed_loop,
    plot_log_contour,
    plot_power_pareto,
    plot_region,
    plot_sensor_map,
    plot_stability_lines,
)
from packetloss_cvx.plots.style import tick_text

AXIS = np.linspace(0.0, 1.0, 61)
MU1, MU2 = np.meshgrid(AXIS, AXIS)
#: like the two-actuator system's J*: about 2 at (1, 1), 150 at (0, 0), the high levels packed near (0, 0)
COST = 2.0 + 140.0 * (1 - MU1) ** 2 * (1 - MU2) ** 2 + 8.0 * (1 - MU1 * MU2)
ALPHAS = (2.5, 3.5, 4.78, 6.0, 8.0, 12.0, 20.0, 35.0, 50.0, 70.0, 100.0)


def rendered(fig):
    FigureCanvasAgg(fig).draw()
    return fig.canvas.get_renderer()


def on_diagonal(alpha):
    """The point (t, t) where COST = alpha, by bisection on the closed form (COST falls as t rises)."""
    lo, hi = 0.0, 1.0
    for _ in range(60):
        t = (lo + hi) / 2
        value = 2.0 + 140.0 * (1 - t) ** 4 + 8.0 * (1 - t * t)
        lo, hi = (t, hi) if value > alpha else (lo, t)
    return ((lo + hi) / 2, (lo + hi) / 2)


def test_a_square_map_without_a_legend_leaves_no_empty_band():
    """fig:TCP-log-cost-mixed had a quarter of its width empty on the left: the figure is as wide as what it
    draws (tight box within a quarter inch of the figure's width)."""
    fig = plot_log_contour(AXIS, AXIS, COST)
    renderer = rendered(fig)
    assert fig.get_figwidth() - fig.get_tightbbox(renderer).width < 0.4


def test_every_contour_level_is_named_once_and_each_marker_says_its_level():
    """The levels packed into a corner (alpha >= 20 on the two-actuator map) had no label: each level inside the
    data is named exactly once, on its line or beside a marker on it with a leader; labels overlap neither each
    other nor the frame; the legend says what a marker is."""
    points = [on_diagonal(a) for a in ALPHAS]
    fig = plot_log_contour(AXIS, AXIS, COST, levels=ALPHAS, allocations={"beta = (1, 1)": points})
    renderer = rendered(fig)
    ax = fig.axes[0]
    inside = [a for a in ALPHAS if COST.min() < a < COST.max()]
    texts = [t for t in ax.texts if t.get_text()]
    assert sorted(t.get_text() for t in texts) == sorted(tick_text(a) for a in inside)
    callouts = [t for t in texts if isinstance(t, Annotation)]
    assert callouts, "the crowded levels are named beside their markers"
    to_frac = ax.transData + ax.transAxes.inverted()
    for text in callouts:                  # the leader starts at the marker of the level it names
        level = inside[[tick_text(a) for a in inside].index(text.get_text())]
        marker = to_frac.transform([points[ALPHAS.index(level)]])[0]
        assert np.allclose(text.xy, marker, atol=1e-9)
    boxes = [t.get_window_extent(renderer) for t in texts]
    frame = ax.get_window_extent(renderer)
    for k, a in enumerate(boxes):
        assert frame.x0 <= a.x0 <= a.x1 <= frame.x1
        assert frame.y0 <= a.y0 <= a.y1 <= frame.y1
        for b in boxes[k + 1:]:
            assert not a.overlaps(b)
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any(text.startswith("each marker") for text in legend)


def test_paths_and_markers_on_the_edges_stay_off_the_frame():
    """Markers on mu = 0 or 1 were drawn across the frame: the axes reach beyond the grid on every side."""
    fig = plot_log_contour(AXIS, AXIS, COST, allocations={"b": [(0.0, 1.0), (1.0, 0.0)]}, marker=(0.0, 0.0))
    ax = fig.axes[0]
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert x0 < 0.0 < 1.0 < x1
    assert y0 < 0.0 < 1.0 < y1


def test_a_path_is_broken_at_the_steps_given():
    """The UDP-like beta = (1, 1) path drew a straight segment across the map where the optimum jumps: the line
    has a gap there (a nan row), nowhere else, and the legend says why."""
    path = [(0.98, 0.95), (0.98, 0.5), (0.98, 0.0), (0.13, 0.73), (0.06, 0.44)]
    fig = plot_log_contour(AXIS, AXIS, COST, levels=ALPHAS[:5], allocations={"b": path}, breaks={"b": [2]})
    (line,) = [line for line in fig.axes[0].lines if line.get_label() == "b"]
    xy = line.get_xydata()
    gaps = np.flatnonzero(np.isnan(xy).all(axis=1))
    assert gaps.tolist() == [3]
    assert np.array_equal(np.delete(xy, gaps, axis=0), np.asarray(path))
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any("broken" in text for text in legend)
    whole = plot_log_contour(AXIS, AXIS, COST, allocations={"b": path})
    assert not np.isnan(whole.axes[0].lines[0].get_xydata()).any()


def radial_region(points=11):
    """r = |mu| / 0.5 on a coarse grid: the radius = 1 line is the quarter circle of radius 0.5."""
    axis = np.linspace(0.0, 1.0, points)
    m1, m2 = np.meshgrid(axis, axis)
    radius = np.hypot(m1, m2) / 0.5 * 0.55          # 0 to 1.56, and 1 at |mu| = 0.5 / 0.55
    return axis, radius


def test_the_region_boundary_is_interpolated_not_a_staircase():
    """A 21 x 21 region map drew the 1/2 level of a 0/1 map: a staircase half a step off. The dp boundary is the
    radius' level 1, interpolated between grid points: on an 11-point grid its vertices lie within 0.01 of the
    exact circle |mu| = 0.5 / 0.55 (the staircase is off by up to half a step, 0.05)."""
    axis, radius = radial_region()
    fig = plot_region(axis, radius, {"dp": (radius < 1.0).astype(float)})
    ax = fig.axes[0]
    lines = [c for c in ax.collections if isinstance(c, ContourSet) and not c.filled]
    assert len(lines) == 1
    vertices = np.vstack([p.vertices for p in lines[0].get_paths() if len(p.vertices)])
    assert np.max(np.abs(np.hypot(vertices[:, 0], vertices[:, 1]) - 0.5 / 0.55)) < 0.01


def test_the_region_colours_fit_the_data_and_each_side_is_named():
    """The colour scale ran to 2 for data up to 1.1, and nothing said which side is stable."""
    axis, radius = radial_region()
    radius = radius * 1.1 / radius.max()            # data up to 1.1, as the two-actuator map's
    fig = plot_region(axis, radius, {"dp": (radius < 1.0).astype(float)})
    ax = fig.axes[0]
    filled = ax.collections[0]
    assert (filled.norm.vmin, filled.norm.vmax) == pytest.approx((radius.min(), radius.max()))
    named = {t.get_text().split("\n")[0]: t for t in ax.texts}
    assert set(named) == {"stable", "not stabilisable"}
    for word, side in (("stable", radius < 1.0), ("not stabilisable", radius > 1.0)):
        x, y = named[word].xy if isinstance(named[word], Annotation) else named[word].get_position()
        i, j = np.argmin(np.abs(axis - x)), np.argmin(np.abs(axis - y))
        assert side[j, i], word                     # the word points into its own side


def drawn_lines(ax):
    return [c for c in ax.collections if isinstance(c, ContourSet) and not c.filled]


@pytest.mark.parametrize("make", [
    lambda: plot_region(*radial_region(), {"dp": (radial_region()[1] < 1).astype(float), "tcp": np.ones((11, 11)),
                                           "udp": (radial_region()[1] < 0.8).astype(float)}),
    lambda: plot_sensor_map([0.5, 0.75, 1.0], [0.5, 0.75, 1.0], np.full((3, 3), 2.0),
                            {"dp": [[0, 1, 1], [1, 1, 1], [1, 1, 1]], "tcp": np.ones((3, 3)),
                             "udp": np.zeros((3, 3))}),
])
def test_legends_list_only_the_lines_drawn(make):
    """The sensor map's legend listed two boundaries that were not drawn (a law stable everywhere or nowhere has
    none): the legend's lines are the lines on the map, one each; the others are said in words."""
    fig = make()
    ax = fig.axes[0]
    handles = [h for h in fig.legends[0].legend_handles if isinstance(h, Line2D) and h.get_linestyle() != "None"]
    assert len(handles) == len(drawn_lines(ax))
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert sum("boundary" in t for t in texts) == len(drawn_lines(ax))


def test_power_axis_has_its_unit():
    rows = [{"budget": 0.0, "cost": 4.0}, {"budget": 1.0, "cost": 2.0}]
    assert plot_power_pareto({"tcp": rows}, unit="mW").axes[0].get_xlabel().endswith("(mW)")
    assert plot_power_pareto({"tcp": rows}).axes[0].get_xlabel().endswith("(power-table units)")


def test_closed_loop_on_a_log_axis_keeps_a_diverging_law_from_flattening_the_others():
    t = np.arange(21)
    runs = {"tcp": {"state_norm_mean": 0.9 ** t, "state_norm_std": 0.1 * 0.9 ** t,
                    "stage_cost_mean": 0.8 ** t[1:]},
            "udp": {"state_norm_mean": 2.0 ** t, "state_norm_std": 0.1 * 2.0 ** t,
                    "stage_cost_mean": 4.0 ** t[1:]}}
    linear = plot_closed_loop(runs)
    assert [ax.get_yscale() for ax in linear.axes] == ["linear", "linear"]
    fig = plot_closed_loop(runs, yscale="log")
    assert [ax.get_yscale() for ax in fig.axes] == ["log", "log"]
    left = fig.axes[0]
    low, high = left.get_ylim()
    assert low < 0.9 ** 20 < 2.0 ** 20 < high          # both laws on the axis, decades apart
    assert "log scale" in left.get_ylabel()
    with pytest.raises(InputError, match="yscale"):
        plot_closed_loop(runs, yscale="logit")


def test_stability_lines_mark_radius_one():
    x = [0.1, 0.5, 0.9]
    fig = plot_stability_lines(x, {"tcp": [2.5, 0.9, 0.4], "udp": [1.2, 1.1, 0.95]}, xlabel="nu")
    ax = fig.axes[0]
    laws = [line for line in ax.lines if line.get_label().endswith("law")]
    assert [line.get_ydata().tolist() for line in laws] == [[2.5, 0.9, 0.4], [1.2, 1.1, 0.95]]
    (one,) = [line for line in ax.lines if line.get_label() == "radius = 1"]
    assert set(one.get_ydata()) == {1.0}
    assert ax.get_ylim()[0] <= 0.4 < 2.5 <= ax.get_ylim()[1]
