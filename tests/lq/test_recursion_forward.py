"""recursion_cost, the one forward referee (recursion.forward_cost on a batch of one), against two independent
references: a step-by-step forward pass written out here, and the paper's dense quadratic form
(costs.dense_cost), including channels with mu = 0 or 1 (the loss-variance term skips perfect channels) and many
actuators. Every term of the forward sum is nonnegative, so the batched order of summation moves it by a few
units in the last place only: 1e-14 relative."""

import numpy as np
import pytest

from packetloss_cvx.lq.costs import dense_cost
from packetloss_cvx.lq.recursion import recursion_cost, udp_variance_weights
from packetloss_cvx.model.random_systems import random_system
from packetloss_cvx.model.system import System


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
def test_forward_cost_equals_the_step_by_step_pass_and_the_dense_form(seed):
    rng = np.random.default_rng(seed)
    s = random_system(rng, m=int(rng.integers(1, 12)) if seed % 3 == 0 else None, edge_mu=bool(seed % 2),
                      non_stationary=bool(seed % 5 == 0))
    U = rng.normal(size=(s.horizon, s.m)) * 10 ** rng.uniform(-3, 3)
    for protocol in ("tcp", "udp"):
        value = recursion_cost(s, U, protocol)
        assert value == pytest.approx(step_by_step(s, U, protocol), rel=1e-14, abs=0)
        assert value == pytest.approx(dense_cost(s, U, protocol), rel=1e-9, abs=0)


def test_forward_cost_by_hand():
    s = System(A=[[1.0]], B=[[1.0, 1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0, 2.0], mu=[0.5, 1.0],
               x0=[1.0])
    U = np.array([[1.0, -1.0], [0.0, 0.0]])
    # x1 = 1 + 0.5 - 1 = 0.5, x2 = 0.5; inputs 0.5 * 1 + 1 * 2 = 2.5; UDP adds 0.5 * 0.5 * (B'S_0 B = 2) * 1 = 0.5
    assert recursion_cost(s, U, "tcp") == 0.25 + 0.25 + 2.5
    assert recursion_cost(s, U, "udp") == 0.25 + 0.25 + 2.5 + 0.5
