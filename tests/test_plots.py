"""Figures are written and their data are the allocations."""

import numpy as np

from packetloss_cvx.allocation import allocate
from packetloss_cvx.plots import plot_allocation_contours, plot_pareto


def test_pareto_figure(two_actuator, tmp_path):
    path = tmp_path / "pareto.png"
    data = plot_pareto(two_actuator, (1.0, 1.0), [1.5, 4.78, 10.0], path)
    assert path.stat().st_size > 1000
    assert data["udp"][0]["communication_cost"] is None          # 1.5 is below the reachable cost
    tcp, udp = data["tcp"][1]["communication_cost"], data["udp"][1]["communication_cost"]
    assert tcp < udp                                               # TCP-like needs less channel
    assert np.isclose(udp, allocate(two_actuator, "udp", 4.78, (1.0, 1.0)).communication_cost, rtol=1e-9)


def test_contour_figure(two_actuator, tmp_path):
    path = tmp_path / "contours.png"
    points = plot_allocation_contours(two_actuator, "tcp", [4.78, 10.0], path, grid=11)
    assert path.stat().st_size > 1000
    assert set(points) == {"(1, 1)", "(0.05, 1)", "(1, 0.05)"}
