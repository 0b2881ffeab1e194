"""Studies: the paper's figures and tables as data, and design-study sweeps.

``sweeps`` evaluates the optimal costs of both protocols and their difference over grids of
delivery probabilities (the data behind the paper's cost figures); ``design`` runs design-study
sweeps over channels, initial states or horizons, batched and optionally on Dask (``engine``),
saved by ``output``; ``allocation`` the allocation studies (Pareto curve, contour allocations, the J*(mu) grid; it
imports cvxpy, so
it is not loaded here);
``burstiness`` sweeps and maps over a chain's burstiness at fixed average rates; ``region_map`` the stabilisable
set over a grid of channels; ``paper_figures`` the paper's figures as data. Plots draw these results; they compute
nothing themselves.
"""

from .design import read_mu_list, sweep
from .output import require_xarray, save_sweep
from .sweeps import shared_channel_sweep, two_channel_sweep

__all__ = ["read_mu_list", "require_xarray", "save_sweep", "shared_channel_sweep", "sweep", "two_channel_sweep"]
