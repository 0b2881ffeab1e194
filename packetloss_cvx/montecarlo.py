"""Sampling checks of the expectations: realised costs of a fixed plan.

The plant is simulated as stated (eq:plant): each actuator's packet arrives with
probability mu_{t,i}, independently across channels and steps; a lost packet
applies zero input; W_t ~ N(0, Sigma_W).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .costs import _inputs
from .model import System, psd_factor

__all__ = ["sample_plan_costs"]


def sample_plan_costs(system: System, inputs: npt.ArrayLike, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Realised costs ``x'Qx + sum_t X_t' Omega_t X_t + sum_t (V_t u_t)' Psi_t (V_t u_t)``.

    The open-loop plan ``inputs`` (N×m) is applied whatever the losses. Returns
    ``samples`` realised costs; their mean estimates E[cost | X_k] of the plan.
    Time O(samples · N · (n^2 + n m)), memory O(samples · n).
    """
    U = _inputs(system, inputs)
    n, N = system.n, system.horizon
    x0 = system.x0
    X = np.repeat(x0[None, :], samples, axis=0)
    total = np.full(samples, float(x0 @ system.initial_weight @ x0))
    L = psd_factor(system.noise_cov)  # W_t = L' z, z ~ N(0, I)
    for t in range(N):
        V = rng.random((samples, system.m)) < system.mu_schedule[t]
        applied = V * U[t]
        total += np.sum(system.input_weights[t] * applied * applied, axis=1)
        X = X @ system.A.T + applied @ system.B.T
        if L.shape[0]:
            X = X + rng.standard_normal((samples, L.shape[0])) @ L
        total += np.einsum("si,ij,sj->s", X, system.state_weights[t], X)
    return total
