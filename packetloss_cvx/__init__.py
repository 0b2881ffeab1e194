"""packetloss-cvx: optimal control over multichannel packet-loss links, cross-checked.

Implements "Optimal Control of Systems with Multichannel Packet Loss" (Casbolt,
Jones, Esnaola): each formula in closed form and as a Clarabel QP.

The public names below are imported on first use (PEP 562), so that importing the
package, or running ``packetloss-cvx --help``, does not import cvxpy or scipy.
"""

# No ``from __future__ import annotations`` and every helper module bound under a private name: the
# module's globals are what ``dir(packetloss_cvx)`` would otherwise show (tests/house/test_namespace.py).
import importlib as _importlib
import typing as _typing

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

if _typing.TYPE_CHECKING:   # the names a type checker and an IDE see; at run time they load on first use
    from .allocation import allocate
    from .claims import audit
    from .lq.costs import closed_form, expected_cost, paper_optimal_cost
    from .model.files import load_example, load_system, save_system
    from .model.system import System
    from .qp.expected_cost import ExpectedCostQP, solve_qp
    from .results import Allocation, ClaimResult, CrossCheck, Maximiser, Solution

__version__ = "0.1.0"

#: public name -> the module (of this package) that defines it
_LAZY = {
    "allocate": "allocation", "audit": "claims",
    "closed_form": "lq.costs", "expected_cost": "lq.costs", "paper_optimal_cost": "lq.costs",
    "load_example": "model.files", "load_system": "model.files", "save_system": "model.files",
    "System": "model.system", "ExpectedCostQP": "qp.expected_cost", "solve_qp": "qp.expected_cost",
    "Allocation": "results", "ClaimResult": "results", "CrossCheck": "results", "Maximiser": "results",
    "Solution": "results",
}

__all__ = [
    "CrossCheckError",
    "DimensionError",
    "InfeasibleError",
    "InputError",
    "NumericalError",
    "ProbabilityError",
    "ResourceError",
    "SolverError",
    "Allocation",
    "ClaimResult",
    "CrossCheck",
    "ExpectedCostQP",
    "Maximiser",
    "Solution",
    "System",
    "allocate",
    "audit",
    "closed_form",
    "expected_cost",
    "load_example",
    "load_system",
    "paper_optimal_cost",
    "save_system",
    "solve_qp",
]


def __getattr__(name: str) -> object:
    """Import a public name's module on first use (PEP 562)."""
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(_importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The public names (``__all__``, loaded or not) and ``__version__``: no helper imports, and no
    submodule that happens to be loaded (``errors``, ``model``, ...). O(len(__all__))."""
    return sorted([*__all__, "__version__"])
