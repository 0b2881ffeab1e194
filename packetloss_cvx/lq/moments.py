"""The state's mean and covariance under a fixed commanded plan, Bernoulli losses and noise (open loop).

The moments the constrained QP's state limits and chance constraints are posed on (docs/mathematics.md §7), by their
forward recursion: used by `packetloss_cvx.qp.constrained` to check and polish a solver's answer without the
matrices the problem was built from. No cvxpy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.system import System

__all__ = ["Moments", "plan_moments"]


@dataclass(frozen=True)
class Moments:
    """The state's moments under a plan (`plan_moments`): ``mean[k]`` = E[x_k] and ``cov[k]`` = Cov(x_k),
    k = 0..N, ``T[k]`` = dE[x_k]/dU (n × N m) and ``C[k]`` with ``Cov(x_k) = C[k] diag(u)^2 C[k]' + S[k]``."""

    mean: np.ndarray
    cov: np.ndarray
    T: np.ndarray
    C: np.ndarray
    S: np.ndarray


def plan_moments(system: System, inputs: np.ndarray, mu: np.ndarray | None = None,
                 x0: np.ndarray | None = None) -> Moments:
    """Mean and covariance of x_k, k = 0..N, under the commanded plan ``inputs`` (N×m), Bernoulli losses of
    ``mu`` (N×m, default the system's) and the noise, by the forward recursion

    .. math:: m_{k+1} = A m_k + B \\bar v_k u_k,\\qquad
              \\Sigma_{k+1} = A \\Sigma_k A' + B\\,\\mathrm{diag}(\\mu_k(1-\\mu_k) u_k^2)B' + \\Sigma_W

    (losses independent across channels and steps, of the state and of the noise; x0 known). O(N^2 n m (n + m)).

    Examples
    --------
    x' = x + v u with mu = 1/2, u = 1, x0 = 0: E[x_1] = 1/2, Var x_1 = 1/4; E[x_2] = 1, Var x_2 = 1/2.

    >>> s = System(A=[[1]], B=[[1]], horizon=2, state_weight=[1], input_weight=[1], mu=[0.5], x0=[0])
    >>> mom = plan_moments(s, np.ones((2, 1)))
    >>> mom.mean.ravel().tolist(), mom.cov.ravel().tolist()
    ([0.0, 0.5, 1.0], [0.0, 0.25, 0.5])
    """
    N, n, m = system.horizon, system.n, system.m
    mu = system.mu_schedule if mu is None else np.asarray(mu, dtype=float).reshape(N, m)
    x = system.x0 if x0 is None else np.asarray(x0, dtype=float)
    u = np.asarray(inputs, dtype=float).reshape(N, m)
    sigma = np.sqrt(mu * (1.0 - mu))
    A, B, W = system.A, system.B, system.noise_cov
    mean, cov = np.zeros((N + 1, n)), np.zeros((N + 1, n, n))
    T, C, S = np.zeros((N + 1, n, N * m)), np.zeros((N + 1, n, N * m)), np.zeros((N + 1, n, n))
    mean[0] = x
    for k in range(N):
        block = slice(k * m, (k + 1) * m)
        mean[k + 1] = A @ mean[k] + B @ (mu[k] * u[k])
        T[k + 1] = A @ T[k]
        T[k + 1][:, block] += B * mu[k]
        C[k + 1] = A @ C[k]
        C[k + 1][:, block] += B * sigma[k]
        S[k + 1] = A @ S[k] @ A.T + W
        spread = B * (sigma[k] * u[k])
        cov[k + 1] = A @ cov[k] @ A.T + spread @ spread.T + W
    return Moments(mean, cov, T, C, S)
