"""Sinopoli's LMI for a bounded expected error covariance (Sinopoli et al. 2004, Theorem 5), one block per
arrival pattern of g sensor channels, in cvxpy + Clarabel's SDP cone.

An X > 0 with ``X > g(X)`` exists (`.bounds.stable_certificate`) iff, for some ``Y > 0`` and ``Z_a``
(n×p_a, one per pattern a with rows), ``Psi(Y, Z) > 0`` with first block row
``[Y, sqrt(p_a) (Y A + Z_a C_a) for each pattern a]`` (``Y A`` for the pattern with no rows) and ``Y`` on the
rest of the diagonal (Schur complement: ``Y > sum_a p_a (A + Y^-1 Z_a C_a)' Y (A + Y^-1 Z_a C_a)``, the
Lyapunov inequality of the filter with gains ``-Y^-1 Z_a`` in the information form ``Y = X^-1``). The program
maximises the margin t of ``Psi >= t I`` over ``tr Y = n`` (homogeneous): t > 0 iff the rate is certified. Cross-checked
against the certificate's bisection in the tests.

Importing this module imports cvxpy (``optional.LAZY_MODULES``).
"""

from __future__ import annotations

import cvxpy as cp
import numpy as np

from ..model.sensor import Sensor
from ..qp.convex import solve_problem
from ..tolerances import CLARABEL_TIGHT
from .arrivals import arrival_patterns
from .kalman import pattern_rows

__all__ = ["FilterLmi"]


class FilterLmi:
    """The program for one plant A and sensor, built once (the patterns' ``sqrt(p_a)`` are Parameters) and
    re-solved for each gamma. One Clarabel SDP with a cone of size ``(1 + 2^g) n``.

    Examples
    --------
    >>> lmi = FilterLmi(np.array([[2.0]]), Sensor(C=[[1.0]], gamma=[0.5]))   # scalar: gamma_c = 1 - 1/4
    >>> lmi.margin(np.array([0.8]))[0] > 0, lmi.margin(np.array([0.7]))[0] > 0
    (True, False)
    """

    def __init__(self, A: np.ndarray, sensor: Sensor) -> None:
        n = A.shape[0]
        self.sensor = sensor
        arrived, _ = arrival_patterns(sensor.gamma)
        self._root = cp.Parameter(len(arrived), nonneg=True, name="sqrt_p")
        Y = cp.Variable((n, n), symmetric=True)
        t = cp.Variable()
        row = [Y]
        for k, a in enumerate(arrived):
            rows = pattern_rows(sensor, a)
            block = Y @ A
            if rows.size:
                block = block + cp.Variable((n, rows.size)) @ sensor.C[rows]
            row.append(self._root[k] * block)
        size = len(row)
        blocks = [row] + [[row[j].T if i == 0 else (Y if i == j else np.zeros((n, n))) for i in range(size)]
                          for j in range(1, size)]
        Psi = cp.bmat(blocks)
        self._t = t
        self._problem = cp.Problem(cp.Maximize(t), [0.5 * (Psi + Psi.T) >> t * np.eye(size * n),
                                                    cp.trace(Y) == n, t <= 1])

    def margin(self, gamma: np.ndarray) -> tuple[float, str]:
        """``(t, status)``: the largest margin of ``Psi >= t I`` over ``tr Y = n`` at ``gamma`` (nan unless optimal)."""
        _, prob = arrival_patterns(np.asarray(gamma, dtype=float))
        self._root.value = np.sqrt(prob)
        status = solve_problem(self._problem, "filter LMI", attempts=(CLARABEL_TIGHT,))
        if status != "optimal" or self._t.value is None:
            return float("nan"), status
        return float(self._t.value), status
