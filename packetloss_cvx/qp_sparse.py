"""The sparse QP's data and the QP twin's memory estimate (re-exported by :mod:`.qp`).

The sparse form of :class:`~packetloss_cvx.qp.ExpectedCostQP` keeps the mean states as variables with the
dynamics as equality constraints: :func:`sparse_dynamics` builds its block-sparse constants, O(N (n^2 + n m))
nonzeros; :func:`qp_memory_estimate` bounds either form's peak memory before anything is built.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .linalg import psd_factor
from .model import System

__all__ = ["qp_memory_estimate", "sparse_dynamics"]


def sparse_dynamics(system: System) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]:
    """Block-sparse mean-state dynamics and state-weight factor for X = (xhat_1..xhat_N):
    ``E X - Bbig z = first x0`` encodes ``xhat_{t+1} = A xhat_t + B z_t``, and
    ``||L X||^2 = sum_t xhat_t' Omega_t xhat_t``. O(N (n^2 + n m)) nonzeros.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=2, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> E, Bbig, first, L = sparse_dynamics(s)          # z = (1, 2): xhat_1 = 1 + 1, xhat_2 = 2 + 2
    >>> np.linalg.solve(E.toarray(), Bbig @ [1.0, 2.0] + first @ s.x0).tolist()
    [2.0, 4.0]
    """
    N, n = system.horizon, system.n
    E = sp.eye(N * n, format="csr") - sp.kron(sp.eye(N, k=-1), system.A, format="csr")
    Bbig = sp.kron(sp.eye(N), system.B, format="csr")
    first = sp.csr_matrix(np.vstack([system.A, np.zeros(((N - 1) * n, n))]))
    L = sp.block_diag([psd_factor(W) for W in system.state_weights], format="csr")
    return E, Bbig, first, L


def qp_memory_estimate(system: System, formulation: str) -> float:
    """Bytes the QP needs at its peak, known before building it: linear in N.

    Measured (tracemalloc, compile and first solve; n = 1..100, m = 1..8, N up to 8000, full
    weights): about 250 N n^2 bytes for the state terms, 350 N n m for the dynamics' input
    columns and 610 N m for the input terms, plus cvxpy's and Clarabel's fixed ~10 MB; the
    condensed form adds its dense (N n)×(N m) data, a Parameter since the problems are shared by shape
    (150 bytes per entry measured at the peak, 66-88 when they were constants: :mod:`.qp_shared`). In
    the sparse form no Parameter multiplies a Variable, so cvxpy keeps no (N m)^2 map.

    Examples
    --------
    >>> s = System(A=[[1]], B=[[1]], horizon=1, state_weight=[1], input_weight=[1], mu=[0.5], x0=[1])
    >>> qp_memory_estimate(s, "sparse")                 # 260 + 400 + 650 + 1e7
    10001310.0
    >>> qp_memory_estimate(s, "condensed") - qp_memory_estimate(s, "sparse")   # one 1x1 dense block
    150.0
    """
    N, n, m = system.horizon, system.n, system.m
    needed = 260.0 * N * n * n + 400.0 * N * n * m + 650.0 * N * m + 1e7
    if formulation == "condensed":
        needed += 150.0 * (N * n) * (N * m)
    return needed
