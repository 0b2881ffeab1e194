"""One channel at a time on the dense path, for searches that call J*(mu) thousands of times
in sequence (the allocation's bisections): vectors instead of stacks, and along a coordinate
line a Schur complement that factors the fixed channels once.

Both answer exactly what [`costs`][packetloss_cvx.lq.evaluator.CostEvaluator.costs] answers (to
rounding) or ``None`` when a check fails, and the caller then takes the checked batch path:

* the solve of ``G u = -Omega_gp x`` keeps a relative residual below ``DENSE_RESIDUAL_RTOL``,
  measured on the full (N m)×(N m) system;
* the cost ``C - x'Omega_gp' Vbar G^{-1} Omega_gp x`` agrees with the forward cost of its own
  plan (the mean state from Phi x and Gamma Vbar U, nonnegative stage costs summed) to
  ``SELF_CHECK_RTOL``, as [`closed_form`][packetloss_cvx.lq.costs.closed_form] requires.
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np
from scipy.linalg.lapack import dgesv as _gesv
from scipy.linalg.lapack import dgetrf as _getrf
from scipy.linalg.lapack import dgetrs as _getrs

from ..linalg import block_diagonal
from ..model.system import System
from ..tolerances import DENSE_RESIDUAL_RTOL
from .dense import dense_constant, hessian_diagonal, hessian_factor
from .policy import self_check
from .prediction import Prediction
from .recursion import forward_cost, input_weight
from .structure import structure_of

__all__ = ["OMEGA_DENSE_MAX", "PointEvaluator"]

#: The forward cost uses blkdiag(Omega_1..Omega_N) as one dense matrix up to this many entries.
OMEGA_DENSE_MAX = 2**20


class PointEvaluator:
    """J*(mu) of one protocol at the system's x0, one point at a time, on the dense path.

    Construction O((N m)^2) (cached vectors of ``pred``). `cost` O((N m)^3) (one LU);
    `line` O((N (m - 1))^3) once, then O(N^3 + (N m)^2) per point.
    """

    def __init__(self, system: System, protocol: str, pred: Prediction, weights: tuple[np.ndarray, float]) -> None:
        s, x = system, system.x0
        self.system, self.pred, self.protocol = s, pred, protocol
        self.structure = structure_of(s)
        self.d = weights[0]
        self.g = pred.Omega_gp @ x
        self.const = dense_constant(s, pred, x)
        self.base = float(x @ s.initial_weight @ x) + weights[1]
        self.Phi_x = pred.Phi @ x
        self.col2 = np.sum(pred.Omega_g ** 2, axis=0)
        self.Og_diag = np.diag(pred.Omega_g).copy()
        self.g_norm = float(np.linalg.norm(self.g))
        #: blkdiag(Omega_t) as one matrix while small (one matvec per forward cost), else per block
        self.Omega = block_diagonal(s.state_weights) if (s.horizon * s.n) ** 2 <= OMEGA_DENSE_MAX else None
        #: per channel i, the line's entries and blocks of Omega_g (:meth:`_blocks`), made on the first line along i
        self.blocks: dict[int, tuple[slice | np.ndarray, ...]] = {}

    def with_protocol(self, protocol: str) -> PointEvaluator:
        """The same system's evaluator for ``protocol`` ("tcp" or "udp", checked by the caller), sharing
        every vector (none depends on the protocol). O(1)."""
        other = copy.copy(self)
        other.protocol = protocol
        return other

    def _diag(self, v: np.ndarray) -> np.ndarray:
        return hessian_diagonal(self.pred, self.protocol, v)

    def cost(self, mu: np.ndarray, checked: bool = True) -> float | None:
        """J*(mu) for a schedule mu (N, m), or None where a check fails. O((N m)^3). ``checked=False``: the
        same value without the residual and the self-check (`_closed`), for callers that confirm
        with a checked call every value a decision rests on."""
        v = mu.ravel()
        G = hessian_factor(self.pred, self.protocol, v)
        with np.errstate(all="ignore"):      # one floating-point context for the solve and the value
            _, _, w, info = _gesv(G, self.g, overwrite_a=True)
            if info != 0:
                return None
            return self._checked(v, self._diag(v), w) if checked else self._closed(v, w)

    def _closed(self, v: np.ndarray, w: np.ndarray) -> float | None:
        """C - g'Vbar w for the solve's w, unchecked (None if not finite or negative); the caller holds
        ``np.errstate(all="ignore")``. O(N m)."""
        closed = self.const - float(self.g @ (v * w))
        return closed if closed >= 0 and closed != np.inf else None     # False for NaN

    def _checked(self, v: np.ndarray, dg: np.ndarray, w: np.ndarray) -> float | None:
        """The cost of the plan u = -w if the solve's residual and the self-check pass. O((N m)^2)."""
        s, pred = self.system, self.pred
        with np.errstate(all="ignore"):
            r = pred.Omega_g @ (v * w) + dg * w - self.g
            res = np.sqrt(r @ r)
            norm_G = np.sqrt(v @ (v * self.col2 + 2.0 * self.Og_diag * dg) + dg @ dg)
            scale = norm_G * np.sqrt(w @ w) + self.g_norm
            if not res <= DENSE_RESIDUAL_RTOL * scale:       # also False for NaN (w not finite)
                return None
            u = -w
            z = v * u
            closed = self.const - float(self.g @ (v * w))
            N, n, m = s.horizon, s.n, s.m
            X = (self.Phi_x + pred.Gamma @ z).reshape(1, N, n)
            mu, U = v.reshape(1, N, m), u.reshape(1, N, m)
            weight = input_weight(s, self.protocol, mu, self.d)
            forward = float(forward_cost(self.structure, mu, U, X, weight, self.base, self.Omega)[0])
            ok = bool(self_check(s, self.protocol, closed, forward, "dense", raise_=False))
        return closed if ok else None

    def line(self, mu: np.ndarray, i: int, checked: bool = True) -> Callable[[float], float | None] | None:
        """``s -> J*(mu with mu_i = s)`` for a stationary mu (m,): the other channels' block
        G_RR of G does not change along the line, so it is factored once and each point solves
        the N×N Schur complement ``s M + diag(psi_i + [UDP] Omega_d,i (1 - s))`` with
        ``M = Omega_g,ii - Omega_g,iR V_R G_RR^{-1} Omega_g,Ri``. None when m = 1 or G_RR is
        singular (use `cost`). Setup O((N (m - 1))^3 + N^2 N m), each point O(N^3 + (N m)^2).
        ``checked=False``: each point's value without its residual and self-check (as `cost`)."""
        s, pred = self.system, self.pred
        N, m = s.horizon, s.m
        if m == 1:
            return None
        on, off, Og_RR, Og_Ri, Og_iR, Og_ii = self._blocks(i)
        v = np.empty((N, m))             # mu at every step (np.tile: the same numbers at 5x the cost)
        v[:] = mu
        v = v.reshape(-1)
        vR = v[off]
        G_RR = hessian_factor(pred, self.protocol, v, off, Og_RR)                       # the fixed channels
        with np.errstate(all="ignore"):
            # LAPACK's LU (getrf/getrs, as scipy.linalg.lu_factor/lu_solve call them, without their wrappers: the
            # same floats); a singular G_RR leaves non-finite Y or y, refused below
            lu, piv, _ = _getrf(G_RR, overwrite_a=True)
            Y = _getrs(lu, piv, Og_Ri)[0]                                         # G_RR^{-1} Omega_g,Ri
            y = _getrs(lu, piv, self.g[off])[0]
            C = Og_iR * vR                                                        # G_iR
            M = Og_ii - C @ Y
            b = self.g[on] - C @ y
        if not (np.isfinite(Y).all() and np.isfinite(y).all() and np.isfinite(M).all()):
            return None
        def at(value: float) -> float | None:
            vs = v.copy()
            vs[on] = value
            dg = self._diag(vs)
            S = M * value
            S.flat[:: N + 1] += dg[on]
            with np.errstate(all="ignore"):
                _, _, w_i, info = _gesv(S, b, overwrite_a=True)
                if info != 0:
                    return None
                w = np.empty(N * m)
                w[on] = w_i
                w[off] = y - value * (Y @ w_i)
                return self._checked(vs, dg, w) if checked else self._closed(vs, w)

        return at

    def _blocks(self, i: int) -> tuple[slice | np.ndarray, ...]:
        """Channel i's line structure, made once per channel: its entries ``on`` (every m-th from i, a slice) and
        the others ``off`` (their indices, ascending) in the stacked (N m,) vectors, and the blocks
        Omega_g[off, off], [off, on], [on, off], [on, on] (copies: the same numbers the line indexed out of
        Omega_g at every call). A slice and an index array pick the same entries in the same order as the
        boolean masks they replace, at a third of the cost per point. O((N m)^2) the first time."""
        if i not in self.blocks:
            s, Og = self.system, self.pred.Omega_g
            size = s.horizon * s.m
            on = slice(i, size, s.m)
            off = np.flatnonzero(np.arange(size) % s.m != i)
            mine = np.arange(i, size, s.m)
            self.blocks[i] = (on, off, Og[np.ix_(off, off)], Og[np.ix_(off, mine)], Og[np.ix_(mine, off)],
                              Og[np.ix_(mine, mine)])
        return self.blocks[i]
