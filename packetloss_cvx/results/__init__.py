"""Every result type the package returns: frozen dataclasses with read-only arrays and
``to_dict()`` for JSON (plain lists and floats).

plans.py: one system's solutions; studies.py: design questions; closed_loop.py: the loop run for
ever and sampled; region.py: the stabilisable set; base.py: what they share.
"""

from .base import eigenvalue_pairs
from .closed_loop import ClosedLoop, ClosedLoopRun, OpenLoopCheck, Riccati, Simulation
from .markov import BurstinessSweep, MarkovSolution, MjlsResult
from .plans import BatchSolution, CrossCheck, Solution
from .region import CriticalPoint, Membership, RegionMap
from .studies import Allocation, ClaimResult, DesignSweep, Maximiser, MinCost, PowerAllocation, ProtocolChoice, Sweep

__all__ = [
    "Allocation",
    "BatchSolution",
    "BurstinessSweep",
    "ClaimResult",
    "ClosedLoop",
    "ClosedLoopRun",
    "CriticalPoint",
    "CrossCheck",
    "DesignSweep",
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
    "Simulation",
    "Solution",
    "Sweep",
    "eigenvalue_pairs",
]
