"""The stabilisable set as two semidefinite programs (cvxpy + Clarabel's SDP cone): the primal LMI
``L_K(X) < X`` with ``Y = K X`` and its alternative, the certificate LMI ``T_mu(P) >= 0``.

Derivation (docs/mathematics.md §2, "The stabilisable set"). With ``F = A X - B M Y`` and ``y_i`` the rows of
``Y = K X``, ``L_K(X) = F X^-1 F' + B diag(c_i y_i X^-1 y_i') B'``, ``c = mu (1 - mu)``. ``X - L_K(X) > 0``,
``X > 0`` holds iff, for some symmetric ``Z`` (m×m),

.. math:: \\begin{bmatrix} X - B\\,\\mathrm{Diag}(Z) B' & F \\\\ F' & X \\end{bmatrix} \\succ 0, \\qquad
   \\begin{bmatrix} Z & C Y \\\\ Y' C & X \\end{bmatrix} \\succeq 0, \\quad C = \\mathrm{diag}(\\sqrt{c}),

(Schur complements; ``Z >= C Y X^-1 Y' C`` gives ``Z_ii >= c_i y_i X^-1 y_i'``, and ``Z = C Y X^-1 Y' C`` is
allowed). Both are homogeneous, so the program maximises the margin ``t`` of the first block over
``tr X = 1``: ``t > 0`` iff mu is in S. Outside S the alternative ``max s : T_mu(P) >= s I, P >= 0, tr P = 1``
has ``s >= 0`` and its P is checked in numpy (`certificate_margin`).

Importing this module imports cvxpy: callers import it inside the function that needs it
(``optional.LAZY_MODULES``).
"""

from __future__ import annotations

import cvxpy as cp
import numpy as np

from ..qp.convex import solve_problem
from ..tolerances import CLARABEL_TIGHT

__all__ = ["LmiForm"]


class LmiForm:
    """The two programs for one plant ``(A, B)``, built once from Parameters (``B M`` and ``sqrt(c)``,
    ``c``) and re-solved for each mu. Time per solve: one Clarabel SDP with cones of size 2n and m + n
    (about O((n^2 + m n)^3) per interior-point step).

    Examples
    --------
    >>> form = LmiForm(np.array([[2.0]]), np.array([[1.0]]))   # scalar: S = {mu > 1 - 1/a^2 = 0.75}
    >>> t, K, status = form.stabilise(np.array([0.9]))
    >>> k = float(K[0, 0])   # its radius by hand: (a - mu k)^2 + mu (1 - mu) k^2
    >>> status, t > 0, (2.0 - 0.9 * k) ** 2 + 0.09 * k ** 2 < 1.0
    ('optimal', True, True)
    >>> s, P, status = form.certify(np.array([0.6]))
    >>> status, s >= -1e-9, bool(np.isclose(P[0, 0], 1.0))
    ('optimal', True, True)
    """

    def __init__(self, A: np.ndarray, B: np.ndarray) -> None:
        n, m = B.shape
        self.A, self.B = A, B
        self._BM = cp.Parameter((n, m), name="BM")
        self._root_c = cp.Parameter((m, m), name="sqrt_c")
        self._c = cp.Parameter(m, nonneg=True, name="c")

        X = cp.Variable((n, n), symmetric=True)
        Y = cp.Variable((m, n))
        Z = cp.Variable((m, m), symmetric=True)
        t = cp.Variable()
        F = A @ X - self._BM @ Y
        CY = self._root_c @ Y
        lyapunov = cp.bmat([[X - B @ cp.diag(cp.diag(Z)) @ B.T, F], [F.T, X]])
        spread = cp.bmat([[Z, CY], [CY.T, X]])
        self._X, self._Y, self._t = X, Y, t
        self._primal = cp.Problem(cp.Maximize(t), [
            0.5 * (lyapunov + lyapunov.T) >> t * np.eye(2 * n), 0.5 * (spread + spread.T) >> 0,
            cp.trace(X) == 1, t <= 1])

        P = cp.Variable((n, n), symmetric=True)
        s = cp.Variable()
        PBM = P @ self._BM
        BPB = B.T @ P @ B
        corner = self._BM.T @ PBM + cp.diag(cp.multiply(self._c, cp.diag(BPB)))
        T = cp.bmat([[A.T @ P @ A - P, -A.T @ PBM], [-(A.T @ PBM).T, corner]])
        self._P, self._s = P, s
        self._dual = cp.Problem(cp.Maximize(s), [0.5 * (T + T.T) >> s * np.eye(n + m), P >> 0, cp.trace(P) == 1,
                                                 s <= 1])

    def _set(self, mu: np.ndarray) -> None:
        c = mu * (1.0 - mu)
        self._BM.value = self.B * mu
        self._root_c.value = np.diag(np.sqrt(c))
        self._c.value = c

    def stabilise(self, mu: np.ndarray) -> tuple[float, np.ndarray | None, str]:
        """``(t, K, status)``: the largest margin ``t`` of ``X - L_K(X) >= t I`` over ``tr X = 1`` and the gain
        ``K = Y X^-1`` (None unless Clarabel reports optimal and X is invertible)."""
        self._set(mu)
        status = solve_problem(self._primal, "stabilising LMI", attempts=(CLARABEL_TIGHT,))
        if status != "optimal" or self._t.value is None:
            return float("nan"), None, status
        X, Y = self._X.value, self._Y.value
        try:
            K = np.linalg.solve(X.T, Y.T).T
        except np.linalg.LinAlgError:
            return float(self._t.value), None, status
        return float(self._t.value), K, status

    def certify(self, mu: np.ndarray) -> tuple[float, np.ndarray | None, str]:
        """``(s, P, status)``: the largest ``s`` with ``T_mu(P) >= s I``, ``P >= 0``, ``tr P = 1`` (s >= 0 outside
        S) and its P (None unless optimal)."""
        self._set(mu)
        status = solve_problem(self._dual, "infeasibility LMI", attempts=(CLARABEL_TIGHT,))
        if status != "optimal" or self._s.value is None:
            return float("nan"), None, status
        P = self._P.value
        return float(self._s.value), 0.5 * (P + P.T), status
