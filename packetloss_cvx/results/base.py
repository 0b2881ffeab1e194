"""What every result type shares: read-only array copies, JSON-safe floats, eigenvalue order."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["Frozen", "eigenvalue_pairs", "finite_or_none", "freeze", "read_only"]


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


class Frozen:
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
