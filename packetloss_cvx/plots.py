"""Matplotlib figures (Agg backend: files only, no screen needed)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .allocation import contour_allocations, pareto_curve  # noqa: E402
from .costs import closed_form  # noqa: E402
from .model import System  # noqa: E402

__all__ = ["plot_allocation_contours", "plot_pareto"]


def plot_pareto(system: System, beta, alphas: Sequence[float], path: str | Path) -> dict:
    """The trade-off alpha <-> communication cost beta'mu* for both protocols; returns the data."""
    data = {p: pareto_curve(system, p, beta, alphas) for p in ("tcp", "udp")}
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for protocol, rows in data.items():
        pts = [(r["alpha"], r["communication_cost"]) for r in rows if r["communication_cost"] is not None]
        if pts:
            ax.plot(*zip(*pts, strict=True), marker="o", ms=3, label=f"{protocol.upper()}-like")
    ax.set_xlabel(r"cost bound $\alpha$")
    ax.set_ylabel(r"communication cost $\beta^\top\mu^*$")
    ax.set_title(f"{system.name or 'system'}: beta = {tuple(float(b) for b in beta)}")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return data


def plot_allocation_contours(system: System, protocol: str, alphas: Sequence[float], path: str | Path,
                             grid: int = 41) -> dict:
    """Figs. 6–7: log J*(mu) over [0, 1]^2 with the optimal allocation on each contour alpha,
    for beta = (1, 1), (0.05, 1), (1, 0.05). Returns the allocation points."""
    if system.m != 2:
        raise ValueError("system: expected m = 2 channels")
    axis = np.linspace(0.0, 1.0, grid)
    J = np.array([[closed_form(system.with_mu([a, b]), protocol, "auto").cost for a in axis] for b in axis])
    points = contour_allocations(system, protocol, alphas)
    fig, ax = plt.subplots(figsize=(5, 4.5))
    cs = ax.contour(axis, axis, J, levels=sorted(alphas), colors="0.4", linewidths=0.8)
    ax.clabel(cs, fmt="%.3g", fontsize=7)
    ax.contourf(axis, axis, np.log(J), levels=30, cmap="viridis", alpha=0.6)
    for (beta, rows), marker in zip(points.items(), ("x", "^", "s"), strict=False):
        pts = [r["mu"] for r in rows if r["mu"] is not None]
        if pts:
            ax.plot(*np.array(pts).T, marker=marker, ls="--", color="k", ms=5, lw=0.8, label=f"beta={beta}")
    ax.set_xlabel(r"$\mu_1$")
    ax.set_ylabel(r"$\mu_2$")
    ax.set_title(f"{protocol.upper()}-like: log J*, optimal allocations")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return {str(k): v for k, v in points.items()}
