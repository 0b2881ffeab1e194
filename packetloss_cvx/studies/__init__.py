"""Studies: the paper's figures and tables as data, and design-study sweeps.

``sweeps`` evaluates the optimal costs of both protocols and their difference over grids of
delivery probabilities (the data behind the paper's cost figures). Plots draw these results;
they compute nothing themselves.
"""

from .sweeps import shared_channel_sweep, two_channel_sweep

__all__ = ["shared_channel_sweep", "two_channel_sweep"]
