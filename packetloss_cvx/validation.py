"""The one validator of numeric input (:func:`numeric_array`): every array the package accepts goes
through it, so that every error names its field. Iterative, O(number of entries)."""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np

from .errors import InputError

__all__ = ["MAX_ENTRIES", "MAX_NESTING", "check_numbers", "digits", "numeric_array"]

#: Arrays in the schema nest at most three levels deep (state_weights: N × n × n).
MAX_NESTING = 3
#: The largest number of entries one stored array may have (8 bytes each: 400 MB), so that a
#: System is refused before an allocation that cannot succeed (horizon = 10**9).
MAX_ENTRIES = 5 * 10**7


def numeric_array(value: Any, field: str) -> np.ndarray:
    """Convert ``value`` to a float array, refusing strings, booleans, NaN, inf, numbers beyond
    the double range, nesting deeper than ``MAX_NESTING`` and more than ``MAX_ENTRIES`` entries.

    The one validator of numeric input: every array the package accepts goes through it,
    so every error names ``field``.

    Examples
    --------
    >>> numeric_array([[1, 2], [3, 4.5]], "A").tolist()
    [[1.0, 2.0], [3.0, 4.5]]
    >>> numeric_array([1.0, float("nan")], "mu")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: mu: expected finite numbers, found NaN or inf
    """
    if isinstance(value, np.ma.MaskedArray) and np.ma.is_masked(value):
        raise InputError(field, "expected plain numbers, found a masked array with masked entries")
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf":
            raise InputError(field, f"expected numbers, found an array of {value.dtype}")
        if value.ndim > MAX_NESTING or value.size > MAX_ENTRIES:
            raise InputError(field, f"expected at most {MAX_NESTING} dimensions and {MAX_ENTRIES} entries, found "
                                    f"shape {value.shape}")
        arr = value.astype(float)
    else:
        check_numbers(value, field)
        try:
            arr = np.asarray(value, dtype=float)
        except ValueError:
            raise InputError(field, "expected a rectangular array of numbers") from None
    if not np.all(np.isfinite(arr)):
        raise InputError(field, "expected finite numbers, found NaN or inf")
    return arr


def check_numbers(value: Any, field: str) -> None:
    """Walk ``value`` without recursion: numbers only, at most MAX_NESTING levels of lists,
    at most MAX_ENTRIES numbers, each within the double range.

    Examples
    --------
    >>> check_numbers([[1, 2.5], [3, 4]], "B") is None       # numbers only: passes silently
    True
    >>> check_numbers([1, "2"], "B")
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: B: expected a number, found the string '2'
    """
    stack: list[tuple[Any, int]] = [(value, 0)]
    count = 0
    while stack:
        item, depth = stack.pop()
        if isinstance(item, bool):
            raise InputError(field, "expected a number, found a boolean")
        if isinstance(item, numbers.Real):
            count += 1
            if count > MAX_ENTRIES:
                raise InputError(field, f"expected at most {MAX_ENTRIES} numbers")
            if isinstance(item, numbers.Integral):
                try:
                    float(item)
                except OverflowError:
                    size = digits(int(item))
                    raise InputError(field, f"expected numbers within the double range (|x| < 1.8e308), found an "
                                            f"integer of about {size} digits") from None
            continue
        if isinstance(item, np.ndarray):            # a row given as an array inside a list
            if item.dtype.kind not in "iuf" or depth + item.ndim > MAX_NESTING:
                raise InputError(field, f"expected numbers, found an array of {item.dtype} and shape {item.shape}")
            count += item.size
            continue
        if isinstance(item, str):
            raise InputError(field, f"expected a number, found the string {item[:40]!r}")
        if isinstance(item, (list, tuple)):
            if depth >= MAX_NESTING:
                raise InputError(field, f"expected at most {MAX_NESTING} levels of nested lists, found more")
            stack.extend((sub, depth + 1) for sub in item)
            continue
        raise InputError(field, f"expected a number or a list of numbers, found {type(item).__name__}")


def digits(value: int) -> int:
    """Decimal digits of a huge integer, without str() (Python refuses it past 4300 digits).

    >>> digits(10**5000)
    5001
    """
    return int(abs(value).bit_length() * 0.30103) + 1
