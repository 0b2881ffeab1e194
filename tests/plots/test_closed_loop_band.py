"""On a log axis the closed-loop figure's band of ||x_t|| is the geometric spread mean x/÷ (1 + std / mean), not
mean - std clipped at 0 (drawn down to the axis' bottom edge and read as spread), and the axis label says so."""

import numpy as np
import pytest

from packetloss_cvx.plots import plot_closed_loop

RUN = {"state_norm_mean": [1.0, 0.5, 0.25], "state_norm_std": [0.0, 1.0, 1.0], "stage_cost_mean": [2.0, 1.0]}


def _band(axis):
    """The band's lower and upper edge at each step, read from the drawn polygon (x -> its y values)."""
    vertices = axis.collections[0].get_paths()[0].vertices
    edges = {}
    for x, y in vertices:
        edges.setdefault(round(float(x), 9), []).append(float(y))
    return {x: (min(ys), max(ys)) for x, ys in edges.items()}


def test_on_a_log_axis_the_band_is_the_geometric_spread():
    left = plot_closed_loop({"tcp": RUN}, yscale="log").axes[0]
    band = _band(left)
    # by hand: lower = mean^2 / (mean + std), upper = mean + std
    assert band[1.0] == pytest.approx((0.25 / 1.5, 1.5), rel=1e-12)
    assert band[2.0] == pytest.approx((0.0625 / 1.25, 1.25), rel=1e-12)
    assert min(lo for lo, _ in band.values()) > 0         # std > mean, yet the band stays above 0
    assert "std/mean" in left.get_ylabel()
    assert r"\pm" not in left.get_ylabel()


def test_on_a_linear_axis_the_band_is_mean_plus_minus_std_clipped_at_zero():
    left = plot_closed_loop({"tcp": RUN}).axes[0]
    band = _band(left)
    assert band[1.0] == pytest.approx((0.0, 1.5))
    assert band[2.0] == pytest.approx((0.0, 1.25))
    assert r"\pm" in left.get_ylabel()


def test_the_log_band_renders(tmp_path):
    path = tmp_path / "loop.png"
    plot_closed_loop({"tcp": RUN, "udp": {**RUN, "state_norm_mean": [1.0, 0.0, np.inf]}}, yscale="log", path=path)
    assert path.stat().st_size > 0
