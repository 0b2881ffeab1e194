"""Typed exceptions.

Bad input subclasses :class:`ValueError` so that ``except ValueError`` still
works; failures of a well-posed computation subclass :class:`RuntimeError` or
:class:`ArithmeticError`.
"""

from __future__ import annotations

__all__ = [
    "DimensionError",
    "InfeasibleError",
    "InputError",
    "NumericalError",
    "ProbabilityError",
    "SolverError",
]


class InputError(ValueError):
    """Bad input: ``field`` names where it is, ``detail`` says what was expected."""

    def __init__(self, field: str, detail: str) -> None:
        self.field = field
        self.detail = detail
        super().__init__(f"{field}: {detail}")

    def renamed(self, field: str) -> InputError:
        """The same error, reported under another field name (e.g. a TOML path)."""
        return type(self)(field, self.detail)


class DimensionError(InputError):
    """An array of the wrong shape."""


class ProbabilityError(InputError):
    """A delivery probability outside [0, 1]."""


class SolverError(RuntimeError):
    """The convex solver did not report an optimal solution."""

    def __init__(self, status: str, detail: str = "") -> None:
        self.status = status
        message = f"solver status {status!r}"
        super().__init__(f"{message}: {detail}" if detail else message)


class InfeasibleError(RuntimeError):
    """No point satisfies the constraints; ``min_cost`` is the best reachable cost."""

    def __init__(self, detail: str, min_cost: float | None = None) -> None:
        self.min_cost = min_cost
        super().__init__(detail)


class NumericalError(ArithmeticError):
    """A dense computation overflowed or lost all precision."""
