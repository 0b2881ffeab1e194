"""Typed exceptions.

Bad input subclasses `ValueError` so that ``except ValueError`` still
works; failures of a well-posed computation subclass `RuntimeError` or
`ArithmeticError`. Each pickles with its own fields (``__reduce__``), so an error raised in a
multiprocessing or joblib worker reaches the caller as itself: an exception whose constructor takes
more than its message cannot be rebuilt from ``args`` alone, and a worker's InputError broke the
whole ProcessPoolExecutor (BrokenProcessPool for every task, the message lost).
"""

from __future__ import annotations

__all__ = [
    "BudgetError",
    "CrossCheckError",
    "DimensionError",
    "FolderBusyError",
    "InfeasibleError",
    "InputError",
    "NumericalError",
    "OutputExistsError",
    "ProbabilityError",
    "ResourceError",
    "SolverError",
    "UnobservedModeError",
    "is_panic",
]


class InputError(ValueError):
    """Bad input: ``field`` names where it is, ``detail`` says what was expected."""

    def __init__(self, field: str, detail: str) -> None:
        self.field = field
        self.detail = detail
        super().__init__(f"{field}: {detail}")

    def __reduce__(self) -> tuple:
        return type(self), (self.field, self.detail), self.__dict__

    def renamed(self, field: str) -> InputError:
        """The same error, reported under another field name (e.g. a TOML path)."""
        return type(self)(field, self.detail)


class DimensionError(InputError):
    """An array of the wrong shape."""


class ProbabilityError(InputError):
    """A delivery probability outside [0, 1]."""


class OutputExistsError(InputError):
    """An output would replace a user's file, or write into a folder holding files this package did not
    write (docs/design.md §4, "Files and runs"); ``--force`` (API: ``overwrite=True``) allows it."""


class FolderBusyError(InputError):
    """An output folder is being written by another live run (its lock names the pid)."""


class UnobservedModeError(InputError):
    """An optimal law asked of a controller that does not know what it needs: without acknowledgements (UDP-like)
    the input an actuator holds, the age of the plan it plays, or the channel state behind a chain
    (closedloop.actuator_design.check_protocol); ``detail`` says why and what to use instead."""


class SolverError(RuntimeError):
    """The convex solver did not report an optimal solution. A solver that says "infeasible" without a certificate
    that survives its rounding is this, not `InfeasibleError`: ``certificate`` then holds the check's verdict
    ("undecided") and its reason."""

    def __init__(self, status: str, detail: str = "", certificate: dict | None = None) -> None:
        self.status = status
        self.detail = detail
        self.certificate = certificate
        message = f"solver status {status!r}"
        super().__init__(f"{message}: {detail}" if detail else message)

    def __reduce__(self) -> tuple:
        return type(self), (self.status, self.detail, self.certificate), self.__dict__


class InfeasibleError(RuntimeError):
    """No point satisfies the constraints; ``min_cost`` is the best reachable cost (where known), ``status`` the
    solver's status that proved it (where a solver did), ``certificate`` the solver's Farkas multipliers and whether
    they survive their rounding (where a solver gave them)."""

    def __init__(self, detail: str, min_cost: float | None = None, status: str | None = None,
                 certificate: dict | None = None) -> None:
        self.min_cost = min_cost
        self.status = status
        self.certificate = certificate
        super().__init__(detail)

    def __reduce__(self) -> tuple:
        return type(self), (self.args[0], self.min_cost, self.status, self.certificate), self.__dict__


class NumericalError(ArithmeticError):
    """A computation overflowed, or would lose (or did lose) the digits of its answer."""


class CrossCheckError(ArithmeticError):
    """Two independent computations of the same number disagree beyond the stated tolerance.

    ``values`` maps each method to its number, so the message and the caller can name both.
    """

    def __init__(self, detail: str, values: dict[str, float]) -> None:
        self.values = dict(values)
        super().__init__(detail)

    def __reduce__(self) -> tuple:
        return type(self), (self.args[0], self.values), self.__dict__


class ResourceError(RuntimeError):
    """A computation does not fit its budget. Refused before any work starts it is a
    [`BudgetError`][packetloss_cvx.errors.BudgetError] (also a ValueError: the command line exits 2); a plain
    ResourceError is a limit met during the work, whose size was not known in advance (e.g. a belief law that re-plans
    more often than its plan budget). ``needed_bytes`` and ``budget_bytes`` are in the budget's unit (bytes for
    memory)."""

    def __init__(self, detail: str, needed_bytes: float, budget_bytes: float) -> None:
        self.needed_bytes = needed_bytes
        self.budget_bytes = budget_bytes
        super().__init__(detail)

    def __reduce__(self) -> tuple:
        return type(self), (self.args[0], self.needed_bytes, self.budget_bytes), self.__dict__


class BudgetError(ResourceError, InputError):
    """A count or size the caller gave (samples, steps, points, cases, workers, boxes, a file's bytes), or the
    memory a system and a method need (the dense method, a QP, a second-moment operator), is beyond its budget
    (`packetloss_cvx.budgets`), refused before any work starts; the message says what to use instead.

    Both a [`ResourceError`][packetloss_cvx.errors.ResourceError] (the work is refused for its size) and an
    [`InputError`][packetloss_cvx.errors.InputError] (the caller asked for it: ``field`` names the argument or option;
    the command line exits 2). ``needed`` and ``budget`` are in the budget's unit; ``env`` is the environment variable
    that raises the budget on purpose.

    Examples
    --------
    >>> err = BudgetError("samples", "too much", 2e14, 1e11, "PACKETLOSS_CVX_BUDGET_SIMULATE_WORK")
    >>> isinstance(err, ResourceError), isinstance(err, ValueError), str(err)
    (True, True, 'samples: too much')
    >>> err.renamed("--samples").field, err.renamed("--samples").budget
    ('--samples', 100000000000.0)
    """

    def __init__(self, field: str, detail: str, needed: float, budget: float, env: str) -> None:
        self.field, self.detail, self.env = field, detail, env
        self.needed, self.budget = float(needed), float(budget)
        ResourceError.__init__(self, f"{field}: {detail}", self.needed, self.budget)

    def __reduce__(self) -> tuple:
        return type(self), (self.field, self.detail, self.needed, self.budget, self.env), self.__dict__

    def renamed(self, field: str) -> BudgetError:
        """The same refusal, reported under another field name (the command-line option)."""
        return type(self)(field, self.detail, self.needed, self.budget, self.env)


def is_panic(err: BaseException) -> bool:
    """Whether ``err`` is a panic of Rust code under pyo3 (Clarabel's): pyo3 raises ``pyo3_runtime.PanicException``,
    a BaseException subclass that no Python module exports, so it is known by its name. O(1).

    Examples
    --------
    >>> PanicException = type("PanicException", (BaseException,), {})
    >>> is_panic(PanicException("Eigval error")), is_panic(ValueError("x")), is_panic(KeyboardInterrupt())
    (True, False, False)
    """
    return type(err).__name__ == "PanicException"
