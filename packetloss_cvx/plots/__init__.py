"""Matplotlib figures drawn from data that something else computed (``figures``), in one style (``style``).
Plots only draw."""

from .figures import (
    plot_ack_break_even,
    plot_allocation_contours,
    plot_burstiness_map,
    plot_closed_loop,
    plot_cost_lines,
    plot_log_contour,
    plot_mpc,
    plot_pareto,
    plot_power_pareto,
    plot_region,
    plot_sensor_map,
    plot_stability_lines,
    plot_strategy_map,
)

__all__ = [
    "plot_ack_break_even", "plot_allocation_contours", "plot_burstiness_map", "plot_closed_loop", "plot_cost_lines",
    "plot_log_contour", "plot_mpc", "plot_pareto", "plot_power_pareto", "plot_region", "plot_sensor_map",
    "plot_stability_lines", "plot_strategy_map",
]
