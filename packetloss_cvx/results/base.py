"""What every result type shares: read-only array copies, JSON-safe floats, eigenvalue order, and a table
(``to_pandas``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..optional import load

__all__ = ["Frozen", "Tabular", "eigenvalue_pairs", "finite_or_none", "freeze", "numbered", "read_only",
           "scalar_row"]


def numbered(name: str, count: int) -> list[str]:
    """Column names of a vector field, 1-based as the CLI and the CSV files number channels and states:
    ``mu1, mu2`` (``x0_1, x0_2`` where the name ends in a digit).

    Examples
    --------
    >>> numbered("mu", 2), numbered("x0", 2)
    (['mu1', 'mu2'], ['x0_1', 'x0_2'])
    """
    sep = "_" if name[-1:].isdigit() else ""
    return [f"{name}{sep}{i + 1}" for i in range(count)]


def _is_number(value: Any) -> bool:
    return value is None or (isinstance(value, (int, float, bool, np.number, np.bool_)) and not isinstance(value, str))


def scalar_row(data: Mapping[str, Any]) -> tuple[dict[str, list], dict[str, Any]]:
    """One table row from a result's ``to_dict()``: numbers and text as columns, a flat list of numbers as one
    column per entry (`numbered`), nested dicts flattened as ``outer_inner``; what is not one value per
    row (matrices, lists of text) goes to the table's ``attrs``. O(size of ``data``).

    Examples
    --------
    >>> scalar_row({"cost": 2.0, "mu": [0.5, 0.9], "gain": [[1.0]], "qp": {"status": "optimal"}})
    ({'cost': [2.0], 'mu1': [0.5], 'mu2': [0.9], 'qp_status': ['optimal']}, {'gain': [[1.0]]})
    """
    row: dict[str, list] = {}
    attrs: dict[str, Any] = {}
    for key, value in data.items():
        if isinstance(value, str) or _is_number(value):
            row[key] = [value]
        elif isinstance(value, (list, tuple)) and value and all(_is_number(v) for v in value):
            row.update({name: [v] for name, v in zip(numbered(key, len(value)), value, strict=True)})
        elif isinstance(value, Mapping):
            inner, inner_attrs = scalar_row(value)
            row.update({f"{key}_{k}": v for k, v in inner.items()})
            attrs.update({f"{key}_{k}": v for k, v in inner_attrs.items()})
        else:
            attrs[key] = value
    return row, attrs


class Tabular:
    """``to_pandas()`` for a result type: a tidy `pandas.DataFrame`, one row per point of the result (one
    row for a result that is a single point), each number once; what describes the whole result (a protocol, a
    method, a scalar cost beside per-step rows) is in the frame's ``attrs``. A subclass that holds a grid, a
    trajectory or a batch overrides `_table`; the others are one row of their ``to_dict()``
    (`scalar_row`). pandas is imported when called (the ``pandas`` extra).

    Examples
    --------
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class Point(Tabular):
    ...     cost: float
    ...     mu: tuple
    ...     def to_dict(self):
    ...         return {"cost": self.cost, "mu": list(self.mu)}
    >>> Point(2.0, (0.5, 0.9)).to_pandas().to_dict("records")
    [{'cost': 2.0, 'mu1': 0.5, 'mu2': 0.9}]
    """

    __slots__ = ()

    def _table(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """(columns, attrs): equal-length columns, one entry per row, and the frame's attributes."""
        return scalar_row(self.to_dict())     # type: ignore[attr-defined]

    def to_pandas(self) -> Any:
        """This result as a tidy `pandas.DataFrame` (one row per point; the ``pandas`` extra). O(size).

        Raises
        ------
        InputError
            Field ``to_pandas`` when pandas is not installed (the message says how to install it).
        """
        pd = load("pandas", "to_pandas")
        columns, attrs = self._table()
        frame = pd.DataFrame(columns)
        frame.attrs.update(attrs)
        return frame


def read_only(value: Any) -> np.ndarray:
    """A read-only copy of ``value`` as an array.

    Examples
    --------
    >>> src = [1.0, 2.0]
    >>> a = read_only(src)
    >>> a.flags.writeable, a.tolist()
    (False, [1.0, 2.0])
    >>> b = np.zeros(2); c = read_only(b); b[0] = 5.0; float(c[0])   # a copy: later writes do not show
    0.0
    """
    arr = np.array(value)
    arr.setflags(write=False)
    return arr


def freeze(obj: Any) -> None:
    """Make every ndarray field of a frozen dataclass a read-only copy.

    Examples
    --------
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class R:
    ...     x: np.ndarray
    ...     def __post_init__(self):
    ...         freeze(self)
    >>> r = R(np.ones(2))
    >>> r.x.flags.writeable
    False
    """
    for name, value in vars(obj).items():
        if isinstance(value, np.ndarray):
            object.__setattr__(obj, name, read_only(value))


class Frozen(Tabular):
    """Base of the frozen result dataclasses: ``__post_init__`` makes their arrays read-only
    (`freeze`; a subclass that checks or derives more calls ``super().__post_init__()`` or
    ``freeze`` itself), and a copy made by pickle (a multiprocessing or joblib worker's answer) or
    ``copy.deepcopy``, which skips ``__init__``, runs ``__post_init__`` again when its state is set, so
    its arrays are read-only as the original's. O(size of the arrays), as building the result.

    Examples
    --------
    >>> import copy, pickle
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class R(Frozen):
    ...     x: np.ndarray
    >>> R(np.ones(2)).x.flags.writeable, copy.deepcopy(R(np.ones(2))).x.flags.writeable
    (False, False)
    """

    __slots__ = ()

    def __post_init__(self) -> None:
        freeze(self)

    def __setstate__(self, state: Any) -> None:
        if isinstance(state, tuple):         # (dict, slots) when a subclass has __slots__
            state = {**(state[0] or {}), **(state[1] or {})}
        for key, value in state.items():
            object.__setattr__(self, key, value)
        self.__post_init__()


def finite_or_none(value: float | None) -> float | None:
    """``value`` as a float, or None when it is missing or not finite (JSON has no inf).

    Examples
    --------
    >>> finite_or_none(np.float64(2.5)), finite_or_none(np.inf), finite_or_none(np.nan), finite_or_none(None)
    (2.5, None, None, None)
    """
    return float(value) if value is not None and np.isfinite(value) else None


def eigenvalue_pairs(eigs: np.ndarray) -> list[list[float]]:
    """Complex eigenvalues as ``[[re, im], ...]`` sorted by descending modulus, then real part.

    Examples
    --------
    >>> eigenvalue_pairs(np.array([0.5, -2.0, 2.0, 1j]))   # |2| first, +2 before -2; |i| = 1 > 0.5
    [[2.0, 0.0], [-2.0, 0.0], [0.0, 1.0], [0.5, 0.0]]
    """
    order = sorted(range(len(eigs)), key=lambda i: (-abs(eigs[i]), -eigs[i].real, -eigs[i].imag))
    return [[float(eigs[i].real), float(eigs[i].imag)] for i in order]
