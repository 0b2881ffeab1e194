"""recursion_cost with its per-step input terms computed for all steps at once, against the step-by-step
forward pass it replaced (kept here as the reference): bit-equal, including channels with mu = 0 or 1
(the loss-variance term skips perfect channels) and many actuators."""

import numpy as np
import pytest

from packetloss_cvx.model import System
from packetloss_cvx.random_systems import random_system
from packetloss_cvx.recursion import recursion_cost, udp_variance_weights


def step_by_step(system, inputs, protocol):
    A, B, W, mu, psi = system.A, system.B, system.state_weights, system.mu_schedule, system.input_weights
    d, noise = udp_variance_weights(system)
    x = system.x0.copy()
    total = float(x @ system.initial_weight @ x) + noise
    for t in range(system.horizon):
        u = inputs[t]
        mean_u = mu[t] * u
        total += float(np.sum(mean_u * (psi[t] * u)))
        if protocol == "udp":
            lossy = mu[t] < 1.0
            total += float(np.sum((mean_u * ((1.0 - mu[t]) * d[t] * u))[lossy]))
        x = A @ x + B @ (mu[t] * u)
        total += float(x @ W[t] @ x)
    return total


@pytest.mark.parametrize("seed", range(40))
def test_forward_cost_is_bit_equal_to_the_step_by_step_pass(seed):
    rng = np.random.default_rng(seed)
    s = random_system(rng, m=int(rng.integers(1, 12)) if seed % 3 == 0 else None, edge_mu=bool(seed % 2),
                      non_stationary=bool(seed % 5 == 0))
    U = rng.normal(size=(s.horizon, s.m)) * 10 ** rng.uniform(-3, 3)
    for protocol in ("tcp", "udp"):
        assert recursion_cost(s, U, protocol) == step_by_step(s, U, protocol)


def test_forward_cost_by_hand():
    s = System(A=[[1.0]], B=[[1.0, 1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0, 2.0], mu=[0.5, 1.0],
               x0=[1.0])
    U = np.array([[1.0, -1.0], [0.0, 0.0]])
    # x1 = 1 + 0.5 - 1 = 0.5, x2 = 0.5; inputs 0.5 * 1 + 1 * 2 = 2.5; UDP adds 0.5 * 0.5 * (B'S_0 B = 2) * 1 = 0.5
    assert recursion_cost(s, U, "tcp") == 0.25 + 0.25 + 2.5
    assert recursion_cost(s, U, "udp") == 0.25 + 0.25 + 2.5 + 0.5
