"""What every result type shares: read-only array copies, JSON-safe floats, eigenvalue order."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["eigenvalue_pairs", "finite_or_none", "freeze", "read_only"]


def read_only(value: Any) -> np.ndarray:
    """A read-only copy of ``value`` as an array."""
    arr = np.array(value)
    arr.setflags(write=False)
    return arr


def freeze(obj: Any) -> None:
    """Make every ndarray field of a frozen dataclass a read-only copy."""
    for name, value in vars(obj).items():
        if isinstance(value, np.ndarray):
            object.__setattr__(obj, name, read_only(value))


def finite_or_none(value: float | None) -> float | None:
    """``value`` as a float, or None when it is missing or not finite (JSON has no inf)."""
    return float(value) if value is not None and np.isfinite(value) else None


def eigenvalue_pairs(eigs: np.ndarray) -> list[list[float]]:
    """Complex eigenvalues as ``[[re, im], ...]`` sorted by descending modulus, then real part."""
    order = sorted(range(len(eigs)), key=lambda i: (-abs(eigs[i]), -eigs[i].real, -eigs[i].imag))
    return [[float(eigs[i].real), float(eigs[i].imag)] for i in order]
