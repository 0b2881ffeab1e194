"""packetloss-cvx: optimal control over multichannel packet-loss links, cross-checked.

Implements "Optimal Control of Systems with Multichannel Packet Loss" (Casbolt,
Jones, Esnaola): each formula in closed form and as a Clarabel QP.
"""

from .allocation import allocate
from .claims import audit
from .costs import closed_form, expected_cost, paper_optimal_cost
from .errors import (
    CrossCheckError,
    DimensionError,
    InfeasibleError,
    InputError,
    NumericalError,
    ProbabilityError,
    ResourceError,
    SolverError,
)
from .io import load_example, load_system, save_system
from .model import System
from .qp import ExpectedCostQP, solve_qp
from .results import Allocation, ClaimResult, CrossCheck, Maximiser, Solution

__version__ = "0.1.0"

__all__ = [
    "Allocation",
    "ClaimResult",
    "CrossCheck",
    "CrossCheckError",
    "DimensionError",
    "ExpectedCostQP",
    "InfeasibleError",
    "InputError",
    "Maximiser",
    "NumericalError",
    "ProbabilityError",
    "ResourceError",
    "Solution",
    "SolverError",
    "allocate",
    "audit",
    "System",
    "closed_form",
    "expected_cost",
    "load_example",
    "load_system",
    "save_system",
    "paper_optimal_cost",
    "solve_qp",
]
