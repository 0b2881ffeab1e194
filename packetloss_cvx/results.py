"""Frozen result objects with ``to_dict()`` for JSON."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["CrossCheck", "Solution", "eigenvalue_pairs"]


def eigenvalue_pairs(eigs: np.ndarray) -> list[list[float]]:
    """Complex eigenvalues as ``[[re, im], ...]`` sorted by descending modulus, then real part."""
    order = sorted(range(len(eigs)), key=lambda i: (-abs(eigs[i]), -eigs[i].real, -eigs[i].imag))
    return [[float(eigs[i].real), float(eigs[i].imag)] for i in order]


@dataclass(frozen=True)
class CrossCheck:
    """Agreement of a solver answer with the closed form.

    ``max_input_diff`` is max |U_qp - U*| over the entries whose channel has mu > 0
    (an input sent over a channel that never delivers does not enter the cost, so
    any value is optimal); ``cost_rel_diff`` is |J_qp - J*| / max(1, |J*|).
    """

    reference_method: str
    max_input_diff: float
    cost_rel_diff: float

    def to_dict(self) -> dict[str, Any]:
        return {"max_input_diff": self.max_input_diff, "cost_rel_diff": self.cost_rel_diff}


@dataclass(frozen=True)
class Solution:
    """The optimal open-loop plan for one protocol.

    Attributes
    ----------
    protocol : {"tcp", "udp"}
    cost : float
        Optimal expected cost J*, constant and noise terms included.
    inputs : ndarray, shape (N, m)
        Commanded inputs U* (row t is U_{k+t}).
    gain : ndarray, shape (m, n), or None
        Receding-horizon gain K: U_k = -K X_k (None when a QP was solved without it).
    closed_loop_eigenvalues : ndarray, complex, shape (n,)
        Eigenvalues of A - B K (the paper's Tables I–II convention).
    method : str
        "dense", "recursion", "qp-condensed" or "qp-sparse".
    status, solve_time : solver status and seconds (QPs only).
    cross_check : CrossCheck or None
        For QPs, the comparison with the closed form.
    """

    protocol: str
    cost: float
    inputs: np.ndarray
    gain: np.ndarray | None
    closed_loop_eigenvalues: np.ndarray | None
    method: str
    status: str | None = None
    solve_time: float | None = None
    cross_check: CrossCheck | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "cost": self.cost,
            "inputs": self.inputs.tolist(),
            "gain": None if self.gain is None else self.gain.tolist(),
            "closed_loop_eigenvalues": (
                None if self.closed_loop_eigenvalues is None
                else eigenvalue_pairs(self.closed_loop_eigenvalues)
            ),
            "method": self.method,
        }
        if self.status is not None:
            out["status"] = self.status
            out["solve_time"] = self.solve_time
        if self.cross_check is not None:
            out.update(self.cross_check.to_dict())
        return out
