"""Sampled realised costs: of a fixed open-loop plan, and of receding-horizon laws run in
closed loop. Their means estimate the expectations the paper states (Monte Carlo checks).

The plant is simulated as stated (eq:plant): each actuator's packet arrives with
probability mu_{t,i}, independently across channels and steps; a lost packet
applies zero input; W_t ~ N(0, Sigma_W).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..linalg import psd_factor
from ..lq.costs import check_inputs
from ..model.system import System, loop_weights
from .channels import sample_delivery_paths, sample_noise_paths, sample_step_deliveries, sample_step_noise

__all__ = ["closed_loop_costs", "sample_plan_costs"]


def sample_plan_costs(system: System, inputs: npt.ArrayLike, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Realised costs ``x'Qx + sum_t X_t' Omega_t X_t + sum_t (V_t u_t)' Psi_t (V_t u_t)``.
    The cost inside the expectation of eq:plant0, on the plant of eq:plant as stated.

    The open-loop plan ``inputs`` (N×m) is applied whatever the losses. Returns
    ``samples`` realised costs; their mean estimates E[cost | X_k] of the plan. Deliveries and noise are
    drawn step by step through `.channels` (`sample_step_deliveries`,
    `sample_step_noise`), in the order this function has always used.
    Time O(samples · N · (n^2 + n m)), memory O(samples · n).

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.3], x0=[1.0])
    >>> c = sample_plan_costs(s, [[-2.0]], 4000, np.random.default_rng(0))   # delivered: 4 + 1; lost: 0 + 1
    >>> sorted(set(c.tolist())), bool(abs(c.mean() - (1 + 4 * 0.3)) < 4 * c.std() / 4000 ** 0.5)
    ([1.0, 5.0], True)
    """
    U = check_inputs(system, inputs)
    N = system.horizon
    x0 = system.x0
    X = np.repeat(x0[None, :], samples, axis=0)
    total = np.full(samples, float(x0 @ system.initial_weight @ x0))
    L = psd_factor(system.noise_cov)  # W_t = L' z, z ~ N(0, I)
    for t in range(N):
        applied = sample_step_deliveries(system, t, samples, rng) * U[t]
        total += np.sum(system.input_weights[t] * applied * applied, axis=1)
        X = X @ system.A.T + applied @ system.B.T
        noise = sample_step_noise(L, samples, rng)
        if noise is not None:
            X = X + noise
        total += np.einsum("si,si->s", X @ system.state_weights[t], X)
    return total


def closed_loop_costs(system: System, gains: list[np.ndarray], steps: int, samples: int,
                      rng: np.random.Generator) -> np.ndarray:
    """Realised costs of receding-horizon laws ``u_t = -K x_t`` run in closed loop.

    Every law in ``gains`` sees the same sampled losses and noise (common random
    numbers), so differences between laws have small variance. Stage cost
    ``x_t' Omega_1 x_t + (V_t u_t)' Psi_0 (V_t u_t)`` for t = 0..steps-1 plus
    ``x_T' Omega_1 x_T``; the channel uses ``mu_schedule[0]`` (deliveries and noise from `.channels`).
    Returns an array (len(gains), samples). Time O(len(gains) · samples · steps · n (n + m)).

    Examples
    --------
    >>> from packetloss_cvx.closedloop.moments import finite_horizon_costs
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> c = closed_loop_costs(s, [np.array([[0.5]]), np.zeros((1, 1))], 3, 4000, np.random.default_rng(0))
    >>> stage, terminal = finite_horizon_costs(s, [[0.5]], 3)      # the exact expectation
    >>> bool(abs(c[0].mean() - stage.sum() - terminal) < 4 * c[0].std() / 4000 ** 0.5)
    True
    >>> bool(np.all(c[1] == 4.0))                                   # K = 0: x stays 1, three stages + terminal
    True
    """
    W, psi = loop_weights(system)
    losses = sample_delivery_paths(system, steps, samples, rng)
    noise = sample_noise_paths(system, steps, samples, rng)
    out = np.empty((len(gains), samples))
    for k, K in enumerate(gains):
        X = np.repeat(system.x0[None, :], samples, axis=0)
        total = np.zeros(samples)
        with np.errstate(over="ignore", invalid="ignore"):
            for t in range(steps):
                applied = losses[t] * (-X @ K.T)
                total += np.einsum("si,si->s", X @ W, X) + np.sum(psi * applied * applied, axis=1)
                X = X @ system.A.T + applied @ system.B.T
                if noise is not None:
                    X = X + noise[t]
            total += np.einsum("si,si->s", X @ W, X)
        out[k] = total
    return out
