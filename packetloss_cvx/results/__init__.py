"""Every result type the package returns: frozen dataclasses with read-only arrays and
``to_dict()`` for JSON (plain lists and floats).

plans.py: one system's solutions; studies.py: design questions; closed_loop.py: the loop run for
ever and sampled; region.py: the stabilisable set; sensing.py: lossy sensors; base.py: what they share.
"""

from .base import eigenvalue_pairs
from .closed_loop import ClosedLoop, ClosedLoopRun, OpenLoopCheck, Riccati, Simulation
from .markov import BurstinessMap, BurstinessSweep, MarkovSolution, MjlsResult, plugin_loss
from .plans import BatchSolution, CrossCheck, LoopStability, Solution
from .region import CriticalPoint, Membership, RegionMap, StabilityAllocation
from .sensing import CovarianceBounds, CriticalGamma, EstimatedLoop, EstimatedRun, FilterStability, SampledCovariance
from .studies import Allocation, ClaimResult, DesignSweep, Maximiser, MinCost, PowerAllocation, ProtocolChoice, Sweep

__all__ = [
    "Allocation",
    "BatchSolution",
    "BurstinessMap",
    "BurstinessSweep",
    "ClaimResult",
    "ClosedLoop",
    "ClosedLoopRun",
    "CovarianceBounds",
    "CriticalGamma",
    "CriticalPoint",
    "CrossCheck",
    "DesignSweep",
    "EstimatedLoop",
    "EstimatedRun",
    "FilterStability",
    "LoopStability",
    "MarkovSolution",
    "Membership",
    "Maximiser",
    "MinCost",
    "MjlsResult",
    "OpenLoopCheck",
    "PowerAllocation",
    "ProtocolChoice",
    "Riccati",
    "RegionMap",
    "SampledCovariance",
    "Simulation",
    "Solution",
    "StabilityAllocation",
    "Sweep",
    "eigenvalue_pairs",
    "plugin_loss",
]
