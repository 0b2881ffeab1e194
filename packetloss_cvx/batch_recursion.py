"""The backward Riccati recursion of :mod:`~packetloss_cvx.recursion` for a batch of P channels at once,
and the rollout of the plans it gives: N steps of stacked small-matrix operations, no loop over the
points. Used by :class:`~packetloss_cvx.evaluator.CostEvaluator`, which checks every point's cost
against the forward cost of its plan.

A point's answers do not depend on the batch it is in (below 64 points: per-matrix products and
solves, and a batch-independent order for x'(Q + P_0)x), so a caller may read a point back instead of
evaluating it again (the brute-force allocator does).
"""

from __future__ import annotations

import numpy as np

from .errors import NumericalError
from .model import System

__all__ = ["FLAT_MIN", "backward_batch", "overflow_error", "rollout_batch"]

#: From this many points on, each step's products are one (P k)×k by k×l product instead of P small ones.
FLAT_MIN = 64


def overflow_error(name: str, protocol: str) -> NumericalError:
    """The error of an exact cost beyond the double range (an unstable plant over a long horizon). O(1).

    Examples
    --------
    >>> str(overflow_error("the cost-to-go matrix", "tcp")).split(" (")[0]
    'the cost-to-go matrix overflowed'
    """
    return NumericalError(f"{name} overflowed (the exact {protocol}-like expected cost exceeds the double-precision "
                          "range, 1e308: the open-loop prediction of an unstable plant over this horizon); shorten "
                          "the horizon or stabilise the plant")


def backward_batch(system: System, protocol: str, mu: np.ndarray, added: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gains K (P, N, m, n) and cost-to-go P_0 (P, n, n) (without Q) of the schedules ``mu`` (P, N, m),
    ``added`` (P, N, m) the diagonal each step's G gets (psi, plus (1 - mu) d for the UDP-like law).
    Per step ``G = B'PB diag(mu_t) + diag(added_t)``, ``K_t = G^{-1} B'PA``,
    ``P <- A'PA - (B'PA)' diag(mu_t) K_t + Omega_t``, symmetrised. O(P N (n^3 + m^3)); NumericalError
    (:func:`overflow_error`) where a step's G is singular or anything overflows.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> K, P0 = backward_batch(s, "tcp", np.array([[[1.0]]]), np.array([[[1.0]]]))   # K = 1/2, P0 = 1/2
    >>> K.ravel().tolist(), P0.ravel().tolist()
    ([0.5], [0.5])
    """
    A, B, W, N, n, m = system.A, system.B, system.state_weights, system.horizon, system.n, system.m
    P = mu.shape[0]
    diagonal = np.zeros((N, P, m, m))                                      # step-major: one view a step
    diagonal.reshape(N, P, m * m)[:, :, :: m + 1] = added.transpose(1, 0, 2)
    rows = list(mu.transpose(1, 0, 2)[:, :, None, :])                      # N of (P, 1, m): mu_t as a row
    K = np.empty((N, P, m, n))
    Pm = np.empty((P, n, n))
    Pm[:] = W[N - 1]
    BA = np.hstack([B, A])
    BAT = BA.T
    solve, matmul = np.linalg.solve, np.matmul
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(N - 1, -1, -1):
            row = rows[t]
            if P >= FLAT_MIN:
                PBT = (Pm.reshape(P * n, n) @ B).reshape(P, n, m).transpose(0, 2, 1).reshape(P * m, n)
                G = np.multiply((PBT @ B).reshape(P, m, m).transpose(0, 2, 1), row, order="C")  # B'PB
                rhs = (PBT @ A).reshape(P, m, n)
                APA = (Pm.reshape(P * n, n) @ A).reshape(P, n, n).transpose(0, 2, 1).reshape(P * n, n) @ A
                APA = APA.reshape(P, n, n).transpose(0, 2, 1)                       # A'(P A)
            else:              # a small batch: few calls, [B A]' P [B A] in two products
                H = matmul(BAT, matmul(Pm, BA))
                G = H[:, :m, :m] * row
                rhs = H[:, :m, m:]
                APA = H[:, m:, m:]
            G += diagonal[t]                                       # off the diagonal, + 0.0 changes nothing
            try:
                Kt = K[t] = solve(G, rhs)
            except np.linalg.LinAlgError:
                raise overflow_error("the cost-to-go matrix", protocol) from None
            Pm = APA - matmul(rhs.transpose(0, 2, 1) * row, Kt)
            if t > 0:
                Pm += W[t - 1]
            Pm += Pm.transpose(0, 2, 1)                            # numpy buffers the overlap
            Pm *= 0.5
    K = K.transpose(1, 0, 2, 3)
    if not (np.all(np.isfinite(Pm)) and np.all(np.isfinite(K))):
        raise overflow_error("the cost-to-go matrix", protocol)
    return K, Pm


def rollout_batch(system: System, mu: np.ndarray, K: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The plans u_t = -K_t x_t (P, N, m) and their mean states x_1..x_N (P, N, n) from x (P, n):
    ``x_{t+1} = (A - B diag(mu_t) K_t) x_t``, one stacked product a step. O(P N n^2 (n + m)).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[1.0], x0=[1.0])
    >>> U, X = rollout_batch(s, np.full((1, 2, 1), 0.5), np.full((1, 2, 1, 1), 0.5), np.array([[2.0]]))
    >>> U.ravel().tolist(), X.ravel().tolist()     # x1 = (1 - 0.25) 2, x2 = 0.75 x1
    ([-1.0, -0.75], [1.5, 1.125])
    """
    A, B, N, n = system.A, system.B, system.horizon, system.n
    P = mu.shape[0]
    with np.errstate(over="ignore", invalid="ignore"):
        loop = A - np.matmul(B * mu[:, :, None, :], K)                     # (P, N, n, n)
        xs = np.empty((P, N + 1, n, 1))
        xs[:, 0, :, 0] = x
        for t in range(N):
            np.matmul(loop[:, t], xs[:, t], out=xs[:, t + 1])
        U = -np.matmul(K, xs[:, :N])[..., 0]
    return U, xs[:, 1:, :, 0]
