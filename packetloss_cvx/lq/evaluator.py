"""J*(mu) for many channels at once: everything that does not depend on mu is built once.

For a fixed system (A, B, weights, horizon, x0, noise) and protocol,
[`CostEvaluator`][packetloss_cvx.lq.evaluator.CostEvaluator]
evaluates the optimal expected cost of Theorem 1 (eq:TCP-opt-cost, eq:UDP-opt-cost, corrected:
``C - x'Omega_gp' Vbar G^{-1} Omega_gp x``) for a batch of channels, stationary ``(points, m)`` or
scheduled ``(points, N, m)``, with no Python loop over the points: stacked small matrices go through
``np.matmul`` and ``np.linalg.solve``.

It allows the paths [`closed_form`][packetloss_cvx.lq.costs.closed_form] allows with ``method="auto"``, a
choice that does not depend on mu (N m and the condition estimate, built from the Lyapunov sums
of `udp_variance_weights`, are fixed); where the dense path is
allowed, a large batch still takes the recursion when that is faster (both are exact):

* ``"dense"`` (N m <= ``costs.AUTO_DENSE_MAX``, well conditioned): Omega_g, Omega_gp, Phi, Gamma
  built once (O((N n)^2 N m)); per point one (N m)×(N m) LU solve, O((N m)^3);
* ``"recursion"``: the backward Riccati recursion of [`recursion`][packetloss_cvx.lq.recursion] over a
  batch, O(N (n^3 + m^3)) per point in N steps of stacked operations.

Never silently wrong, as ``closed_form``: every point's cost is checked against the forward cost
of its own plan (a sum of nonnegative stage costs, ``SELF_CHECK_RTOL``), vectorised; a dense
point whose solve residual or self-check fails is recomputed by the recursion (as ``"auto"``
falls back); a recursion point that fails raises [`NumericalError`][packetloss_cvx.errors.NumericalError] naming the
weights' spread, and so does any cost beyond the double range. Memory: both paths work in chunks of
about ``CHUNK_BYTES`` (the dense path's stacked matrices; the recursion's gains, O(N m n) a point).
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ..errors import DimensionError, InputError, NumericalError, ProbabilityError
from ..linalg import block_diagonal
from ..model.protocols import check_protocol
from ..model.system import System, check_system, numeric_array
from ..model.validation import MAX_ENTRIES, channel_range
from ..results import BatchSolution, Solution
from ..threads import blas_limited
from ..tolerances import DENSE_RESIDUAL_RTOL, SELF_CHECK_ATOL, SELF_CHECK_RTOL
from .dense import dense_constant, hessian_diagonal, hessian_factor
from .pointwise import PointEvaluator
from .policy import choose, refuse_correlated, self_check, weight_spread
from .prediction import prediction
from .recursion import backward_batch, forward_cost, input_weight, overflow_error, rollout_batch
from .structure import structure_of

__all__ = ["CHUNK_BYTES", "CostEvaluator"]

#: The dense path stacks at most this many bytes of (N m)×(N m) matrices at a time, and the
#: recursion about this many bytes of gains, inputs and states.
CHUNK_BYTES = 2**25
#: The forward cost multiplies the mean states by blkdiag(Omega_1..Omega_N) as one matrix up to
#: N n = this (a (points, N n) by (N n)×(N n) product is faster than N small ones), else block by block.
OMEGA_BLOCKS_MAX = 64


class CostEvaluator:
    """Optimal expected costs J*(mu) of one system and protocol for many channels.

    Parameters
    ----------
    system : System
        Fixes A, B, the weights, the horizon, x0 and the noise; its own mu is ignored.
    protocol : {"tcp", "udp"}
    method : {"auto", "dense", "recursion"}
        As for [`closed_form`][packetloss_cvx.lq.costs.closed_form]; ``"auto"`` (default) picks once.

    Notes
    -----
    Construction: O(N n^3) (Lyapunov sums), plus O((N n)^2 N m) for the dense path.
    Per point: O((N m)^3) dense or O(N (n^3 + m^3)) recursion, the self-check O(N n (n + m))
    or O(N N m n) included. Costs equal ``closed_form(system.with_mu(mu), protocol).cost`` to
    rounding (about 1e-15 relative; tests: 1e-12).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0],
    ...            input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> ev = CostEvaluator(s, "tcp")
    >>> # min (1 + mu u)^2 + mu u^2: 0.5 at mu = 1, 1 at mu = 0
    >>> bool(np.allclose(ev.costs([[1.0], [0.0]]), [0.5, 1.0]))
    True
    """

    def __init__(self, system: System, protocol: str, method: str = "auto") -> None:
        self.system = check_system(system)
        self.protocol = check_protocol(protocol)
        s = self.system
        #: what does not depend on mu, built once per system structure: the kernels' first argument
        self.structure = structure_of(s)
        self.weights = self.structure.variance_weights
        self._d, self._noise = self.weights
        self._d_finite = bool(np.all(np.isfinite(self._d)))
        with np.errstate(over="ignore", invalid="ignore"):
            self._base = float(s.x0 @ s.initial_weight @ s.x0) + self._noise      # x0'Q x0 + noise
        #: blkdiag(Omega_1..Omega_N) while small: the forward cost's state terms in one product
        Nn = s.horizon * s.n
        self._Omega = None
        if Nn <= OMEGA_BLOCKS_MAX:
            self._Omega = block_diagonal(s.state_weights)
        self.requested = method
        # the one chooser and fallback closed_form takes (InputError on an unknown method)
        self.method, self._pred = choose(s, method, self.weights, lambda: prediction(s))
        self._point = None if self._pred is None else PointEvaluator(s, self.protocol, self._pred, self.weights)
        self._optimum: Solution | None = None

    def with_protocol(self, protocol: str) -> CostEvaluator:
        """The same system's evaluator for ``protocol``, sharing everything built (the Lyapunov sums,
        the prediction matrices, the method's choice: none depends on the protocol); answers equal to a
        fresh ``CostEvaluator(system, protocol, method)``'s bit for bit. O(1).

        Examples
        --------
        >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0],
        ...            input_weight=[1.0], mu=[0.5], x0=[1.0])
        >>> udp = CostEvaluator(s, "tcp").with_protocol("udp")   # J*_udp = 1 - mu/2
        >>> udp.protocol, udp.cost(np.array([0.5]))
        ('udp', 0.75)
        """
        other = copy.copy(self)
        other.protocol = check_protocol(protocol)
        other._optimum = None
        other._point = None if self._point is None else self._point.with_protocol(other.protocol)
        return other

    # ------------------------------------------------------------------ inputs
    def _schedules(self, mus: npt.ArrayLike) -> np.ndarray:
        """(points, N, m) schedules from (points, m) or (points, N, m); ProbabilityError / DimensionError."""
        s = self.system
        if (isinstance(mus, np.ndarray) and mus.dtype == np.float64 and 0 < mus.size <= MAX_ENTRIES
                and mus.shape[1:] in ((s.m,), (s.horizon, s.m)) and 0.0 <= mus.min() and mus.max() <= 1.0):
            # already a float array of probabilities (NaN fails the comparisons): no copy, no walk
            return np.broadcast_to(mus[:, None, :], (mus.shape[0], s.horizon, s.m)) if mus.ndim == 2 else mus
        arr = numeric_array(mus, "mu")
        if arr.ndim == 2 and arr.shape[1] == s.m:
            arr = np.broadcast_to(arr[:, None, :], (arr.shape[0], s.horizon, s.m))
        elif arr.ndim != 3 or arr.shape[1:] != (s.horizon, s.m):
            raise DimensionError("mu", f"expected shape (points, {s.m}) or (points, {s.horizon}, {s.m}), "
                                       f"found {arr.shape}")
        if np.any(arr < 0.0) or np.any(arr > 1.0):
            bad = arr[(arr < 0.0) | (arr > 1.0)].flat[0]
            raise ProbabilityError("mu", f"expected probabilities in [0, 1], found {bad}")
        return arr

    def _initial_states(self, x0: npt.ArrayLike | None, points: int) -> np.ndarray:
        """(points, n) initial states: the system's, one shared (n,), or one per point (points, n)."""
        n = self.system.n
        if x0 is None:
            return np.broadcast_to(self.system.x0, (points, n))
        arr = numeric_array(x0, "x0")
        if arr.shape == (n,):
            return np.broadcast_to(arr, (points, n))
        if arr.shape != (points, n):
            raise DimensionError("x0", f"expected shape ({n},) or ({points}, {n}), found {arr.shape}")
        return arr

    # ------------------------------------------------------------------ public
    @blas_limited
    def cost(self, mu: npt.ArrayLike, x0: npt.ArrayLike | None = None, checked: bool = True) -> float:
        """J*(mu) for one channel: mu of shape (m,) or (N, m), x0 (n,) or None (the system's).

        On the dense path at the system's x0, vectors instead of stacks
        (`PointEvaluator`: one LU, checked the same way, equal to
        [`costs`][packetloss_cvx.lq.evaluator.CostEvaluator.costs] to rounding); otherwise, or where its check fails, a
        batch of one.

        ``checked=False`` (searches only: the allocation's probes) skips the one-point path's residual and
        self-check, O((N m)^2) of an O((N m)^3) point: the value is the same as the checked one wherever the
        check passes, and unchecked where it would fail. A caller must confirm with a checked call every
        value that a decision its certificate depends on rests on.
        """
        s = self.system
        if (x0 is None and self._point is not None and type(mu) is np.ndarray and mu.dtype == np.float64
                and (_channel_vector(mu, s.m) or (mu.shape == (s.horizon, s.m)
                                                  and 0.0 <= mu.min() and mu.max() <= 1.0))):
            # NaN fails the comparisons: validated below
            schedule = mu
            if mu.ndim == 1:            # the stationary schedule (N, m): a filled array (np.tile costs 3x more)
                schedule = np.empty((s.horizon, s.m))
                schedule[:] = mu
            value = self._point.cost(schedule, checked)   # vectors, not stacks
            if value is not None:
                return value
        one = numeric_array(mu, "mu")
        if x0 is None and self._point is not None and one.shape in ((s.m,), (s.horizon, s.m)):
            value = self._point.cost(self._schedules(one[None])[0])
            if value is not None:
                return value
        return float(self.costs(one[None], None if x0 is None else numeric_array(x0, "x0")[None])[0])

    def line(self, mu: npt.ArrayLike, i: int, checked: bool = True) -> Callable[[float], float]:
        """``s -> J*(mu with mu_i = s)`` for a stationary mu (m,) and s in [0, 1], at the system's x0.

        On the dense path the other channels are factored once (a Schur complement,
        `PointEvaluator.line`): per point O(N^3 + (N m)^2) instead of O((N m)^3); every
        point is checked as [`cost`][packetloss_cvx.lq.evaluator.CostEvaluator.cost] checks it and falls back to
        [`cost`][packetloss_cvx.lq.evaluator.CostEvaluator.cost] on a failed check. ``checked=False``: the points'
        values without the check, with the contract of [`cost`][packetloss_cvx.lq.evaluator.CostEvaluator.cost]'s.
        """
        if type(mu) is np.ndarray and mu.dtype == np.float64 and _channel_vector(mu, self.system.m):
            base = mu.copy()            # already a channel vector (a search's line): nothing to convert
        else:
            base = self._schedules(numeric_array(mu, "mu")[None])[0, 0].copy()
        if not (isinstance(i, (int, np.integer)) and 0 <= i < self.system.m):
            raise InputError("i", f"expected {channel_range(self.system.m)}, found {i!r}")
        fast = None if self._point is None else self._point.line(base, int(i), checked)

        def at(value: float) -> float:
            if fast is not None and 0.0 <= value <= 1.0:
                got = fast(float(value))
                if got is not None:
                    return got
            point = base.copy()
            point[i] = value
            return self.cost(point, checked=checked)

        return at

    @blas_limited
    def costs(self, mus: npt.ArrayLike, x0: npt.ArrayLike | None = None) -> np.ndarray:
        """J*(mu) for each channel of the batch, shape (points,). ``x0``: (n,) or (points, n) to override the
        system's initial state (the costs are quadratic in it). See the class notes for time."""
        return self._run(mus, x0, gains=False)[0]

    @blas_limited
    def solve(self, mus: npt.ArrayLike, x0: npt.ArrayLike | None = None) -> BatchSolution:
        """Costs (points,), optimal inputs U* (points, N, m) and the first step's gains K (points, m, n).

        The gains cost n more right-hand sides per dense solve; the recursion has them anyway.
        """
        costs, inputs, gains, method = self._run(mus, x0, gains=True)
        return BatchSolution(protocol=self.protocol, costs=costs, inputs=inputs, gains=gains, method=method)

    def optimum(self) -> Solution:
        """The optimal plan at the system's own channel (its mu schedule): cost, inputs U* and the first
        step's gain K, equal to ``closed_form(system, protocol)``'s to rounding, without the closed-loop
        eigenvalues (None: nobody asked); computed on the first call, the same frozen object after. A
        Gilbert–Elliott channel's UDP-like cost is refused as closed_form refuses it.
        O((N m)^3) or O(N (n^3 + m^3)) the first time, O(1) after.

        Examples
        --------
        >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0],
        ...            input_weight=[1.0], mu=[1.0], x0=[1.0])
        >>> sol = CostEvaluator(s, "tcp").optimum()      # min (1 + u)^2 + u^2 at u = -1/2, K = 1/2
        >>> bool(np.allclose([sol.cost, sol.inputs[0, 0], sol.gain[0, 0]], [0.5, -0.5, 0.5]))
        True
        """
        if self._optimum is None:
            refuse_correlated(self.system, self.protocol)
            sol = self.solve(self.system.mu_schedule[None])
            self._optimum = Solution(protocol=self.protocol, cost=float(sol.costs[0]), inputs=sol.inputs[0],
                                     gain=sol.gains[0], closed_loop_eigenvalues=None, method=sol.method)
        return self._optimum

    # ------------------------------------------------------------------ paths
    def _run(self, mus, x0, gains: bool):
        mu = self._schedules(mus)
        points = mu.shape[0]
        x = self._initial_states(x0, points)
        base = self._base if x0 is None else None       # x0'Q x0 + noise of the forward costs
        s = self.system
        costs = np.empty(points)
        inputs = np.empty((points, s.horizon, s.m))
        K0 = np.empty((points, s.m, s.n)) if gains else None
        method = self.method
        todo = np.arange(points)
        if self.method == "dense" and self.requested == "auto" and not self._dense_is_faster(points):
            method = "recursion"
        if self.method == "dense" and points and (self.requested == "dense" or self._dense_is_faster(points)):
            k = s.horizon * s.m
            chunk = max(1, CHUNK_BYTES // (8 * k * k))
            failed = []
            for start in range(0, points, chunk):
                idx = np.arange(start, min(points, start + chunk))
                ok = self._dense(mu[idx], x[idx], idx, costs, inputs, K0, base)
                failed.append(idx[~ok])
            todo = np.concatenate(failed)
            if todo.size:
                if self.requested == "dense":
                    raise NumericalError(
                        f"method 'dense': {todo.size} of {points} points failed the dense solve's residual or the "
                        f"self-check against the forward cost of their plans ({weight_spread(s)}); "
                        "use method='recursion'")
                method = "mixed"
        # the recursion keeps gains, inputs and states per point: O(N (m n + m + n)) doubles each
        chunk = max(1, CHUNK_BYTES // (8 * s.horizon * (s.m * s.n + s.m + s.n + s.m)))
        for start in range(0, todo.size, chunk):
            part = todo[start:start + chunk]
            self._recursion(mu[part], x[part], part, costs, inputs, K0, base)
        return costs, inputs, K0, method

    def _dense_is_faster(self, points: int) -> bool:
        """Whether ``points`` dense solves beat one batched recursion, by a cost model fitted on this machine
        (docs/performance.md, "Batched evaluation"): dense 1.2e-4 + points (5e-6 + 9e-11 (N m)^3) s,
        recursion N (3e-5 + 1e-6 points) s. Both paths are exact; this only picks the faster. O(1)."""
        N, k = self.system.horizon, self.system.horizon * self.system.m
        return 1.2e-4 + points * (5e-6 + 9e-11 * k**3) <= N * (3e-5 + 1e-6 * points)

    def _forward(self, mu: np.ndarray, x: np.ndarray, U: np.ndarray, X: np.ndarray,
                 weight: np.ndarray | None = None, base: np.ndarray | float | None = None) -> np.ndarray:
        """The referee (`forward_cost`) of plans U (points, N, m) whose mean states
        X (points, N, n) are x_1..x_N; ``weight``: `input_weight` if the caller has
        it; ``base``: x0'Q x0 + noise, if known. O(points N (n^2 + m)), O(points (N n)^2) up to OMEGA_BLOCKS_MAX."""
        s = self.system
        if weight is None:
            weight = input_weight(s, self.protocol, mu, self._d)
        if base is None:
            with np.errstate(over="ignore", invalid="ignore"):
                base = np.einsum("pi,ij,pj->p", x, s.initial_weight, x) + self._noise
        return forward_cost(self.structure, mu, U, X, weight, base, self._Omega)

    def _dense(self, mu, x, idx, costs, inputs, K0, base=None) -> np.ndarray:
        """Theorem 1's dense law for a chunk; returns which points passed their checks."""
        s, pred = self.system, self._pred
        N, n, m = s.horizon, s.n, s.m
        points = mu.shape[0]
        v = mu.reshape(points, N * m)
        G = hessian_factor(pred, self.protocol, v)
        diag = hessian_diagonal(pred, self.protocol, v)
        g = x @ pred.Omega_gp.T                                          # (points, N m)
        rhs = np.broadcast_to(pred.Omega_gp, (points, N * m, n)) if K0 is not None else g[:, :, None]
        ok = np.ones(points, dtype=bool)
        with np.errstate(all="ignore"):
            try:
                F = np.linalg.solve(G, rhs)
            except np.linalg.LinAlgError:
                return np.zeros(points, dtype=bool)
            # G F = Omega_g (v F) + diag F: one (points r)×k by k×k product, not points stacked ones; and
            # ||G||_F^2 = sum_j v_j^2 |Omega_g e_j|^2 + 2 v_j Omega_g,jj diag_j + diag_j^2 (no cancellation:
            # every term >= 0), O(N m) a point instead of O((N m)^2)
            r = F.shape[2]
            OgVF = ((v[:, :, None] * F).transpose(0, 2, 1).reshape(points * r, N * m) @ pred.Omega_g.T)
            GF = OgVF.reshape(points, r, N * m).transpose(0, 2, 1) + np.reshape(diag, (-1, N * m))[:, :, None] * F
            res = np.linalg.norm((GF - rhs).reshape(points, -1), axis=1)
            Og = pred.Omega_g
            G_norm = np.sqrt(np.sum(v * v * np.sum(Og * Og, axis=0) + (2.0 * v * np.diag(Og) + diag) * diag, axis=1))
            scale = (G_norm * np.linalg.norm(F.reshape(points, -1), axis=1)
                     + np.linalg.norm(rhs.reshape(points, -1), axis=1))
            ok &= np.all(np.isfinite(F.reshape(points, -1)), axis=1) & np.isfinite(res)
            ok &= res <= DENSE_RESIDUAL_RTOL * scale
            u = -np.einsum("pkj,pj->pk", F, x) if K0 is not None else -F[:, :, 0]
            const = dense_constant(s, pred, x)
            closed = const + np.einsum("pk,pk->p", g, v * u)
            X = (x @ pred.Phi.T + (v * u) @ pred.Gamma.T).reshape(points, N, n)
            U = u.reshape(points, N, m)
            forward = self._forward(mu, x, U, X, base=base)
        ok &= self_check(s, self.protocol, closed, forward, "dense", raise_=False)
        costs[idx[ok]] = closed[ok]
        inputs[idx[ok]] = U[ok]
        if K0 is not None:
            K0[idx[ok]] = F[ok, :m, :]
        return ok

    def _recursion(self, mu, x, idx, costs, inputs, K0, base=None) -> None:
        """The backward Riccati recursion (recursion.backward_pass) over a batch, then the rollout."""
        s = self.system
        points = mu.shape[0]
        if self.protocol == "udp" and not self._d_finite and not np.all(np.isfinite(self._d[np.any(mu < 1.0, axis=0)])):
            raise overflow_error("diag(Omega_g)", self.protocol)
        added = input_weight(s, self.protocol, mu, self._d)                   # (points, N, m)
        K, Pm = backward_batch(self.structure, self.protocol, mu, added)
        if not np.isfinite(self._noise):
            raise overflow_error("the cost-to-go matrix", self.protocol)
        with np.errstate(over="ignore", invalid="ignore"):
            # x'(Q + P_0)x in an order that does not depend on the batch (einsum's three-operand form
            # reduces a batch of one n = 2 point in another order): a point's cost is a function of the point
            closed = np.einsum("pj,pj->p", np.matmul(x[:, None, :], s.initial_weight + Pm)[:, 0, :], x) + self._noise
        U, X = rollout_batch(self.structure, mu, K, x)
        forward = self._forward(mu, x, U, X, added, base)
        atol = np.zeros(points)
        rough = np.abs(closed - forward) > SELF_CHECK_RTOL * forward
        if np.any(rough):      # the rounding scale of x'P_0 x, only where the relative test alone fails
            atol[rough] = SELF_CHECK_ATOL * np.linalg.norm(Pm[rough], 2, axis=(1, 2)) * np.sum(x[rough] ** 2, axis=1)
        self_check(s, self.protocol, closed, forward, "recursion", atol)
        costs[idx] = closed
        inputs[idx] = U
        if K0 is not None:
            K0[idx] = K[:, 0]


def _channel_vector(mu: np.ndarray, m: int) -> bool:
    """Whether a plain float array ``mu`` (an ``np.ndarray`` itself: a masked array's ``tolist`` gives None for
    its masked entries, and `numeric_array` refuses those) is one channel vector, shape (m,)
    with every entry in [0, 1] (NaN fails the comparisons): its m entries compared as Python floats, several times
    cheaper than two NumPy reductions at this size (the searches' probes and lines, thousands per allocation). O(m)."""
    return mu.shape == (m,) and all(0.0 <= p <= 1.0 for p in mu.tolist())

