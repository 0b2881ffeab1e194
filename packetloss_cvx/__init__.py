"""packetloss-cvx: optimal control over multichannel packet-loss links, cross-checked.

Implements "Optimal Control of Systems with Multichannel Packet Loss" (Casbolt,
Jones, Esnaola): each formula in closed form and as a Clarabel QP.
"""

from .costs import closed_form, expected_cost, paper_optimal_cost
from .errors import (
    DimensionError,
    InfeasibleError,
    InputError,
    NumericalError,
    ProbabilityError,
    SolverError,
)
from .io import load_example, load_system, save_system
from .model import System
from .qp import ExpectedCostQP, solve_qp
from .results import CrossCheck, Solution

__version__ = "0.1.0"

__all__ = [
    "CrossCheck",
    "DimensionError",
    "ExpectedCostQP",
    "InfeasibleError",
    "InputError",
    "NumericalError",
    "ProbabilityError",
    "Solution",
    "SolverError",
    "System",
    "closed_form",
    "expected_cost",
    "load_example",
    "load_system",
    "save_system",
    "paper_optimal_cost",
    "solve_qp",
]
